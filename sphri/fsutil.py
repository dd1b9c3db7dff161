"""Small file-system helpers shared by the writers of cache entries, model files and recordings.

``tempfile.mkstemp`` creates its file with mode 0600 whatever the umask; a
file renamed into place from it stays 0600, which a cache or a model folder
shared by a group cannot read. :func:`umask_mode` is the mode ``open()``
would give a new file (0666 less the process umask); the writers apply it
with ``os.fchmod`` before renaming (:func:`write_atomic` does both).
"""

from __future__ import annotations

import contextlib
import itertools
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Iterable, Iterator
from pathlib import Path

_lock = threading.Lock()


def current_umask() -> int:
    """The process umask, read without changing it where the OS allows (Linux: /proc/self/status)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _lock:  # os.umask can only be read by setting it: set it back at once
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def umask_mode(base: int = 0o666) -> int:
    """``base`` less the process umask: the mode a plain ``open(path, "w")`` gives a new file."""
    return base & ~current_umask()


def write_atomic(path: str | os.PathLike, data: bytes, fsync: bool = False) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``: a reader
    sees the old file or the new one, never half of it. The file gets the umask's mode (not mkstemp's
    0600); the temporary file is removed on any failure. ``fsync``: flushed to disk before the rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, umask_mode())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            if fsync:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


@contextlib.contextmanager
def replace_dir(target: str | os.PathLike) -> Iterator[Path]:
    """A new folder beside ``target`` to write a whole folder into; when the block ends it takes
    ``target``'s place (an existing ``target`` is moved aside, then removed): a reader sees the old
    folder or the new one, never a mix. On any failure the new folder is removed and ``target`` is
    untouched. The folder gets the umask's mode (not mkdtemp's 0700)."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    aside: Path | None = None
    try:
        os.chmod(tmp, umask_mode(0o777))
        yield tmp
        if target.is_symlink() or target.exists():
            aside = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
            os.replace(target, aside / "old")  # the name alone moves; a link is moved, never followed
        os.replace(tmp, target)
    except BaseException:
        if aside is not None and os.path.lexists(aside / "old") and not os.path.lexists(target):
            os.replace(aside / "old", target)  # put the old folder back
        shutil.rmtree(tmp, ignore_errors=True)
        if aside is not None:
            shutil.rmtree(aside, ignore_errors=True)
        raise
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)


@contextlib.contextmanager
def into_dir(target: str | os.PathLike) -> Iterator[Path]:
    """Where to write a folder whole: ``target`` itself when it is absent or empty, else a new folder beside it
    that takes its place when the block ends (:func:`replace_dir`: on a failure ``target`` is untouched, and
    the old files are never mixed with the new). Callers refuse a non-empty ``target`` beforehand unless the
    user asked to replace it (:func:`sphri.config.check_output_dir` with ``overwrite``)."""
    target = Path(target)
    if target.is_dir() and any(target.iterdir()):
        with replace_dir(target) as fresh:
            yield fresh
    else:
        target.mkdir(parents=True, exist_ok=True)
        yield target


def moved(paths: Iterable[Path], src: Path, dst: Path) -> list[Path]:
    """``paths`` under ``src`` as they lie once ``src`` has become ``dst`` (:func:`into_dir`)."""
    return [dst / Path(p).relative_to(src) for p in paths]


def new_run_dir(parent: str | os.PathLike) -> Path:
    """A new folder under ``parent`` named by the local time (``2026-12-03_07-16-11``; ``_2``, ``_3``, ... when a
    run that started in the same second holds that name), made here so that two runs never share one."""
    parent = Path(parent)
    parent.mkdir(parents=True, exist_ok=True)
    stem = time.strftime("%Y-%m-%d_%H-%M-%S")
    for n in itertools.count(1):
        path = parent / (stem if n == 1 else f"{stem}_{n}")
        try:
            path.mkdir()
        except FileExistsError:
            continue
        return path
    raise AssertionError("unreachable")
