"""The Random Forest resolution sweep as ``make sweep`` runs it: wall time, per-stage share, resume.

Runs ``python -m sphri -m +experiment=resolution_sweep model=rf`` through the
default launcher (joblib, 2 parallel jobs, each limited to its share of the
cores) on an empty stage cache and MLflow store in a temporary directory, then
the report (``sphri report``), then the same sweep again, which must
skip every job (resume by config hash). From every job's MLflow run it reads
the stage times (``time/<stage>_s``: exclusive wall seconds, upstream stages
not counted) and which stages were computed or loaded from the cache:

- ``sweep_wall_s``: the sweep's wall time, cold (what a user waits for);
- ``stage_share``: each stage's share of the worker-seconds (wall x parallel
  jobs); ``other`` is what no stage accounts for: interpreter start, imports,
  config composition, MLflow logging, the launcher, and cores idle at the end
  of the sweep;
- ``contact_computed``: how many jobs computed contact (the stage cache must
  make it 1: one job computes, the others wait for and load its entry);
- ``other_per_job_s``: the worker-seconds no stage accounts for, per job;
- baseline measured in the same run, at the sweep's finest resolution on its
  warm cache: the Random Forest's features-once cross-validation against the
  per-fold features it replaced (``features_once_speedup``, CPU seconds; the
  fold accuracies must be identical).

Sizes: full (the default) is exactly ``make sweep`` (resolutions 1..50, the
full synthetic study: 18 participants x 8 gestures x 20 repetitions);
``--quick`` (what ``make bench`` runs) takes 8 resolutions (1, 8, ..., 50) on
4 participants. Writes ``outputs/bench/sweep.json`` (``sweep_quick.json`` for
the quick size, so that a quick run never overwrites the full numbers).

    python bench/bench_sweep.py [--quick] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, write_json  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
#: Chain order of the pipeline's stages.
STAGES = ("hand", "robot", "data", "contact", "surface", "layout", "plan", "encode", "noise", "filter", "evaluate")

FULL = {"resolutions": "range(1,51)", "n_resolutions": 50, "overrides": []}
QUICK = {"resolutions": "range(1,51,7)", "n_resolutions": 8, "overrides": ["data.participants=4"]}


def sweep_cmd(size: dict, work: Path) -> list[str]:
    """The ``make sweep`` command line, pointed at ``work`` for its cache, MLflow store and sweep dir."""
    return [
        sys.executable,
        "-m",
        "sphri",
        "-m",
        "+experiment=resolution_sweep",
        "model=rf",
        f"layout.res={size['resolutions']}",
        f"output_dir={work}",
        f"hydra.sweep.dir={work}/sweep",
        *size["overrides"],
    ]


def timed(cmd: list[str], log_path: Path, timeout_s: float) -> float:
    """Run ``cmd`` in the repository root, output to ``log_path``; its wall seconds (raises on failure)."""
    t0 = time.perf_counter()
    with open(log_path, "w") as log:
        proc = subprocess.run(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, timeout=timeout_s)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        tail = log_path.read_text()[-3000:]
        raise RuntimeError(f"{' '.join(cmd[1:4])} ... exited {proc.returncode} (log {log_path}):\n{tail}")
    return wall


def job_statuses(sweep_dir: Path) -> list[dict[str, Any]]:
    """Each job's ``sphri_status.json`` (FINISHED, SKIPPED or FAILED)."""
    return [json.loads(p.read_text()) for p in sorted(sweep_dir.glob("*/sphri_status.json"))]


def job_runs(sweep_dir: Path) -> list[dict[str, Any]]:
    """Per job of the sweep: res, stage seconds and sources, read from the parent run's children."""
    from mlflow.tracking import MlflowClient

    parent = json.loads((sweep_dir / "mlflow_parent_run.json").read_text())
    client = MlflowClient(parent["uri"])
    exp = client.get_run(parent["run_id"]).info.experiment_id
    runs = client.search_runs([exp], f"tags.`mlflow.parentRunId` = '{parent['run_id']}'", max_results=1000)
    out = []
    for run in runs:
        m, t = run.data.metrics, run.data.tags
        out.append(
            {
                "res": int(run.data.params["layout.res"]),
                "status": run.info.status,
                "accuracy_mean": m.get("accuracy_mean"),
                "stage_s": {s: float(m.get(f"time/{s}_s", 0.0)) for s in STAGES},
                "from_cache": [s for s in t.get("sphri.from_cache", "").split(",") if s and s != "none"],
                "job_s": (run.info.end_time - run.info.start_time) / 1e3 if run.info.end_time else None,
            }
        )
    return sorted(out, key=lambda r: r["res"])


def stage_shares(runs: list[dict[str, Any]], wall_s: float, parallel: int) -> dict[str, Any]:
    """Each stage's seconds summed over jobs and its share of the sweep's worker-seconds."""
    budget = wall_s * parallel
    totals = {s: sum(r["stage_s"][s] for r in runs) for s in STAGES}
    shares = {s: totals[s] / budget for s in STAGES}
    shares["other"] = max(0.0, 1.0 - sum(shares.values()))
    return {"worker_s": budget, "stage_s": totals, "stage_share": shares}


