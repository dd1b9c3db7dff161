"""A sweep through hydra/launcher=slurm, end to end on this machine: submitit
writes and submits the sbatch job array to a stand-in SLURM (fake_slurm.py:
sbatch/srun/sacct that run the array's tasks locally with SLURM's variables).
Each task re-composes its config in a fresh process (the ConfigStore schemas
travel in Hydra's pickled singleton state), runs with the thread caps the
sbatch script exported, and logs a child run under the sweep's MLflow parent."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import fake_slurm
import pytest
from launcher_support import SETUP_THREADS, THREAD_VARS

pytestmark = pytest.mark.slow


def test_slurm_sweep_through_fake_sbatch(submitit_plugin, run_sphri, sweep_runs, tmp_path: Path):
    out = tmp_path / "outputs"
    slurm_dir = tmp_path / "slurm"
    bin_dir = fake_slurm.install(tmp_path / "bin")
    env = {"PATH": f"{bin_dir}:{os.environ['PATH']}", "FAKE_SLURM_DIR": str(slurm_dir)}
    proc = run_sphri(
        [
            "-m",
            "hydra/launcher=slurm",
            "+debug=fast",
            "layout.res=2,3",
            f"output_dir={out}",
            "hydra.launcher.partition=fake",
            "hydra.launcher.cpus_per_task=1",
            "hydra.launcher.array_parallelism=2",
            "hydra.launcher.timeout_min=10",
        ],
        cwd=tmp_path,
        env=env,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "2 of 2 jobs finished" in proc.stdout, proc.stdout[-3000:]

    scripts = sorted(slurm_dir.glob("*.sbatch"))
    assert len(scripts) == 1, "one job array for the whole sweep"
    text = scripts[0].read_text()
    opts = fake_slurm.sbatch_options(text)
    assert opts["array"] == "0-1%2" and opts["partition"] == "fake" and opts["cpus-per-task"] == "1"
    assert opts["time"] == "10" and opts["mem"] == "16GB"
    assert text.index(SETUP_THREADS) < text.index("srun ")
    # submitit returns once the results are written; the batch scripts end a moment later
    deadline = time.monotonic() + 60
    while (
        len(states := {p.name: p.read_text() for p in (slurm_dir / "state").glob("*")}) < 2
        and time.monotonic() < deadline
    ):
        time.sleep(0.2)
    assert sorted(states.values()) == ["COMPLETED", "COMPLETED"], states
    for seen in (json.loads(p.read_text()) for p in (slurm_dir / "env").glob("*.json")):
        assert seen == {**{k: "1" for k in THREAD_VARS}, "SLURM_CPUS_PER_TASK": "1"}

    runs = sweep_runs(out)
    assert len(runs.parents) == 1 and runs.parents[0].info.status == "FINISHED"
    assert len(runs.children) == 2
    assert all(c.data.tags["mlflow.parentRunId"] == runs.parents[0].info.run_id for c in runs.children)
    assert all(c.info.status == "FINISHED" for c in runs.children)
    assert sorted(c.data.params["layout.res"] for c in runs.children) == ["2", "3"]
