"""Where and how long each curve of a sweep was computed: the report's compute table.

Per curve (group): its jobs' wall time summed (each finished job's ``time/<stage>_s`` metrics:
the stages it computed in its finishing run; folds a resumed job loaded from the stage cache and
interrupted attempts are not counted, so a resumed curve took longer than this), the slowest job,
and the machines and model runtime the jobs recorded in MLflow (``sphri.machine.*`` tags, ``run.device`` / ``run.precision`` params,
torch version). Jobs whose evaluation came from the stage cache computed nothing here; they are
counted apart, so a curve computed elsewhere does not look free.

Summed wall time is the cost on the recorded machines when jobs run one at a time; with several
jobs at once (``hydra.launcher.n_jobs``) the sweep's own wall time is shorter than the sum.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sphri.report.sweep import Sweep

#: Columns of ``compute.csv`` (one row per curve).
COLUMNS = (
    "group",
    "jobs",
    "jobs_from_cache",
    "total_h",
    "slowest_res",
    "slowest_h",
    "machines",
    "model_runtime",
    "torch",
)


def _join(values: Any) -> str:
    return "; ".join(sorted({str(v) for v in values if str(v)})) or "not recorded"


def compute_rows(sweep: Sweep) -> list[dict[str, Any]]:
    """One row per group (:data:`COLUMNS`): jobs, hours, the slowest job, machines, model runtime."""
    rows = []
    for label, jobs in sweep.groups():
        total_s = jobs["stage_s"].to_numpy(float)
        slow = int(np.argmax(total_s)) if len(jobs) else 0
        machines = [f"{m} ({n} CPUs), GPU {g}" for m, n, g in zip(jobs["cpu_model"], jobs["cpu_count"], jobs["gpu"])]
        here = jobs[jobs["evaluated_here"].astype(bool)]
        runtime = [" ".join(x for x in (d, p) if x) for d, p in zip(here["device"], here["precision"])]
        rows.append(
            {
                "group": label,
                "jobs": len(jobs),
                "jobs_from_cache": int((~jobs["evaluated_here"].astype(bool)).sum()),
                "total_h": float(total_s.sum()) / 3600.0,
                "slowest_res": int(jobs["res"].iloc[slow]),
                "slowest_h": float(total_s[slow]) / 3600.0,
                "machines": _join(machines),
                "model_runtime": _join(runtime),
                "torch": _join(jobs["torch"]),
            }
        )
    return rows


def _hours(h: float) -> str:
    return f"{h * 60:.1f} min" if h < 1 else f"{h:.2f} h"


def compute_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The compute table as text lines (the summary's ``[compute]`` section)."""
    out = []
    for r in rows:
        cached = f", {r['jobs_from_cache']} evaluated from the cache" if r["jobs_from_cache"] else ""
        out.append(
            f"  {r['group']}: {r['jobs']} jobs{cached}, {_hours(r['total_h'])} wall summed over jobs' stages; "
            f"slowest res {r['slowest_res']} ({_hours(r['slowest_h'])}); on {r['machines']}; "
            f"model on {r['model_runtime']}" + (f"; torch {r['torch']}" if r["torch"] != "not recorded" else "")
        )
    return out
