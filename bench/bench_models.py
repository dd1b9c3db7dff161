"""Benchmark: Random Forest and CNN-GRU leave-one-subject-out at full size.

Targets (2 cores, about 2,800 trials, 18 folds, res 18 -> 18 x 19 grid,
L = 50): RF LOSO < 60 s, CNN-GRU LOSO < 15 min. Writes
``outputs/bench/models.json`` (``models_quick.json`` with ``--quick``).

Wall times depend on what else runs on the machine; ``fold_cpu_s`` (CPU
seconds of all folds) / workers gives ``cpu_bound_wall_s``, the wall time on
idle cores, and ``cpu_bound_wall_all_folds_s`` extrapolates a ``--cnn-folds``
subset to every participant.

Data: ``--data pipeline`` (default) runs the sphri chain on the built-in
synthetic gestures (``data=synthetic``, 18 participants x 20 repetitions,
cached under outputs/cache); ``--data toy`` uses
:func:`sphri.testing.toy_windows.blob_windows` (moving blobs, same size). If the
pipeline fails the toy data is used and the JSON says so.

CNN-GRU training budgets (``--budgets``, default :data:`DEFAULT_BUDGETS`):
the paper's settings (``paper``: 20 epochs at most, early stopping with
patience 4) and shorter one-cycle schedules, each run on the same folds in
this one process, so their CPU seconds and accuracies compare side by side.
``models_pareto.png`` (``_quick``) plots CPU seconds per fold against LOSO
accuracy for each budget, with the Random Forest's single point, and marks
the budgets no other budget beats on both.

    python bench/bench_models.py            # full size
    python bench/bench_models.py --quick    # 6 participants, CNN on 3 folds
    python bench/bench_models.py --budgets paper onecycle8 --cnn-folds 3

Run-to-run spread (``--seeds 0 1 2 3 4``): each budget runs LOSO once per
model seed (the seed also picks the early-stopping participants), and the
JSON gives the LOSO accuracy of every seed, their mean and standard
deviation, and whether a budget's mean is at or above the paper's lowest
seed (``within_paper_seed_spread``). ``--save-windows F`` / ``--windows F`` store and reuse the
model input (a stage-cache entry: checksummed arrays + JSON, no pickle), so the same windows can be trained on
another machine, e.g. ``--device cuda --workers 12`` for many seeds at once
(accuracies only: GPU float32 is not bit-identical to the CPU's):

    python bench/bench_models.py --skip-cnn --save-windows outputs/bench/windows_res18.entry
    python bench/bench_models.py --windows outputs/bench/windows_res18.entry --device cuda --precision float32 \
        --workers 12 --seeds 0 1 2 3 4 --budgets paper batch8_e7 --name models_seeds
"""

from __future__ import annotations

import argparse
import functools
import logging
import os
import platform
import sys
import time
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import OUT as OUT_DIR  # noqa: E402
from _common import machine, write_json  # noqa: E402

from sphri.evaluate.cv import LeaveOneSubjectOut  # noqa: E402
from sphri.evaluate.metrics import summarize  # noqa: E402
from sphri.models.cnn_gru import CnnGru  # noqa: E402
from sphri.models.rf import RandomForest  # noqa: E402
from sphri.testing.toy_windows import blob_windows  # noqa: E402
from sphri.types import WindowedFrames  # noqa: E402

log = logging.getLogger("bench_models")


#: CNN-GRU training budgets compared (settings over the model's defaults, the paper's).
BUDGETS: dict[str, dict] = {
    "paper": {},
    "onecycle8": {"schedule": "onecycle", "max_epochs": 8, "patience": 99},
    "onecycle6_lr2e-3": {"schedule": "onecycle", "max_epochs": 6, "patience": 99, "lr": 2e-3},
    "onecycle4_lr3e-3": {"schedule": "onecycle", "max_epochs": 4, "patience": 99, "lr": 3e-3},
    # the paper's lr and optimizer, 4x the updates per epoch (batch 8 costs ~1.16x batch 32 per window)
    "batch8_e7": {"batch_size": 8, "max_epochs": 7, "patience": 99},
    # the paper's settings without early stopping's discarded tail (its best epoch averages ~11)
    "paper_e13": {"max_epochs": 13, "patience": 99},
    # explored on a GPU over seeds (docs/BENCHMARKS.md, "Run-to-run spread"); not run by default
    "batch8_e4": {"batch_size": 8, "max_epochs": 4, "patience": 99},
    "batch8_e3": {"batch_size": 8, "max_epochs": 3, "patience": 99},
    "batch4_e3": {"batch_size": 4, "max_epochs": 3, "patience": 99},
    "batch8_oc4_lr2e-3": {"batch_size": 8, "max_epochs": 4, "patience": 99, "schedule": "onecycle", "lr": 2e-3},
    "batch16_oc4_lr3e-3": {"batch_size": 16, "max_epochs": 4, "patience": 99, "schedule": "onecycle", "lr": 3e-3},
    "batch16_e8": {"batch_size": 16, "max_epochs": 8, "patience": 99},
}