def single_job_baseline(size: dict, work: Path, res: int) -> dict[str, Any]:
    """Cross-validation at ``res`` on the sweep's warm cache: features once vs per fold (CPU seconds)."""
    from sphri.cache import StageCache
    from sphri.config import compose
    from sphri.evaluate.cv import LeaveOneSubjectOut
    from sphri.models.rf import RandomForest
    from sphri.pipeline import make_pipeline

    class PerFoldForest(RandomForest):
        """The forest as it ran before: features recomputed inside every fold."""

        TRANSFORM_PER_TRIAL = False

    cfg = compose([f"layout.res={res}", f"output_dir={work}", *size["overrides"]])
    p = make_pipeline(cfg, StageCache(root=cfg.cache.dir, enabled=True))
    t0 = time.perf_counter()
    windows = p.get("filter")  # the model's input: windows, noise, skin-side filter
    upstream_s = time.perf_counter() - t0
    params = dict(n_jobs=-1, seed=int(cfg.seed), geometry=windows.geometry)
    out: dict[str, Any] = {"res": res, "upstream_from_cache_s": upstream_s}
    accuracy = {}
    for name, cls in (("features_once", RandomForest), ("features_per_fold", PerFoldForest)):
        c0, t0 = time.process_time(), time.perf_counter()
        result = LeaveOneSubjectOut(progress=False).run(lambda: cls(**params), windows, int(cfg.seed))
        out[name] = {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}
        accuracy[name] = [f.accuracy for f in result.folds]
    out["same_fold_accuracies"] = accuracy["features_once"] == accuracy["features_per_fold"]
    out["features_once_speedup"] = out["features_per_fold"]["cpu_s"] / out["features_once"]["cpu_s"]
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--quick", action="store_true", help="8 resolutions on 4 participants (default: exactly `make sweep`)"
    )
    parser.add_argument("--keep", type=Path, default=None, help="work in this directory and keep it")
    args = parser.parse_args(argv)
    size = QUICK if args.quick else FULL
    name = "sweep_quick" if args.quick else "sweep"
    tmp = None
    if args.keep is None:
        tmp = tempfile.TemporaryDirectory(prefix="sphri-bench-sweep-")
        work = Path(tmp.name)
    else:
        work = args.keep.resolve()
        work.mkdir(parents=True, exist_ok=True)
    try:
        env_load = machine()
        cmd = sweep_cmd(size, work)
        print(f"sweep: {size['n_resolutions']} resolutions into {work}", flush=True)
        cold_s = timed(cmd, work / "sweep_cold.log", timeout_s=3 * 3600)
        runs = job_runs(work / "sweep")
        report_s = timed([sys.executable, "-m", "sphri", "report", str(work / "sweep")], work / "report.log", 1800)
        resume_s = timed(cmd, work / "sweep_resume.log", timeout_s=1800)
        statuses = job_statuses(work / "sweep")
        parallel = 2  # conf/hydra/launcher/local.yaml: n_jobs
        shares = stage_shares(runs, cold_s, parallel)
        finest = max(r["res"] for r in runs)
        print(
            f"sweep cold {cold_s:.0f} s, report {report_s:.0f} s, resume {resume_s:.0f} s; baseline job at res {finest}",
            flush=True,
        )
        base = single_job_baseline(size, work, finest)
        result = {
            "machine": env_load,
            "size": {"resolutions": size["resolutions"], "overrides": size["overrides"], "parallel_jobs": parallel},
            "command": " ".join(["python", *cmd[1:]]),
            "sweep_wall_s": cold_s,
            "sweep_wall_min": cold_s / 60,
            "report_s": report_s,
            "resume_wall_s": resume_s,
            "resume_skipped": sum(1 for s in statuses if s.get("status") == "SKIPPED"),
            "jobs": len(runs),
            "jobs_finished": sum(1 for r in runs if r["status"] == "FINISHED"),
            "contact_computed": sum(
                1 for r in runs if "contact" not in r["from_cache"] and r["stage_s"]["contact"] > 0
            ),
            **shares,
            "baseline_single_job": base,
            "other_per_job_s": shares["stage_share"]["other"] * shares["worker_s"] / max(1, len(runs)),
            "accuracy_by_res": {r["res"]: r["accuracy_mean"] for r in runs},
            "machine_after": machine(),
        }
        path = write_json(name, result)
        share = ", ".join(f"{k} {v:.0%}" for k, v in result["stage_share"].items() if v >= 0.005)
        print(
            f"wrote {path}: {len(runs)} jobs in {cold_s / 60:.1f} min (contact computed by {result['contact_computed']} job); "
            f"shares: {share}; resume skipped {result['resume_skipped']}/{len(statuses)} in {resume_s:.0f} s; "
            f"features once vs per fold at res {finest}: {base['features_once_speedup']:.1f}x less CPU",
            flush=True,
        )
        ok = (
            result["jobs_finished"] == size["n_resolutions"]
            and result["resume_skipped"] == size["n_resolutions"]
            and result["contact_computed"] == 1
            and base["same_fold_accuracies"]
        )
        return 0 if ok else 1
    finally:
        if tmp is not None:
            tmp.cleanup()


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
