"""A job whose every stage is in the cache imports none of the libraries only computing needs.

Issue 28 (a cached ``+debug=fast`` run should cost little of sphri's own time): the synthetic data
component imported its hand kinematics (numba) and link geometry (trimesh, scipy.spatial) at module
level, so reading its ``VERSION`` for the config hash cost about 0.6 s on every cached run; the
robot checks, mesh helpers, contact stage and encoder did the same with trimesh and numba.

Likewise a parallel sweep's thread caps (``limit_threads``) reach torch and numba through the
environment they read at import, so a Random Forest job's worker does not import torch to cap it.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

# numba still loads: the noise component's kernels are defined in its own module (sklearn, with
# scipy.spatial, comes with the Random Forest's base class, whose VERSION enters the config hash)
HEAVY = ("trimesh", "torch", "matplotlib", "mlflow", "embreex")

PROBE = """
import atexit, runpy, sys
heavy = {heavy!r}
atexit.register(lambda: print("LOADED", sorted(m for m in heavy if m in sys.modules)))
sys.argv = ["sphri", *{args!r}]
runpy.run_module("sphri", run_name="__main__")
"""


def _job(tmp_path: Path, probe: bool) -> subprocess.CompletedProcess:
    args = ["+debug=fast", f"output_dir={tmp_path / 'out'}", "tracking.enabled=false"]
    cmd = (
        [sys.executable, "-c", PROBE.format(heavy=HEAVY, args=args)]
        if probe
        else [sys.executable, "-m", "sphri", *args]
    )
    out = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return out


def test_a_fully_cached_job_imports_no_compute_library(tmp_path: Path):
    _job(tmp_path, probe=False)  # fills the stage cache
    again = _job(tmp_path, probe=True)
    assert "(from cache)" in again.stdout or "cache" in again.stdout, again.stdout[-2000:]
    loaded = again.stdout.split("LOADED", 1)[1].strip()
    assert loaded == "[]", f"a cached job imported {loaded}"


CAPS = """
import sys
from sphri.__main__ import limit_threads
limit_threads(1)
print("IMPORTED", [m for m in ("torch", "numba") if m in sys.modules])
import numba, torch
print("THREADS", torch.get_num_threads(), numba.get_num_threads())
"""


def test_a_parallel_sweep_jobs_thread_caps_import_neither_torch_nor_numba(tmp_path: Path):
    """``limit_threads`` (each job of a parallel sweep) caps a library imported later through the
    environment it reads at import: a Random Forest job's worker never imports torch."""
    out = subprocess.run([sys.executable, "-c", CAPS], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "IMPORTED []" in out.stdout, out.stdout
    assert "THREADS 1 1" in out.stdout, out.stdout


def test_thread_caps_reach_torch_and_numba_imported_before(monkeypatch):

    import numba
    import torch

    from sphri.__main__ import limit_threads

    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "SPHRI_THREADS"):
        monkeypatch.delenv(var, raising=False)  # restored after the test
    before = torch.get_num_threads(), numba.get_num_threads()
    try:
        limit_threads(1)
        assert (torch.get_num_threads(), numba.get_num_threads()) == (1, 1)
    finally:
        torch.set_num_threads(before[0])
        numba.set_num_threads(before[1])
