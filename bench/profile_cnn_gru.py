"""Profile: where a CNN-GRU LOSO fold's time goes, at res 6 / 18 / 50.

For each resolution, on the first LOSO fold of the windows (full-size
synthetic study by default; ``--quick``: 6 participants x 5 repetitions):

* ``ops``: torch.profiler over ``--batches`` training steps (default
  settings: batch 32, bf16 autocast where native), self CPU time grouped into
  conv forward, conv backward, GRU forward/backward, linear, pooling matmul,
  optimizer, data movement (index/copy/cat/pad) and the rest;
* ``epoch``: one training epoch's and one validation pass's wall/CPU time;
* ``flops``: floating-point operations of one training step
  (``torch.utils.flop_counter``: convolutions and matrix products, the GRU's
  included), per training window, and the epoch's achieved GFLOP per CPU
  second beside a float32 matrix product's on one thread in the same run
  (``matmul_gflops_1_thread``, this CPU's practical peak);
* ``fit`` (``--fit-res``, default 18): one whole fit with the model's
  default (old, ``--budget old``) settings: epochs run, best epoch, and the
  share of epochs discarded by early stopping; ``floor_cpu_s``: the CPU
  seconds of the best epoch's training work alone at the matrix product's
  peak (no discarded epochs, no validation), and its ratio to the fit's.

* ``sweep_estimate`` (two or more ``--res``): the 50-resolution CNN-GRU
  sweep's CPU time extrapolated from these measurements. The CPU seconds of
  an epoch plus its validation pass are interpolated linearly in the taxel
  count between the profiled resolutions (constant beyond them). Each resolution 1..50 gets
  its grid from the study's surface (:func:`sphri.layout.common.grid_dims`),
  then ``epochs_per_fit`` epochs (the res-18 fit's count, or 16), 18 folds, on
  2 cores. Scaled to the res-18 fit's measured CPU seconds per epoch, because
  the profiled epoch holds no trials out for validation.

Writes ``outputs/bench/cnn_gru_profile.json`` (``_quick`` with ``--quick``).

    python bench/profile_cnn_gru.py [--quick] [--res 6 18 50] [--fit-res 18]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.nn.functional as F  # noqa: E402
from _common import machine, write_json  # noqa: E402
from bench_models import get_windows  # noqa: E402

from sphri.models.cnn_gru import CnnGru, CnnGruNet  # noqa: E402

CATEGORIES = [
    ("conv_backward", ("convolution_backward",)),
    ("conv_forward", ("convolution", "conv2d", "mkldnn_conv")),
    ("gru", ("gru", "rnn", "_thnn_fused")),
    ("optimizer", ("adam", "_foreach", "optimizer")),
    (
        "data_movement",
        (
            "index",
            "copy_",
            "cat",
            "pad",
            "to_copy",
            "clone",
            "contiguous",
            "stack",
            "_to_copy",
            "select",
            "slice",
            "reshape",
            "view",
            "permute",
            "transpose",
            "empty",
        ),
    ),
    ("matmul_linear", ("mm", "addmm", "matmul", "linear", "bmm")),
    ("elementwise", ("relu", "threshold", "add", "mul", "sub", "div", "sigmoid", "tanh")),
]


def category(name: str) -> str:
    n = name.lower()
    for cat, keys in CATEGORIES:
        if any(k in n for k in keys):
            return cat
    return "other"


def matmul_gflops(seconds: float = 1.5, n: int = 1024, dtype: torch.dtype = torch.float32) -> float:
    """GFLOP per CPU second of an n x n matrix product in ``dtype`` on one thread (the CPU's practical
    peak for that type: bf16 is several times float32 where the CPU has native bf16, slower where not)."""
    prev = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        a, b = torch.randn(n, n, dtype=dtype), torch.randn(n, n, dtype=dtype)
        a @ b
        c0, k = time.process_time(), 0
        while time.process_time() - c0 < seconds:
            a @ b
            k += 1
        return 2 * n**3 * k / (time.process_time() - c0) / 1e9
    finally:
        torch.set_num_threads(prev)


def first_fold(win):
    g = np.asarray(win.groups)
    held = np.unique(g)[0]
    return np.flatnonzero(g != held), np.flatnonzero(g == held)


def profile_res(win, batches: int) -> dict:
    x, y = win.x, np.asarray(win.y)
    tr, _ = first_fold(win)
    m = CnnGru(geometry=win.geometry)
    grid, wrap = m._layout(x.shape[2])
    torch.manual_seed(0)
    net = CnnGruNet(x.shape[2], grid, wrap, list(m.channels), list(m.strides), m.embed_size, m.hidden, 8)
    opt = torch.optim.AdamW(net.parameters(), lr=m.lr, weight_decay=m.weight_decay)
    dev = torch.device("cpu")
    from sphri.models.cnn_gru import resolve_precision

    m.precision_ = resolve_precision(m.precision, dev)
    xt = torch.from_numpy(np.ascontiguousarray(x[tr]))
    yt = torch.from_numpy(y[tr].astype(np.int64))
    gen = torch.Generator().manual_seed(0)

    def step(b):
        with m._autocast(dev):
            logits = net(xt[b]).float()
        loss = F.cross_entropy(logits, yt[b])
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    order = list(torch.split(torch.randperm(xt.shape[0], generator=gen), m.batch_size))
    for b in order[:3]:  # warm-up
        step(b)
    from torch.utils.flop_counter import FlopCounterMode

    with FlopCounterMode(display=False) as counter:
        step(order[3])
    flops_per_window = counter.get_total_flops() / order[3].numel()
    with torch.profiler.profile(activities=[torch.profiler.ProfilerActivity.CPU]) as prof:
        for b in order[3 : 3 + batches]:
            step(b)
    cats: dict[str, float] = defaultdict(float)
    top = []
    for ev in prof.key_averages():
        cats[category(ev.key)] += ev.self_cpu_time_total / 1e6
        top.append((ev.self_cpu_time_total / 1e6, ev.key))
    total = sum(cats.values())
    top.sort(reverse=True)
    # one epoch and one validation pass (forward only over ~15 % of the training trials)
    c0, t0 = time.process_time(), time.perf_counter()
    net.train()
    for b in order:
        step(b)
    epoch = {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "steps": len(order)}
    nva = int(0.15 * xt.shape[0])
    c0, t0 = time.process_time(), time.perf_counter()
    m._loss_acc(net, xt[:nva], yt[:nva], dev)
    val = {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "trials": nva}
    return {
        "grid_shape": grid,
        "n_train": int(xt.shape[0]),
        "precision": m.precision_,
        "batches_profiled": batches,
        "ops_self_cpu_s": {k: round(v, 3) for k, v in sorted(cats.items(), key=lambda kv: -kv[1])},
        "ops_share": {k: round(v / total, 3) for k, v in sorted(cats.items(), key=lambda kv: -kv[1])},
        "top_ops": [{"op": k, "self_cpu_s": round(v, 3)} for v, k in top[:12]],
        "epoch": {k: round(v, 2) if isinstance(v, float) else v for k, v in epoch.items()},
        "validation_pass": {k: round(v, 2) if isinstance(v, float) else v for k, v in val.items()},
        "validation_share_of_epoch": round(val["wall_s"] / (epoch["wall_s"] + val["wall_s"]), 3),
        "flops": {
            "training_flops_per_window": round(flops_per_window),
            "epoch_gflop": round(flops_per_window * xt.shape[0] / 1e9, 1),
            "epoch_gflop_per_cpu_s": round(flops_per_window * xt.shape[0] / 1e9 / epoch["cpu_s"], 1),
        },
    }


def profile_fit(win, flops_per_window: float | None = None, peak_gflops: float | None = None) -> dict:
    tr, _ = first_fold(win)
    g = np.asarray(win.groups)
    m = CnnGru(geometry=win.geometry)
    c0, t0 = time.process_time(), time.perf_counter()
    m.fit(win.x[tr], np.asarray(win.y)[tr], groups=g[tr])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    ran = len(m.history_)
    out = {
        "wall_s": round(wall, 1),
        "cpu_s": round(cpu, 1),
        "epochs_run": ran,
        "best_epoch": m.best_epoch_,
        "epochs_discarded": ran - m.best_epoch_,
        "discarded_share": round((ran - m.best_epoch_) / ran, 3),
        "n_train": m.n_train_,
        "n_val": m.n_val_,
        "history": m.history_,
    }
    if flops_per_window and peak_gflops:
        floor = m.best_epoch_ * m.n_train_ * flops_per_window / 1e9 / peak_gflops
        out["floor_cpu_s"] = round(floor, 1)
        out["floor_over_fit_cpu"] = round(floor / cpu, 3)
    return out


def sweep_estimate(out: dict, participants: int, reps: int, cores: int = 2) -> dict:
    """Extrapolate the 1..50 resolution sweep's CNN-GRU time from the profiled epochs (see module docstring)."""
    from sphri.cache import StageCache
    from sphri.config import compose
    from sphri.layout.common import grid_dims
    from sphri.pipeline import make_pipeline

    pts = [
        (int(np.prod(e["grid_shape"])), e["epoch"]["cpu_s"] + e["validation_pass"]["cpu_s"])
        for e in out["res"].values()
        if "epoch" in e
    ]
    pts.sort()
    n_tax = np.array([t for t, _ in pts], dtype=float)
    cost = np.array([c for _, c in pts])
    fit18 = out["res"].get("18", {}).get("fit_old_settings")
    epochs = fit18["epochs_run"] if fit18 else 16
    # the profiled epoch trains on every non-held-out trial; a fit holds ~15 % out for validation:
    # calibrate to the measured res-18 fit (CPU s per epoch, validation included) where there is one
    calib = 1.0
    e18 = out["res"].get("18", {})
    if fit18 and "epoch" in e18:
        calib = fit18["cpu_s"] / fit18["epochs_run"] / (e18["epoch"]["cpu_s"] + e18["validation_pass"]["cpu_s"])
    cfg = compose(
        [
            "data=synthetic",
            "data.regions=[arm]",
            f"data.participants={participants}",
            f"data.repetitions={reps}",
            "seed=0",
        ]
    )
    surface = make_pipeline(cfg, StageCache(root=cfg.cache.dir, enabled=bool(cfg.cache.enabled))).get("surface")
    per_res = {}
    for r in range(1, 51):
        h, w = grid_dims(surface, r)
        per_res[r] = float(np.interp(h * w, n_tax, cost)) * calib * epochs * participants / cores
    total = sum(per_res.values())
    return {
        "epoch_cpu_s_points": [[int(t), round(float(c), 2)] for t, c in pts],
        "epochs_per_fit": epochs,
        "calibration_to_res18_fit": round(float(calib), 3),
        "folds": participants,
        "cores": cores,
        "per_res_wall_min": {str(r): round(v / 60, 1) for r, v in per_res.items() if r in (1, 6, 18, 36, 50)},
        "sweep_wall_h": round(float(total) / 3600, 1),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--res", type=int, nargs="+", default=[6, 18, 50])
    ap.add_argument("--fit-res", type=int, nargs="*", default=[18])
    ap.add_argument("--batches", type=int, default=10)
    ap.add_argument("--peak-only", action="store_true", help="only the one-thread matrix-product peaks (seconds)")
    args = ap.parse_args(argv)
    if args.peak_only:
        peak = {"machine": machine(), "torch": torch.__version__, "n": 1024, "gflop_per_cpu_s_1_thread": {}}
        for name, dtype in (("float32", torch.float32), ("bf16", torch.bfloat16)):
            peak["gflop_per_cpu_s_1_thread"][name] = round(matmul_gflops(dtype=dtype), 1)
        print(peak["gflop_per_cpu_s_1_thread"], flush=True)
        write_json("matmul_peak", peak)
        return 0
    participants, reps = (6, 5) if args.quick else (18, 20)
    torch.set_num_threads(2)
    out = {
        "machine": machine(),
        "quick": args.quick,
        "threads": torch.get_num_threads(),
        "matmul_gflops_1_thread": round(matmul_gflops(), 1),
        "res": {},
    }
    for res in sorted(set(args.res) | set(args.fit_res)):
        win, source, _ = get_windows("pipeline", res, participants, reps, seed=0)
        entry = {"data_source": source, "windows": list(win.x.shape)}
        if res in args.res:
            entry.update(profile_res(win, args.batches))
        if res in args.fit_res:
            fpw = entry.get("flops", {}).get("training_flops_per_window")
            entry["fit_old_settings"] = profile_fit(win, fpw, out["matmul_gflops_1_thread"])
        out["res"][str(res)] = entry
        print(res, {k: v for k, v in entry.items() if k not in ("top_ops", "fit_old_settings")}, flush=True)
        write_json("cnn_gru_profile_quick" if args.quick else "cnn_gru_profile", out)
    if sum("epoch" in e for e in out["res"].values()) >= 2:
        out["sweep_estimate"] = sweep_estimate(out, participants, reps)
        print("sweep estimate", out["sweep_estimate"], flush=True)
        write_json("cnn_gru_profile_quick" if args.quick else "cnn_gru_profile", out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
