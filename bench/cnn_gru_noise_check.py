"""The CNN-GRU and the Random Forest at res 8 / 18 / 50 with and without noise, side by side (issue 26, item 5).

    python bench/cnn_gru_noise_check.py SWEEP_DIR [SWEEP_DIR ...] [--output-dir outputs] [--name NAME]

Reads every finished job of the given sweeps (their ``sphri_status.json`` and the
per-participant scores in ``<output_dir>/mlartifacts/<run_id>/artifacts/per_participant.csv``,
as ``bench/seed_curves.py`` does) and groups them by model, noise and resolution
(other overrides, e.g. ``cv.max_folds``, must not split a point: two jobs of the
same point are refused). Per point it prints and writes accuracy and macro-F1 as
mean +/- SD over the held-out participants (LOSO folds), the folds' values,
and the job's wall time; per model and noise the paired differences res 8 -
res 18 and res 50 - res 18 over the participants both points hold
(positive: res 18 is below), and per model and resolution the noisy minus
the clean accuracy, paired the same way. Writes ``outputs/bench/<name>.json`` with the
machine (``bench/_common.machine``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, write_json  # noqa: E402


def load(sweeps: list[Path], output_dir: Path) -> tuple[pd.DataFrame, dict]:
    """(one row per job and participant, {(model, noise, res): job info})."""
    rows, jobs = [], {}
    for status_file in sorted(f for s in sweeps for f in s.glob("*/sphri_status.json")):
        st = json.loads(status_file.read_text())
        if st.get("status") not in ("FINISHED", "SKIPPED") or not st.get("mlflow_run_id"):
            continue
        ov = dict(o.lstrip("+").split("=", 1) for o in st["overrides"])
        key = (
            ov.get("model", "rf"),
            ov.get("noise", "salt_pepper"),
            int(ov.get("layout.res", ov.get("encoder.res", 18))),
        )
        if key in jobs:
            raise SystemExit(
                f"cnn_gru_noise_check: two jobs for model={key[0]} noise={key[1]} res={key[2]}: "
                f"{jobs[key]['job_dir']} and {status_file.parent}"
            )
        pp = output_dir / "mlartifacts" / st["mlflow_run_id"] / "artifacts" / "per_participant.csv"
        if not pp.is_file():
            raise SystemExit(f"cnn_gru_noise_check: {pp} missing (job {status_file.parent})")
        df = pd.read_csv(pp)
        jobs[key] = {
            "job_dir": str(status_file.parent),
            "overrides": st["overrides"],
            "seconds": st.get("seconds"),
            "from_cache": st.get("from_cache"),
            "run_id": st["mlflow_run_id"],
        }
        for _, r in df.iterrows():
            rows.append(
                {
                    "model": key[0],
                    "noise": key[1],
                    "res": key[2],
                    "participant": r["fold"],
                    "accuracy": float(r["accuracy"]),
                    "macro_f1": float(r["macro_f1"]),
                }
            )
    if not rows:
        raise SystemExit(f"cnn_gru_noise_check: no finished job under {sweeps}")
    return pd.DataFrame(rows), jobs


def _sd(x: np.ndarray) -> float:
    return float(np.std(x, ddof=1)) if len(x) > 1 else float("nan")


def summarize(df: pd.DataFrame, jobs: dict) -> dict:
    points, diffs = [], []
    for (m, n, r), d in df.groupby(["model", "noise", "res"]):
        points.append(
            {
                "model": m,
                "noise": n,
                "res": int(r),
                "n_folds": len(d),
                "accuracy_mean": d.accuracy.mean(),
                "accuracy_sd": _sd(d.accuracy.to_numpy()),
                "macro_f1_mean": d.macro_f1.mean(),
                "macro_f1_sd": _sd(d.macro_f1.to_numpy()),
                "accuracy_per_fold": dict(zip(d.participant, d.accuracy.round(4))),
                **{k: jobs[(m, n, r)][k] for k in ("seconds", "from_cache", "run_id", "overrides")},
            }
        )
    for (m, n), d in df.groupby(["model", "noise"]):
        per = d.pivot(index="participant", columns="res", values="accuracy")
        for r in (8, 50):
            if r in per and 18 in per:
                x = (per[r] - per[18]).dropna().to_numpy()
                diffs.append(
                    {
                        "model": m,
                        "noise": n,
                        "diff": f"res {r} - res 18",
                        "n_participants": len(x),
                        "mean": float(x.mean()),
                        "sd": _sd(x),
                        "per_participant": x.round(4).tolist(),
                    }
                )
    for (m, r), d in df.groupby(["model", "res"]):  # what the noise costs, per resolution
        per = d.pivot(index="participant", columns="noise", values="accuracy")
        if "none" in per and "salt_pepper" in per:
            x = (per["salt_pepper"] - per["none"]).dropna().to_numpy()
            diffs.append(
                {
                    "model": m,
                    "noise": "salt_pepper - none",
                    "diff": f"res {int(r)}",
                    "n_participants": len(x),
                    "mean": float(x.mean()),
                    "sd": _sd(x),
                    "per_participant": x.round(4).tolist(),
                }
            )
    return {"points": points, "paired_differences": diffs}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sweep", type=Path, nargs="+")
    p.add_argument("--output-dir", type=Path, default=Path("outputs"), help="the runs' output_dir (mlartifacts)")
    p.add_argument("--name", default="cnn_gru_noise_check", help="outputs/bench/<name>.json")
    p.add_argument("--note", default="", help="free text stored in the JSON (size, commands, timings)")
    args = p.parse_args(argv)
    df, jobs = load(args.sweep, args.output_dir)
    out = summarize(df, jobs)
    for pt in out["points"]:
        folds = " ".join(f"{v:.3f}" for v in pt["accuracy_per_fold"].values())
        sec = f"{pt['seconds']:.0f} s" + (" (from cache)" if pt["from_cache"] else "")
        print(
            f"{pt['model']:8s} {pt['noise']:12s} res {pt['res']:2d}: accuracy {pt['accuracy_mean']:.3f} +/- "
            f"{pt['accuracy_sd']:.3f}, macro-F1 {pt['macro_f1_mean']:.3f} +/- {pt['macro_f1_sd']:.3f} "
            f"({pt['n_folds']} folds: {folds}; {sec})"
        )
    for d in out["paired_differences"]:
        print(
            f"{d['model']:8s} {d['noise']:12s} {d['diff']}: {d['mean']:+.3f} +/- {d['sd']:.3f} (SD over "
            f"{d['n_participants']} participants)"
        )
    path = write_json(
        args.name, {"sweeps": [str(s) for s in args.sweep], "note": args.note, "machine": machine(), **out}
    )
    print(f"written: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
