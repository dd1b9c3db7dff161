"""Small file-system helpers shared by the writers of cache entries, model files and recordings.

``tempfile.mkstemp`` creates its file with mode 0600 whatever the umask; a
file renamed into place from it stays 0600, which a cache or a model folder
shared by a group cannot read. :func:`umask_mode` is the mode ``open()``
would give a new file (0666 less the process umask); the writers apply it
with ``os.fchmod`` before renaming (:func:`write_atomic` does both).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import threading
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
