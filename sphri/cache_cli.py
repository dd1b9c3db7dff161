"""``python -m sphri.cache info|clear [STAGE ...]``: see and trim the stage cache, never the MLflow store.

::

    python -m sphri.cache info                          # entries and size per stage under outputs/cache
    python -m sphri.cache info dir=/shared/sphri/cache  # another cache folder
    python -m sphri.cache clear evaluate                # drop one stage's entries (recomputed when needed)
    python -m sphri.cache clear older_than_days=14      # drop entries not read or written for two weeks
    python -m sphri.cache clear                         # drop every entry (asks nothing: it is only a cache)

Arguments are ``key=value`` (``dir``, default ``outputs/cache``;
``older_than_days``) plus stage names. Entries are removed under their lock,
so a job computing the same entry is not disturbed; orphan lock and
temporary files go with them. Runs, reports and ``mlflow.db`` are never
touched (``make clean`` removes everything).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from sphri.cache import SUFFIX


class CacheCliError(ValueError):
    """A bad argument of ``python -m sphri.cache``."""


def _entries(root: Path, stages: list[str]) -> dict[str, list[Path]]:
    if not root.is_dir():
        raise CacheCliError(f"dir={root}: no cache folder there")
    present = sorted(p.name for p in root.iterdir() if p.is_dir())
    unknown = [s for s in stages if s not in present]
    if unknown:
        raise CacheCliError(f"no stage {unknown} in {root}; stages there: {', '.join(present) or 'none'}")
    # only files are entries: a folder someone named *.entry is neither counted nor removed
    return {s: sorted(p for p in (root / s).glob(f"*{SUFFIX}") if p.is_file()) for s in (stages or present)}


def _human(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GB"


def info(root: Path, stages: list[str]) -> str:
    lines = [f"stage cache {root.resolve()}:"]
    total = 0
    for stage, paths in _entries(root, stages).items():
        size = sum(p.stat().st_size for p in paths)
        total += size
        age = ""
        if paths:
            newest = max(p.stat().st_mtime for p in paths)
            age = f", newest {(time.time() - newest) / 86400:.1f} days ago"
        lines.append(f"  {stage:<10} {len(paths):>5} entries  {_human(size):>9}{age}")
    lines.append(f"  {'total':<10} {'':>5}          {_human(total):>9}")
    return "\n".join(lines)


def clear(root: Path, stages: list[str], older_than_days: float | None = None) -> tuple[int, int]:
    """Remove entries (of ``stages``, or all; only those older than the limit if given): (count, bytes)."""
    from filelock import FileLock

    cutoff = None if older_than_days is None else time.time() - older_than_days * 86400
    n = freed = 0
    for stage, paths in _entries(root, stages).items():
        for path in paths:
            st = path.stat()
            if cutoff is not None and max(st.st_mtime, st.st_atime) > cutoff:
                continue
            lock = path.with_suffix(".lock")
            with FileLock(lock):  # the entry's own lock: a job writing it finishes first
                path.unlink(missing_ok=True)
            lock.unlink(missing_ok=True)
            n, freed = n + 1, freed + st.st_size
        if cutoff is None:
            for junk in [*(root / stage).glob(".*.tmp"), *(root / stage).glob("by-path/*.json")]:
                junk.unlink(missing_ok=True)
    return n, freed


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help") or argv[0] not in ("info", "clear"):
        try:
            print(__doc__)
        except BrokenPipeError:  # `--help | head`: the reader went away
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    cmd, rest = argv[0], argv[1:]
    root, older, stages = Path("outputs/cache"), None, []
    try:
        for a in rest:
            key, eq, value = a.partition("=")
            if not eq:
                stages.append(a)
            elif key == "dir":
                root = Path(value)
            elif key == "older_than_days" and cmd == "clear":
                try:
                    older = float(value)
                except ValueError:
                    raise CacheCliError(f"older_than_days={value} is invalid: must be a number of days") from None
                if older < 0:
                    raise CacheCliError(f"older_than_days={value} is invalid: must be >= 0")
            else:
                raise CacheCliError(f"unknown argument {a!r} for {cmd}")
        if cmd == "info":
            print(info(root, stages))
        else:
            n, freed = clear(root, stages, older)
            print(f"removed {n} entries ({_human(freed)}) from {root.resolve()}")
    except CacheCliError as exc:
        print(f"sphri.cache: {exc}", file=sys.stderr)
        return 2
    return 0
