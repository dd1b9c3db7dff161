"""A sweep through hydra/launcher=ray on a local Ray instance: one MLflow parent,
every job a FINISHED child under it, shared stages computed once across the
worker processes, and each job's threads capped to its Ray CPUs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from launcher_support import SCHEMA_MATCH_WARNING, THREAD_VARS, compose_with_hydra, job_logs
from omegaconf import OmegaConf

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings(SCHEMA_MATCH_WARNING)]


def test_ray_sweep_one_parent_three_children(ray_plugin, run_sphri, sweep_runs, tmp_path: Path):
    out = tmp_path / "outputs"
    proc = run_sphri(
        ["-m", "hydra/launcher=ray", "+robot=reachy", "+debug=fast", "layout.res=2,3,4", f"output_dir={out}"],
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "3 of 3 jobs finished" in proc.stdout, proc.stdout[-3000:]
    assert "Ray Launcher is launching 3 jobs" in proc.stderr + proc.stdout

    runs = sweep_runs(out)
    assert len(runs.parents) == 1
    parent = runs.parents[0]
    assert parent.info.status == "FINISHED"
    assert len(runs.children) == 3
    assert all(c.data.tags["mlflow.parentRunId"] == parent.info.run_id for c in runs.children)
    assert all(c.info.status == "FINISHED" for c in runs.children)
    assert sorted(c.data.params["layout.res"] for c in runs.children) == ["2", "3", "4"]

    statuses = [json.loads(p.read_text()) for p in sorted(out.glob("multirun/*/*/[0-9]*/sphri_status.json"))]
    assert [s["job"] for s in statuses] == [0, 1, 2] and all(s["status"] == "FINISHED" for s in statuses)
    # the stage cache is shared by the worker processes: data and contact computed by one job only
    logs = job_logs(out)
    assert len(logs) == 3
    for stage in ("data", "contact"):
        computed = sum(f"stage {stage:<9} computing" in text for text in logs)
        cached = sum(f"stage {stage:<9} from cache" in text for text in logs)
        assert (computed, cached) == (1, 2), f"stage {stage}: computed in {computed} jobs, from cache in {cached}"


def test_ray_jobs_start_with_thread_caps(ray_plugin, tmp_path: Path):
    """A job started with the launcher's remote options sees its thread caps from the start."""
    import ray

    cfg = compose_with_hydra(["hydra/launcher=ray", "hydra.launcher.ray.remote.num_cpus=1", f"output_dir={tmp_path}"])
    remote = OmegaConf.to_container(cfg.hydra.launcher.ray.remote, resolve=True)

    def probe() -> dict:
        import os

        import numba
        import torch
        from threadpoolctl import threadpool_info

        return {
            "env": {k: os.environ.get(k) for k in THREAD_VARS},
            "numba": numba.config.NUMBA_NUM_THREADS,
            "torch": torch.get_num_threads(),
            "blas": sorted({p["num_threads"] for p in threadpool_info()}),
            "pid": os.getpid(),
        }

    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=80 * 2**20, log_to_driver=False)
    try:
        seen = ray.get([ray.remote(**remote)(probe).remote() for _ in range(2)])
    finally:
        ray.shutdown()
    for s in seen:
        assert s["env"] == {k: "1" for k in THREAD_VARS}
        assert s["numba"] == 1 and s["torch"] == 1 and s["blas"] == [1], s
    assert seen[0]["pid"] != seen[1]["pid"]  # max_calls=1: a fresh worker process per job
