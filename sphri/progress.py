"""A progress display for a long step that prints nothing else while it runs: a tqdm bar on stderr when
stderr is a terminal (the real rate and the time left, never a fixed estimate), nothing otherwise (logs,
pipes and tests stay clean)."""

from __future__ import annotations

import io
import sys
from typing import IO, Any


class _Quiet:
    """What :func:`bar` gives when stderr is not a terminal: the bar's calls, doing nothing."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> _Quiet:
        return self

    def __exit__(self, *exc: object) -> None:
        pass


def bar(total: int, desc: str, unit: str = "it", file: IO[str] | None = None) -> Any:
    """A tqdm bar of ``total`` steps named ``desc`` on ``file`` (default: stderr) if that is a terminal,
    else an object with the same ``update``/``close`` that shows nothing. Use it as a context manager."""
    stream = sys.stderr if file is None else file
    isatty = getattr(stream, "isatty", None)
    if not (callable(isatty) and isatty()):
        return _Quiet()
    from tqdm import tqdm

    columns, rows = _size(stream)
    return tqdm(total=total, desc=desc, unit=unit, file=stream, leave=False, ncols=columns, nrows=rows)


def _size(stream: IO[str]) -> tuple[int, int]:
    """The terminal's (columns, rows); 80 x 24 where it reports none (a pseudo-terminal nobody sized reports
    0 x 0, and tqdm would draw an empty bar, or hide it below the last row)."""
    import os

    try:
        size = os.get_terminal_size(stream.fileno())
        columns, rows = size.columns, size.lines
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        columns, rows = 0, 0
    return columns or 80, rows or 24
