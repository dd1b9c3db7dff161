"""Work is bounded before it starts: settings that size a job's arrays are estimated from the inputs and
refused past the memory limit (``SPHRI_MAX_MEMORY_GIB``, else the memory available) in one line naming the
setting, the estimate and the limit, before anything is allocated."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import forked_cli


def _run(args: list[str], cwd: Path, limit_gib: str | None = "64") -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "SPHRI_MAX_MEMORY_GIB"}
    if limit_gib is not None:
        env["SPHRI_MAX_MEMORY_GIB"] = limit_gib
    return forked_cli.run(["-m", *args], cwd, env, 300)


_one_line = forked_cli.one_line


def test_a_million_participants_is_refused_at_validate_with_the_estimate(tmp_path: Path):
    """`data.participants=1000000` ran 40 min to 12 GB with no estimate."""
    proc = _run(["sphri", "validate", "data.participants=1000000"], tmp_path)
    _one_line(
        proc, 2, "invalid config", "data.participants=1000000", "GiB, more than SPHRI_MAX_MEMORY_GIB=64", "frames"
    )
    ok = _run(["sphri", "validate", "data.participants=18"], tmp_path, limit_gib="1")
    assert ok.returncode == 0, ok.stderr[-2000:]


def test_the_same_run_refuses_before_computing(tmp_path: Path):
    proc = _run(["sphri", "data.participants=1000000", f"output_dir={tmp_path / 'o'}"], tmp_path)
    _one_line(proc, 2, "data.participants=1000000", "SPHRI_MAX_MEMORY_GIB")
    assert not (tmp_path / "o" / "mlflow.db").exists()


def test_a_report_bootstrap_past_the_limit_is_one_line(tmp_path: Path):
    """`sphri report DIR n_boot=10^12` died with numpy's ArrayMemoryError."""
    proc = _run(["sphri", "report", str(tmp_path / "sweep"), "n_boot=1000000000000"], tmp_path)
    _one_line(proc, 2, "n_boot=1000000000000", "1.49e+04 GiB", "SPHRI_MAX_MEMORY_GIB")


def test_a_skin_grid_larger_than_a_frame_holds_is_one_line(tmp_path: Path):
    """`skin record grid=1000x1000` printed a traceback from the decoder."""
    proc = _run(
        ["sphri", "skin", "record", "port=sim://", f"out={tmp_path / 'r.npz'}", "grid=1000x1000", "frames=5"],
        tmp_path,
    )
    _one_line(proc, 2, "grid='1000x1000'", "1000000 taxels", "4096")
    assert not (tmp_path / "r.npz").exists()


def test_a_layout_past_the_limit_is_refused_before_it_is_built(tmp_path: Path):
    """A 2 M-taxel layout was refused only after a 150 s layout stage and a 14.6 GB peak; the taxel count
    is known from the grid's size before any taxel is placed."""
    args = ["sphri", "+debug=fast", "layout.res=300", "cache.enabled=false", f"output_dir={tmp_path / 'o'}"]
    proc = _run(args, tmp_path, limit_gib="0.25")
    _one_line(proc, 2, "invalid config", "layout.res=300 with layout.aspect=1", "taxels", "SPHRI_MAX_MEMORY_GIB=0.25")
    assert "stage layout    computed" not in proc.stdout + proc.stderr
