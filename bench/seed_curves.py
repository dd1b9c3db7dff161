"""Accuracy curves of a multirun that repeats each setting over seeds: mean over seeds, paired differences.

    python bench/seed_curves.py SWEEP_DIR [SWEEP_DIR ...] [--output-dir outputs] [--base GROUP]

Reads every job's ``sphri_status.json`` in the sweep directories (its overrides
and MLflow run id) and the job's per-participant scores
(``<output_dir>/mlartifacts/<run_id>/artifacts/per_participant.csv``). Jobs
are grouped by their overrides without ``seed`` and ``layout.res`` (one
curve per group, e.g. per ``sensitivity`` variant). Per curve and resolution
it prints and writes (``seed_curves.csv`` in the first sweep directory):

- ``accuracy_mean``: mean over seeds of the job's mean accuracy over
  participants; ``seed_se``: standard error of that mean over seeds;
- ``vs_<base>`` and ``vs_<base>_se``: the curve minus the ``--base`` curve,
  paired per participant and seed, averaged over seeds per participant; SE
  over participants (each participant's seed-averaged difference is one unit).

Then, per curve, the dip at res 18: accuracy at res 8 and at the finest
swept resolution up to 36 minus the accuracy at res 18, paired per
participant (averaged over seeds), mean +/- SE over participants; positive =
res 18 is below that neighbour. Only finished jobs are read, so a running or
stopped sweep gives what it has (``n_seeds`` says how many); a job that
a resumed sweep skipped is read from the finished run it points to.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd


def load_jobs(sweeps: Path | list[Path], output_dir: Path) -> pd.DataFrame:
    """One row per (finished job, participant): group, res, seed, participant, accuracy."""
    rows = []
    sweeps = [sweeps] if isinstance(sweeps, Path) else list(sweeps)
    for status_file in sorted(f for sweep in sweeps for f in sweep.glob("*/sphri_status.json")):
        st = json.loads(status_file.read_text())
        if st.get("status") not in ("FINISHED", "SKIPPED") or not st.get("mlflow_run_id"):
            continue  # SKIPPED: resumed, the finished MLflow run of the same config holds the scores
        ov = dict(o.lstrip("+").split("=", 1) for o in st["overrides"])
        res = int(ov.pop("layout.res", None) or ov.pop("encoder.res"))  # encoder.res: sweeps of earlier releases
        ov.pop("encoder.res", None)
        seed = int(ov.pop("seed", 0))
        ov.pop("experiment", None)
        group = ",".join(f"{k}={v}" for k, v in sorted(ov.items())) or "all"
        pp = output_dir / "mlartifacts" / st["mlflow_run_id"] / "artifacts" / "per_participant.csv"
        if not pp.is_file():
            print(f"seed_curves: {pp} missing (job {status_file.parent.name}): left out", file=sys.stderr)
            continue
        df = pd.read_csv(pp)
        for part, acc in zip(df["fold"], df["accuracy"]):
            rows.append({"group": group, "res": res, "seed": seed, "participant": part, "accuracy": float(acc)})
    if not rows:
        raise SystemExit(f"seed_curves: no finished job with per-participant scores under {sweeps}")
    return pd.DataFrame(rows)


def _se(x: np.ndarray) -> float:
    return float(np.std(x, ddof=1) / np.sqrt(len(x))) if len(x) > 1 else float("nan")


def curves(jobs: pd.DataFrame, base: str | None) -> pd.DataFrame:
    job_mean = jobs.groupby(["group", "res", "seed"])["accuracy"].mean().reset_index()
    out = []
    for (g, r), d in job_mean.groupby(["group", "res"]):
        row = {
            "group": g,
            "res": r,
            "n_seeds": len(d),
            "accuracy_mean": d["accuracy"].mean(),
            "seed_se": _se(d["accuracy"].to_numpy()),
        }
        if base is not None and g != base:
            a = jobs[(jobs.group == g) & (jobs.res == r)].set_index(["seed", "participant"])["accuracy"]
            b = jobs[(jobs.group == base) & (jobs.res == r)].set_index(["seed", "participant"])["accuracy"]
            both = a.index.intersection(b.index)
            if len(both):
                d_p = (a[both] - b[both]).groupby(level="participant").mean().to_numpy()
                row[f"vs_{base}"] = float(d_p.mean())
                row[f"vs_{base}_se"] = _se(d_p)
                row["paired_seeds"] = len(set(s for s, _ in both))
        out.append(row)
    return pd.DataFrame(out).sort_values(["group", "res"]).reset_index(drop=True)


def dips(jobs: pd.DataFrame) -> list[str]:
    lines = []
    for g, d in jobs.groupby("group"):
        per = d.groupby(["res", "participant"])["accuracy"].mean().unstack("res")  # seed-averaged
        if 18 not in per or 8 not in per:
            continue
        fine = max([r for r in per.columns if 18 < r <= 36], default=None)
        parts = []
        for r in (8, fine):
            if r is None:
                continue
            diff = (per[r] - per[18]).dropna().to_numpy()
            parts.append(f"res {r} - res 18 = {diff.mean():+.3f} +/- {_se(diff):.3f}")
        lines.append(f"{g}: " + "; ".join(parts) + f" (paired over {len(per)} participants)")
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sweep", type=Path, nargs="+", help="multirun directories (their jobs are pooled)")
    p.add_argument("--output-dir", type=Path, default=Path("outputs"), help="the runs' output_dir (mlartifacts)")
    p.add_argument(
        "--base",
        default=None,
        help="group the others are paired against (default: the one holding 'reference', else none)",
    )
    args = p.parse_args(argv)
    jobs = load_jobs(args.sweep, args.output_dir)
    groups = sorted(jobs.group.unique())
    base = args.base or next((g for g in groups if "reference" in g), None)
    table = curves(jobs, base)
    out = args.sweep[0] / "seed_curves.csv"
    table.to_csv(out, index=False)
    with pd.option_context("display.width", 200, "display.max_rows", 500, "display.float_format", "{:.3f}".format):
        print(table.to_string(index=False))
    print("\ndip at res 18 (positive: res 18 below the neighbour), seed-averaged per participant:")
    for line in dips(jobs):
        print("  " + line)
    print(f"\nwritten: {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
