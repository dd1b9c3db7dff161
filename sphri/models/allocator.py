"""Keep freed memory in the process: glibc's allocator set for the CNN-GRU's training loop.

Each training step allocates its activations and gradients (buffers up to a few MiB at res 18) and
frees them at its end. With glibc's default settings, freed memory at the top of the heap beyond the
trim threshold (twice the largest mmapped buffer freed so far) goes back to the kernel, buffers above
the mmap threshold are mapped and unmapped on every use, and the next step faults the same pages in
again (the faults per step and the CPU time with and without this setting are measured by
``bench/bench_cnn_levers.py``: ``outputs/bench/cnn_levers.json``, with the machine, and docs/BENCHMARKS.md).

:func:`keep_freed_memory` sets glibc's ``M_MMAP_THRESHOLD`` to 32 MiB (the largest glibc accepts) and
``M_TRIM_THRESHOLD`` to 1 GiB with ``mallopt``, once per process: buffers below 32 MiB come from the
heap, and the heap keeps what a step freed for the next one. The results do not change (torch aligns
every buffer to 64 bytes either way; the benchmark's losses and weights, and the tests' predictions,
are bit-identical with and without); the process's peak resident memory stays the same (measured),
but the process holds that peak until it exits instead of returning freed memory to the kernel. Where ``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_`` or
``GLIBC_TUNABLES`` are set, the environment's choice stands; other C libraries are left alone.
"""

from __future__ import annotations

import ctypes
import os
import platform

#: glibc's largest mmap threshold on 64-bit (HEAP_MAX_SIZE / 2): buffers below it come from the heap.
MMAP_THRESHOLD = 32 * 2**20
#: Freed memory at the top of the heap is returned to the kernel only beyond this.
TRIM_THRESHOLD = 2**30
#: ``mallopt`` parameter numbers (glibc's malloc.h).
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
#: Environment variables through which a user sets glibc's allocator (read by glibc at start).
ENV_VARS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")

_state: str | None = None


def keep_freed_memory() -> str:
    """Set glibc's allocator to keep freed memory (see the module doc), once per process; returns what
    this process's allocator does, as the CNN-GRU records it (``runtime_["allocator"]``)."""
    global _state
    if _state is None:
        _state = _apply()
    return _state


def _apply() -> str:
    user = [v for v in ENV_VARS if os.environ.get(v)]
    if user:
        return f"glibc as the environment sets it ({', '.join(user)})"
    if platform.libc_ver()[0] != "glibc":
        return "the C library's default (not glibc)"
    mallopt = ctypes.CDLL(None).mallopt
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    if not (mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) and mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)):
        return "glibc default (mallopt refused the thresholds)"
    return f"glibc keeps freed memory (mmap threshold {MMAP_THRESHOLD >> 20} MiB, trim threshold {TRIM_THRESHOLD >> 30} GiB)"
