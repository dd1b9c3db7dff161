"""A first run says that it compiles sphri's numba kernels; a run that loads them from numba's cache says nothing."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

PROBE = """
import logging, sys
import numpy as np
logging.basicConfig(level=logging.INFO, stream=sys.stdout, format="%(message)s")
from sphri._numba import announce_compiles
a = announce_compiles()
from sphri.noise.hashing import frame_key
frame_key(np.uint64(1), np.uint64(2), np.int64(3), np.int64(4))
print("KERNELS", a.kernels, "SECONDS", round(a.seconds, 3))
"""


def _run(cache_dir: Path) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir), "PYTHONPATH": str(REPO)}
    out = subprocess.run(
        [sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, cwd=cache_dir, timeout=300
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


def test_first_compile_is_announced_and_timed_cached_load_is_silent(tmp_path):
    first = _run(tmp_path)
    assert "compiling sphri's numba kernels" in first
    kernels, seconds = first.split("KERNELS")[1].split("SECONDS")
    assert int(kernels) >= 1 and float(seconds) > 0
    again = _run(tmp_path)  # same cache dir: loaded from disk, no compile event
    assert "compiling" not in again
    assert "KERNELS 0 " in again