#: Budgets run when ``--budgets`` is not given (``make bench``).
DEFAULT_BUDGETS: list[str] = ["paper", "onecycle8", "onecycle6_lr2e-3", "onecycle4_lr3e-3", "batch8_e7", "paper_e13"]


def pareto_front(points: dict[str, tuple[float, float]]) -> list[str]:
    """Names whose (cost, accuracy) no other point beats on both (lower cost, higher accuracy)."""
    return [
        n
        for n, (c, a) in points.items()
        if not any(c2 <= c and a2 >= a and (c2, a2) != (c, a) for c2, a2 in points.values())
    ]


def plot_pareto(out: dict, path_stem: str) -> list:
    """CPU seconds per fold against accuracy: every CNN-GRU budget and the Random Forest."""
    from sphri.figures import new_figure, save

    points = {
        f"cnn_gru {n}": (b["fold_cpu_s"] / b["folds"], b["accuracy_mean"]) for n, b in out["cnn_gru_budgets"].items()
    }
    rf = (out["rf"]["fold_cpu_s"] / out["rf"]["folds"], out["rf"]["accuracy_mean"])
    front = set(pareto_front({**points, "rf": rf}))
    fig, ax = new_figure("one", height=3.2)
    for i, (name, (c, a)) in enumerate({**points, "Random Forest": rf}.items()):
        on_front = name in front or (name == "Random Forest" and "rf" in front)
        ax.scatter(
            [c],
            [a],
            marker="s" if name == "Random Forest" else "o",
            s=22,
            zorder=3,
            color=f"C{i}",
            facecolors=f"C{i}" if on_front else "none",
            label=name.removeprefix("cnn_gru ") + (" (Pareto)" if on_front else ""),
        )
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.25), ncol=2, fontsize=7, frameon=False)
    ax.set_xscale("log")
    from matplotlib.ticker import NullFormatter

    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("CPU seconds per fold")
    ax.set_ylabel("LOSO accuracy (mean of folds)")
    ax.grid(alpha=0.3)
    return save(fig, OUT_DIR / path_stem, formats=("png",))


def pipeline_windows(res: int, participants: int, repetitions: int, seed: int) -> WindowedFrames:
    """Windows from the sphri chain (synthetic data, arm), stages cached on disk."""
    from sphri.cache import StageCache
    from sphri.config import compose
    from sphri.pipeline import make_pipeline

    cfg = compose(
        [
            "data=synthetic",
            "data.regions=[arm]",
            f"data.participants={participants}",
            f"data.repetitions={repetitions}",
            f"layout.res={res}",
            f"seed={seed}",
        ]
    )
    p = make_pipeline(cfg, StageCache(root=cfg.cache.dir, enabled=bool(cfg.cache.enabled)))
    return p.get("filter")  # the model's input: windows, noise, skin-side filter


def describe_windows(win, source: str, note: str, args) -> dict:
    """The ``data`` entry of a bench's JSON: where the windows came from and their shape."""
    return {
        "source": source,
        "note": note,
        "n_trials": int(win.x.shape[0]),
        "L": int(win.x.shape[1]),
        "n_taxels": int(win.x.shape[2]),
        "grid_shape": win.geometry.grid_shape,
        "participants": int(len(set(win.groups))),
        "res": None if args.windows else args.res,
    }


def get_windows(
    source: str, res: int, participants: int, repetitions: int, seed: int
) -> tuple[WindowedFrames, str, str]:
    if source == "pipeline":
        try:
            return pipeline_windows(res, participants, repetitions, seed), "pipeline", ""
        except Exception as exc:  # the chain is optional here: fall back, say why
            note = f"pipeline failed ({type(exc).__name__}: {exc}); used toy data"
            log.warning("%s\n%s", note, traceback.format_exc())
            return blob_windows(participants, repetitions, res, seed=seed), "toy", note
    return blob_windows(participants, repetitions, res, seed=seed), "toy", ""


