"""bf16 against float32 for the CNN-GRU: the same folds and seeds, compared with the seed spread (issue 31).

Reads the finished CNN-GRU jobs of one resolution from an output folder's MLflow store, made by

    python -m sphri -m model=cnn_gru layout.res=18 model.seed=0,1,2 \\
        model.precision=float32,bf16 cv.workers=2

(18 LOSO folds x 3 seeds x 2 precisions; resumable: a rerun recomputes only missing folds), and
writes ``outputs/bench/bf16_parity.json`` and a Markdown table on stdout:

- per precision: accuracy and macro-F1 of each seed (mean over its folds), their mean, and the
  seed spread (standard deviation of the seed means, ddof=1);
- paired: bf16 minus float32 on every (seed, fold), its mean with a 95 % bootstrap interval
  (10,000 resamples of the pairs, seed 0), against the largest difference between two float32
  seeds (what changing only the initialisation moves the result by);
- the machine each run recorded (``sphri.machine.*`` tags, torch) and the fit time per fold.

The verdict is printed as measured: "within the seed spread" when both ends of the paired
difference's interval lie inside +/- the largest float32 seed difference; with one seed in both
precisions there is no spread and no verdict. Usage:
``python bench/bf16_parity.py OUTPUT_DIR [--res 18] [--name bf16_parity]``.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_json  # noqa: E402

PRECISIONS = ("float32", "bf16")
METRICS = ("accuracy", "macro_f1")


def _fold_metric(client: Any, run_id: str, name: str) -> dict[int, float]:
    return {m.step: m.value for m in client.get_metric_history(run_id, f"fold_{name}")}


def collect(output_dir: Path, res: int) -> dict[str, dict[int, dict[str, Any]]]:
    """``{precision: {seed: {"accuracy": {fold: value}, "macro_f1": {...}, "tags": ..., "seconds": ...}}}``
    of the FINISHED CNN-GRU jobs at ``res`` (the latest run of each (precision, seed))."""
    from mlflow.tracking import MlflowClient

    from sphri.tracking.mlflow_tracker import default_uri

    db = output_dir / "mlflow.db"
    if not db.is_file():
        raise SystemExit(f"bf16_parity: no MLflow store at {db} (run the sweep in the module docstring there)")
    client = MlflowClient(default_uri(output_dir))
    found: dict[str, dict[int, dict[str, Any]]] = {p: {} for p in PRECISIONS}
    for exp in client.search_experiments():
        runs = client.search_runs(
            [exp.experiment_id],
            f"attributes.status = 'FINISHED' and tags.`sphri.kind` = 'job' and params.`layout.res` = '{res}'",
            order_by=["attributes.start_time ASC"],
        )
        for run in runs:
            params = run.data.params
            if not str(params.get("model", "")).lower().startswith("cnn"):
                continue
            precision, seed = params.get("run.precision"), params.get("model.seed")
            if precision not in found or seed is None:
                continue
            found[precision][int(seed)] = {
                **{name: _fold_metric(client, run.info.run_id, name) for name in METRICS},
                "run_id": run.info.run_id,
                "seconds": run.data.metrics.get("time/evaluate_s"),
                "machine": {
                    k: v for k, v in run.data.tags.items() if k.startswith(("sphri.machine.", "sphri.lib.torch"))
                },
            }
    return found


def compare(found: dict[str, dict[int, dict[str, Any]]]) -> dict[str, Any]:
    from sphri.evaluate.metrics import bootstrap_ci

    seeds = sorted(set(found["float32"]) & set(found["bf16"]))
    if not seeds:
        raise SystemExit(
            "bf16_parity: no seed has a finished job in both precisions yet "
            f"(float32 seeds {sorted(found['float32'])}, bf16 seeds {sorted(found['bf16'])})"
        )
    out: dict[str, Any] = {"seeds": seeds, "metrics": {}}
    for name in METRICS:
        per = {}
        for p in PRECISIONS:
            seed_means = [float(np.mean(list(found[p][s][name].values()))) for s in seeds]
            per[p] = {
                "seed_means": seed_means,
                "mean": float(np.mean(seed_means)),
                "seed_std": float(np.std(seed_means, ddof=1)) if len(seeds) > 1 else float("nan"),
            }
        pairs = [
            found["bf16"][s][name][f] - found["float32"][s][name][f]
            for s in seeds
            for f in sorted(set(found["bf16"][s][name]) & set(found["float32"][s][name]))
        ]
        diff = np.asarray(pairs)
        lo, hi = bootstrap_ci(diff, n_boot=10_000, seed=0)
        f32 = per["float32"]["seed_means"]
        seed_gap = max((abs(a - b) for a, b in itertools.combinations(f32, 2)), default=float("nan"))
        # one seed has no spread to compare with: no verdict (None), not "outside"
        within = bool(max(abs(lo), abs(hi)) <= seed_gap) if np.isfinite(seed_gap) else None
        out["metrics"][name] = {
            **per,
            "n_pairs": len(pairs),
            "paired_mean_diff": float(diff.mean()),
            "paired_ci95": [lo, hi],
            "largest_float32_seed_gap": seed_gap,
            "within_seed_spread": within,
        }
    out["seconds_per_job"] = {p: [found[p][s]["seconds"] for s in seeds] for p in PRECISIONS}
    out["machine"] = {p: found[p][seeds[0]]["machine"] for p in PRECISIONS}
    return out


def table(result: dict[str, Any]) -> str:
    lines = [
        "| metric | precision | seed means | mean | seed std | bf16 - float32 (paired, 95 % CI) | largest float32 seed gap |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, m in result["metrics"].items():
        for p in PRECISIONS:
            seeds = " / ".join(f"{v:.3f}" for v in m[p]["seed_means"])
            paired = (
                f"{m['paired_mean_diff']:+.3f} [{m['paired_ci95'][0]:+.3f}, {m['paired_ci95'][1]:+.3f}] "
                f"over {m['n_pairs']} folds"
                if p == "bf16"
                else ""
            )
            gap = f"{m['largest_float32_seed_gap']:.3f}" if p == "float32" else ""
            lines.append(f"| {name} | {p} | {seeds} | {m[p]['mean']:.3f} | {m[p]['seed_std']:.3f} | {paired} | {gap} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output_dir", type=Path, help="the sweep's output_dir (holds mlflow.db)")
    parser.add_argument("--res", type=int, default=18, help="layout.res of the jobs to compare (default 18)")
    parser.add_argument("--name", default="bf16_parity", help="outputs/bench/NAME.json (default bf16_parity)")
    args = parser.parse_args(argv)
    result = compare(collect(args.output_dir, args.res))
    result["res"] = args.res
    path = write_json(args.name, result)
    print(table(result))
    for name, m in result["metrics"].items():
        if m["within_seed_spread"] is None:
            print(f"{name}: no verdict: one seed in both precisions has no seed spread to compare with")
            continue
        verdict = "within" if m["within_seed_spread"] else "NOT within"
        print(f"{name}: bf16 is {verdict} the float32 seed spread ({len(result['seeds'])} seeds)")
    print(f"written: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
