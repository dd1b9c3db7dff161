"""Shared fixtures: ../shared (skipped when absent), temporary output dirs."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

REPO = Path(__file__).resolve().parent.parent

# Property tests draw the same examples on every run (`make test`, CI): a red run is reproducible.
# SPHRI_DEEP_TESTS=1 (`make test-all`) explores new random examples, remembered in .hypothesis/.
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile("explore" if os.environ.get("SPHRI_DEEP_TESTS") else "repeatable")
SHARED = Path(os.environ.get("SPHRI_SHARED", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared folder with the real study's assets; skips the test when absent."""
    if not (SHARED / "vr-gesture-dataset").is_dir():
        pytest.skip(f"../shared not present at {SHARED}")
    return SHARED


@pytest.fixture()
def arm_mesh_roots(tmp_path: Path) -> tuple[Path, Path]:
    """(good, bad): folders holding ``arm.obj``, the parametric Reachy arm or a file that is not a mesh.

    With ``robot=mesh robot.links={l_arm: arm.obj} robot.regions={arm: l_arm} robot.root=...``
    a job on ``bad`` passes validation and fails at the robot stage.
    """
    import trimesh

    from sphri import pipeline
    from sphri.config import compose

    good, bad = tmp_path / "good", tmp_path / "bad"
    good.mkdir()
    bad.mkdir()
    link = pipeline.build(compose(["+debug=fast"]).robot).build().link_for("arm")
    trimesh.Trimesh(link.vertices, link.faces, process=False).export(good / "arm.obj")
    (bad / "arm.obj").write_text("this is not a mesh\n")
    return good, bad


@pytest.fixture()
def sweep_then_report(tmp_path: Path):
    """``run(sweep_args, n_jobs, report_args)``: ``python -m sphri -m <sweep_args>`` into
    ``tmp_path/outputs/sweep`` (serial launcher), checked to finish all ``n_jobs``, then ``python -m sphri.report``
    on it, checked to exit 0; returns ``(sweep_dir, report_process)``."""
    repo = Path(__file__).resolve().parent.parent
    env = {
        **os.environ,
        "PYTHONUNBUFFERED": "1",
        "HYDRA_FULL_ERROR": "1",
        "PYTHONPATH": os.pathsep.join([str(repo), os.environ.get("PYTHONPATH", "")]),
    }
    out, sweep = tmp_path / "outputs", tmp_path / "outputs" / "sweep"

    def run(sweep_args: list[str], n_jobs: int, report_args: list[str], timeout: int = 600):
        job = subprocess.run(
            [
                sys.executable,
                "-m",
                "sphri",
                "-m",
                *sweep_args,
                f"output_dir={out}",
                f"hydra.sweep.dir={sweep}",
                "hydra/launcher=serial",
            ],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        assert job.returncode == 0 and f"{n_jobs} of {n_jobs} jobs finished" in job.stdout, job.stderr[-3000:]
        rep = subprocess.run(
            [sys.executable, "-m", "sphri.report", str(sweep), *report_args],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert rep.returncode == 0, rep.stderr[-3000:]
        return sweep, rep

    return run