def save_windows(win: WindowedFrames, path: str) -> Path:
    """Write the windows to ``path`` in the stage cache's entry format (checksummed arrays + JSON, no pickle)."""
    from sphri.cache import write_entry

    return write_entry(Path(path), win, {"what": "bench windows"})


def load_windows(path: str) -> WindowedFrames:
    """Windows written by :func:`save_windows`; a clear error for a file that is not one."""
    from sphri.cache import CorruptEntry, read_entry
    from sphri.codec import DecodeError

    try:
        return read_entry(Path(path), WindowedFrames)[1]
    except (OSError, CorruptEntry, DecodeError) as exc:
        raise SystemExit(f"--windows {path}: not windows written by --save-windows ({exc})") from None


def combine_seeds(rows: dict[int, dict]) -> dict:
    """One budget's LOSO rows, one per model seed -> one row: accuracy, CPU and wall time are means
    over the seeds; the per-fold fields (``per_fold_accuracy``, ``accuracy_std``, ...) are the first
    seed's (``per_fold_fields_seed``); ``by_seed`` keeps every seed's."""
    accs = [r["accuracy_mean"] for r in rows.values()]
    first = dict(next(iter(rows.values())))
    first["per_fold_fields_seed"] = next(iter(rows))
    first["by_seed"] = {
        str(s): {k: r[k] for k in ("accuracy_mean", "fold_cpu_s", "wall_s", "folds", "per_fold_accuracy")}
        for s, r in rows.items()
    }
    first["seed_accuracy"] = [round(a, 4) for a in accs]
    first["accuracy_mean"] = float(np.mean(accs))
    first["seed_accuracy_sd"] = float(np.std(accs, ddof=1)) if len(accs) > 1 else float("nan")
    first["fold_cpu_s"] = round(float(np.mean([r["fold_cpu_s"] for r in rows.values()])), 1)
    first["wall_s"] = round(float(np.mean([r["wall_s"] for r in rows.values()])), 1)
    return first


