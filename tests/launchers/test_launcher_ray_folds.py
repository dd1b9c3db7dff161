"""Folds as Ray tasks: a 2-job sweep through hydra/launcher=ray with cv.backend=ray runs the folds of
each job as Ray tasks on the launcher's local Ray instance and gets exactly the fold accuracies of the
same sweep run in this process (serial launcher, folds in the job's process); neither sweep refits and
logs a model per job by default (tracking.log_model=null)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from launcher_support import SCHEMA_MATCH_WARNING, job_logs

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings(SCHEMA_MATCH_WARNING)]

SWEEP = [
    "-m",
    "+robot=reachy",
    "+debug=fast",
    "model=rf",
    "layout.res=2,3",
    "tracking.experiment=sphri",
    "tracking.log_model=null",  # the default (+debug=fast turns it off): a sweep's jobs log no model
]
# a small local Ray instance: 2 CPUs, a 200 MB object store
RAY = [
    "hydra/launcher=ray",
    "hydra.launcher.ray.init.num_cpus=2",
    "hydra.launcher.ray.init.object_store_memory=200000000",
    "cv.backend=ray",
]


def _fold_accuracies(out: Path, sweep_runs) -> dict[str, list[float]]:
    """layout.res -> the job's fold accuracies in fold order; checks no job logged a model."""
    from mlflow.tracking import MlflowClient

    from sphri.tracking.mlflow_tracker import MlflowTracker, default_uri

    runs = sweep_runs(out)
    assert len(runs.children) == 2 and all(c.info.status == "FINISHED" for c in runs.children)
    client = MlflowClient(default_uri(out))
    found = {}
    for child in runs.children:
        history = sorted(client.get_metric_history(child.info.run_id, "fold_accuracy"), key=lambda m: m.step)
        found[child.data.params["layout.res"]] = [m.value for m in history]
        assert MlflowTracker().logged_models(str(out), child.info.run_id) == []  # no refit per job
    return found


def test_ray_fold_tasks_give_the_in_process_fold_accuracies(ray_plugin, run_sphri, sweep_runs, tmp_path: Path):
    cache = tmp_path / "cache"  # shared: the Ray sweep reuses data, contact and encode, recomputes the evaluation
    local_out, ray_out = tmp_path / "local", tmp_path / "ray"
    proc = run_sphri([*SWEEP, "hydra/launcher=serial", f"output_dir={local_out}", f"cache.dir={cache}"], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "2 of 2 jobs finished" in proc.stdout, proc.stdout[-3000:]
    local = _fold_accuracies(local_out, sweep_runs)

    for stage in ("evaluate", "evaluate_fold"):  # cv.backend is a runtime setting: without this, a cache hit
        shutil.rmtree(cache / stage, ignore_errors=True)
    proc = run_sphri([*SWEEP, *RAY, f"output_dir={ray_out}", f"cache.dir={cache}"], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "2 of 2 jobs finished" in proc.stdout, proc.stdout[-3000:]
    assert "Ray Launcher is launching 2 jobs" in proc.stderr + proc.stdout
    logs = job_logs(ray_out)
    assert len(logs) == 2
    for text in logs:  # each job computed its evaluation, its folds as Ray tasks
        assert "stage evaluate  computing" in text
        assert "folds submitted as Ray tasks (1 CPU each)" in text, text[-3000:]
    tasks = _fold_accuracies(ray_out, sweep_runs)

    assert sorted(local) == sorted(tasks) == ["2", "3"]
    assert all(len(v) == 3 for v in local.values())  # +debug=fast: 3 participants, 3 LOSO folds
    assert tasks == local  # exactly, fold by fold
