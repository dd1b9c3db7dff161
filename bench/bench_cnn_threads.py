"""Benchmark: the CNN-GRU's fold-process/thread split on whole folds (issue 31, item 5).

Runs the first ``--folds`` (default 2) leave-one-subject-out folds of the CNN-GRU, each fold trained
to its end (early stopping as configured), once per layout in ``--layouts`` (default ``2x1 1x2``:
2 fold processes x 1 thread, 1 process x 2 threads; ``cv.workers`` x ``cv.threads_per_worker``),
interleaved over ``--rounds`` rounds (A B, B A, ...) so that a change in the machine's load hits
every layout alike. Each row records wall and CPU seconds, every fold's time and accuracy, and the
1-minute load average before and after; the file records the machine (CPU model and SIMD flags via
:mod:`sphri.tracking.machine`, cores, torch). Read the ratio only within one file: it depends on the
CPU and on what else runs on it (the load average says how busy the machine was).

    python bench/bench_cnn_threads.py                                   # full study, res 18
    python bench/bench_cnn_threads.py --quick                           # 6 participants x 5 repetitions, res 8
    python bench/bench_cnn_threads.py --windows outputs/bench/windows_res18.entry   # windows saved by bench_models

Writes ``outputs/bench/<name>.json`` (default ``cnn_threads``, ``cnn_threads_quick`` with ``--quick``).
"""

from __future__ import annotations

import argparse
import functools
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import machine, write_json  # noqa: E402
from bench_models import describe_windows, get_windows, load_windows  # noqa: E402

from sphri.evaluate.cv import LeaveOneSubjectOut  # noqa: E402
from sphri.models.cnn_gru import CnnGru  # noqa: E402

log = logging.getLogger("bench_cnn_threads")


def parse_layout(text: str) -> tuple[int, int]:
    """``"2x1"`` -> (2 workers, 1 thread each)."""
    try:
        w, t = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"layout {text!r}: expected WORKERSxTHREADS, e.g. 2x1") from None
    if w < 1 or t < 1:
        raise argparse.ArgumentTypeError(f"layout {text!r}: workers and threads must be >= 1")
    return w, t


def run_layout(make, win, workers: int, threads: int, folds: int) -> dict:
    """The first ``folds`` LOSO folds with ``workers`` x ``threads``: times, accuracies, load."""
    timings: list[dict] = []
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    cv = LeaveOneSubjectOut(workers=workers, threads_per_worker=threads, max_folds=folds, progress=False)
    result = cv.run(make, win, seed=0, on_fold=lambda r, t: timings.append(t))
    wall = time.perf_counter() - t0
    return {
        "layout": f"{workers}x{threads}",
        "workers": workers,
        "threads_per_worker": threads,
        "wall_s": round(wall, 2),
        "fold_cpu_s": [round(t["cpu_s"], 2) for t in timings],
        "fold_wall_s": [round(t["wall_s"], 2) for t in timings],
        "fold_accuracy": [round(f.accuracy, 6) for f in result.folds],
        "loadavg_1min_start": load0,
        "loadavg_1min_end": os.getloadavg()[0],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layouts", nargs="+", type=parse_layout, default=[(2, 1), (1, 2)], help="WORKERSxTHREADS")
    ap.add_argument("--folds", type=int, default=2, help="whole LOSO folds per run (default 2)")
    ap.add_argument("--rounds", type=int, default=1, help="interleaved rounds (the order alternates)")
    ap.add_argument("--quick", action="store_true", help="6 participants x 5 repetitions at res 8 (make bench)")
    ap.add_argument("--res", type=int, default=None, help="default 18 (8 with --quick)")
    ap.add_argument("--participants", type=int, default=None, help="default 18 (6 with --quick)")
    ap.add_argument("--repetitions", type=int, default=None, help="default 20 (5 with --quick)")
    ap.add_argument("--data", choices=["pipeline", "toy"], default="pipeline")
    ap.add_argument("--windows", default=None, help="windows saved by bench_models.py --save-windows")
    ap.add_argument("--precision", default=None, help="CNN-GRU precision (default: the model's, auto)")
    ap.add_argument("--name", default=None, help="default cnn_threads (cnn_threads_quick with --quick)")
    args = ap.parse_args(argv)
    args.res = args.res or (8 if args.quick else 18)
    args.participants = args.participants or (6 if args.quick else 18)
    args.repetitions = args.repetitions or (5 if args.quick else 20)
    args.name = args.name or ("cnn_threads_quick" if args.quick else "cnn_threads")
    if args.folds < 1 or args.rounds < 1:
        ap.error("--folds and --rounds must be >= 1")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")

    t0 = time.perf_counter()
    if args.windows:
        win, source, note = load_windows(args.windows), "file", str(args.windows)
    else:
        win, source, note = get_windows(args.data, args.res, args.participants, args.repetitions, seed=0)
    log.info("windows %s from %s in %.1f s", win.x.shape, source, time.perf_counter() - t0)
    make = functools.partial(CnnGru, geometry=win.geometry, **({"precision": args.precision} if args.precision else {}))
    out: dict = {
        "command": "python bench/bench_cnn_threads.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "machine": {**machine(), "affinity_cores": len(os.sched_getaffinity(0))},
        "data": describe_windows(win, source, note, args),
        "model": {k: v for k, v in make().get_params().items() if k != "geometry"},
        "folds": args.folds,
        "rows": [],
    }
    for r in range(args.rounds):
        order = args.layouts if r % 2 == 0 else args.layouts[::-1]
        for workers, threads in order:
            row = {"round": r, **run_layout(make, win, workers, threads, args.folds)}
            log.info("%s", row)
            out["rows"].append(row)
            write_json(args.name, out)
    walls = {
        f"{w}x{t}": [x["wall_s"] for x in out["rows"] if x["workers"] == w and x["threads_per_worker"] == t]
        for w, t in args.layouts
    }
    out["median_wall_s"] = {k: float(np.median(v)) for k, v in walls.items()}
    first = f"{args.layouts[0][0]}x{args.layouts[0][1]}"
    out["speedup_vs_" + first] = {k: round(out["median_wall_s"][first] / v, 3) for k, v in out["median_wall_s"].items()}
    accs = {tuple(x["fold_accuracy"]) for x in out["rows"]}
    out["fold_accuracies_identical"] = len(accs) == 1
    out["machine"]["loadavg_1min_end"] = os.getloadavg()[0]
    path = write_json(args.name, out)
    print(f"wrote {path}: median wall {out['median_wall_s']}; accuracies identical: {len(accs) == 1}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