def timed_loso(make, windows: WindowedFrames, workers: int, threads: int, max_folds: int | None) -> dict:
    cv = LeaveOneSubjectOut(workers=workers, threads_per_worker=threads, max_folds=max_folds, progress=True)
    timings: list[dict] = []
    c0, t0 = time.process_time(), time.perf_counter()
    result = cv.run(make, windows, seed=0, on_fold=lambda res, timing: timings.append(timing))
    wall = time.perf_counter() - t0
    s = summarize(result, seed=0)
    fold_cpu = sum(t["cpu_s"] for t in timings)
    n_all = len(set(windows.groups))
    return {
        "wall_s": round(wall, 2),
        "parent_cpu_s": round(time.process_time() - c0, 2),
        # load-independent: the folds' CPU seconds spread over the workers
        "fold_cpu_s": round(fold_cpu, 1),
        "cpu_bound_wall_s": round(fold_cpu / min(workers, len(timings)), 1),
        "cpu_bound_wall_all_folds_s": round(fold_cpu / len(timings) * n_all / workers, 1),
        "fold_wall_s": [round(t["wall_s"], 1) for t in timings],
        "folds": len(result.folds),
        "accuracy_mean": s["accuracy_mean"],
        "accuracy_std": s["accuracy_std"],
        "accuracy_ci": [s["accuracy_ci_low"], s["accuracy_ci_high"]],
        "macro_f1_mean": s["macro_f1_mean"],
        "per_fold_accuracy": [round(f.accuracy, 4) for f in result.folds],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="6 participants x 5 repetitions; CNN on 3 folds")
    ap.add_argument("--data", choices=["pipeline", "toy"], default="pipeline")
    ap.add_argument("--res", type=int, default=18)
    ap.add_argument("--participants", type=int, default=None)
    ap.add_argument("--repetitions", type=int, default=None)
    ap.add_argument("--workers", type=int, default=2, help="fold processes (default 2)")
    ap.add_argument("--threads", type=int, default=1, help="threads per fold process (default 1)")
    ap.add_argument("--skip-cnn", action="store_true")
    ap.add_argument("--cnn-folds", type=int, default=None, help="CNN on the first K folds only")
    ap.add_argument(
        "--budgets",
        nargs="+",
        choices=list(BUDGETS),
        default=DEFAULT_BUDGETS,
        help=f"CNN-GRU training budgets to compare (default: {' '.join(DEFAULT_BUDGETS)})",
    )
    ap.add_argument(
        "--seeds",
        nargs="+",
        type=int,
        default=[0],
        help="model seeds: each budget runs LOSO once per seed (default: 0)",
    )
    ap.add_argument("--device", default="cpu", help="CNN-GRU device: cpu (default), cuda, cuda:K")
    ap.add_argument(
        "--precision",
        choices=["auto", "float32", "bf16"],
        default=None,
        help="CNN-GRU precision (default: the model's, auto)",
    )
    ap.add_argument(
        "--windows", default=None, help="read the windows from this file (--save-windows) instead of --data"
    )
    ap.add_argument("--save-windows", default=None, help="also write the windows to this .npz")
    ap.add_argument("--name", default=None, help="output name under outputs/bench (default: models or models_quick)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")

    name = args.name or ("models_quick" if args.quick else "models")  # a quick run never overwrites the full numbers
    participants = args.participants or (6 if args.quick else 18)
    repetitions = args.repetitions or (5 if args.quick else 20)
    cnn_folds = args.cnn_folds or (3 if args.quick else None)
    t0 = time.perf_counter()
    if args.windows:
        win, source, note = load_windows(args.windows), "file", str(args.windows)
    else:
        win, source, note = get_windows(args.data, args.res, participants, repetitions, seed=0)
    if args.save_windows:
        log.info("windows written to %s", save_windows(win, args.save_windows))
    data_s = time.perf_counter() - t0
    log.info("windows %s from %s in %.1f s", win.x.shape, source, data_s)

    out: dict = {
        "machine": {
            **machine(),
            "platform": platform.processor() or platform.machine(),
            "affinity_cores": len(os.sched_getaffinity(0)),
        },
        "quick": args.quick,
        "data": {**describe_windows(win, source, note, args), "seconds": round(data_s, 1)},
        "cv": {"scheme": "loso", "workers": args.workers, "threads_per_worker": args.threads},
        "cnn_gru_run": {
            "device": args.device,
            "precision": args.precision or "auto (the model's default)",
            "seeds": args.seeds,
        },
        "targets_s": {"rf": 60, "cnn_gru": 900},
    }
    rf = functools.partial(RandomForest, geometry=win.geometry)
    out["rf"] = timed_loso(rf, win, args.workers, args.threads, None)
    log.info("rf: %s", {k: v for k, v in out["rf"].items() if k != "per_fold_accuracy"})
    write_json(name, out)
    if not args.skip_cnn:
        out["cnn_gru_budgets"] = {}
        run_kw = {"device": args.device, **({"precision": args.precision} if args.precision else {})}
        for budget in args.budgets:
            settings = BUDGETS[budget]
            rows = {}
            for seed in args.seeds:
                cnn = functools.partial(CnnGru, geometry=win.geometry, seed=seed, **run_kw, **settings)
                rows[seed] = timed_loso(cnn, win, args.workers, args.threads, cnn_folds)
                log.info("cnn_gru %s seed %d: accuracy %.4f", budget, seed, rows[seed]["accuracy_mean"])
            row = combine_seeds(rows) if len(rows) > 1 else rows[args.seeds[0]]
            row["settings"] = settings
            out["cnn_gru_budgets"][budget] = row
            log.info("cnn_gru %s: %s", budget, {k: v for k, v in row.items() if k != "per_fold_accuracy"})
            write_json(name, out)
        if "paper" in out["cnn_gru_budgets"]:
            out["cnn_gru"] = {
                **out["cnn_gru_budgets"]["paper"],
                "params": {k: v for k, v in CnnGru().get_params().items() if k != "geometry"},
            }
            base = out["cnn_gru"]["fold_cpu_s"]
            out["cnn_gru_cpu_ratio_vs_paper"] = {
                n: round(b["fold_cpu_s"] / base, 3) for n, b in out["cnn_gru_budgets"].items()
            }
            if len(args.seeds) > 1:  # is each budget's seed mean at or above the paper's lowest seed?
                lowest = min(out["cnn_gru"]["seed_accuracy"])
                out["within_paper_seed_spread"] = {
                    n: bool(b["accuracy_mean"] >= lowest) for n, b in out["cnn_gru_budgets"].items()
                }
        out["pareto_front"] = pareto_front(
            {
                **{
                    f"cnn_gru {n}": (b["fold_cpu_s"] / b["folds"], b["accuracy_mean"])
                    for n, b in out["cnn_gru_budgets"].items()
                },
                "rf": (out["rf"]["fold_cpu_s"] / out["rf"]["folds"], out["rf"]["accuracy_mean"]),
            }
        )
        plot_pareto(out, f"{name}_pareto")
    out["machine"]["loadavg_1min_end"] = os.getloadavg()[0]
    path = write_json(name, out)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
