"""Small file-system helpers shared by the writers of cache entries, model files and recordings.

``tempfile.mkstemp`` creates its file with mode 0600 whatever the umask; a
file renamed into place from it stays 0600, which a cache or a model folder
shared by a group cannot read. :func:`umask_mode` is the mode ``open()``
would give a new file (0666 less the process umask); the writers apply it
with ``os.fchmod`` before renaming.
"""

from __future__ import annotations

import os
import threading

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
