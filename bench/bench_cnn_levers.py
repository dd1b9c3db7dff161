"""Benchmark: three levers on the CNN-GRU's training step, each against a baseline in the same run.

Every measurement is a fresh process (``--child``) that builds the CNN-GRU exactly as ``CnnGru.fit``
does (same network, seed, precision rule, deterministic algorithms), runs ``--warmup`` training steps,
then ``--steps`` measured steps of batch 32 on the built-in synthetic study's windows, and records per
step: user and system CPU seconds (``resource.getrusage``, all threads of the process), minor and major
page faults (``ru_minflt``, ``ru_majflt``), voluntary and involuntary context switches, wall seconds;
its peak resident memory; and every step's loss with a checksum of the final weights, so the file
says whether a lever changes the numbers. It also counts a step's floating-point operations and
measures, in the same run, the one-thread matrix-product peak in float32 and bf16, so each variant's
GFLOP per CPU second is read as a share of its precision's peak (``share_of_peak``).

Levers (``--levers``), each a set of variants measured in ``--rounds`` interleaved rounds (the order
alternates: A B C, C B A, ...) so that a change in the machine's load hits every variant alike:

* ``alloc``: glibc's allocator keeps freed memory: ``mallopt`` at run time (``M_MMAP_THRESHOLD``
  32 MiB, glibc's largest, and ``M_TRIM_THRESHOLD`` 1 GiB), and the same through the
  ``MALLOC_MMAP_THRESHOLD_`` / ``MALLOC_TRIM_THRESHOLD_`` variables of a fresh process;
* ``threads``: 2 OpenMP threads with the default wait policy, 2 threads with
  ``OMP_WAIT_POLICY=PASSIVE`` (read when the OpenMP runtime starts: a fresh process), 1 thread;
  once on the otherwise idle cores (``threads``) and once while a competing process spins on one
  core (``threads_contended``: another fold, a test worker, another engineer's job);
* ``channels_last``: the CNN's convolutions on channels-last (NHWC) tensors;
* ``channels_last_fit``: channels-last on top of the allocator ``fit`` sets (what adopting it would save
  in a fold);
* ``precision``: float32 against bf16, both with the allocator ``fit`` sets: the ratio is what bf16
  saves (run it where the CPU has bf16 natively and at a grid outside the defect class, e.g. res 18).

``alloc`` and ``channels_last`` run with ``--threads`` threads (default 1: a fold process's share of
2 cores, and the least disturbed by other work on the machine). Ratios are baseline / variant of the
median over rounds of the mean CPU (or wall) seconds per step: above 1 the lever saves. The per-round
ratios' range is the run-to-run spread to read them against.

    python bench/bench_cnn_levers.py                  # res 18 and res 1, 3 rounds
    python bench/bench_cnn_levers.py --quick          # res 18, alloc and channels_last, 15 steps, 2 rounds
    python bench/bench_cnn_levers.py --levers alloc --res 18 --rounds 5
    python bench/bench_cnn_levers.py --precision bf16  # every variant in bf16, whatever auto picks

Writes ``outputs/bench/cnn_levers.json`` (``cnn_levers_quick.json`` with ``--quick``), with the machine
(CPU model and SIMD flags, cores, load average at the start and end, torch) and the date.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import machine, write_json  # noqa: E402

from sphri.models.allocator import MMAP_THRESHOLD, TRIM_THRESHOLD, keep_freed_memory  # noqa: E402

log = logging.getLogger("bench_cnn_levers")

#: lever -> variants (name, what the child does): ``env`` for the fresh process, ``args`` for the child.
LEVERS: dict[str, list[dict[str, Any]]] = {
    "alloc": [
        {"name": "base"},
        {"name": "mallopt", "args": ["--mallopt"]},
        {
            "name": "malloc_env",
            "env": {"MALLOC_MMAP_THRESHOLD_": str(MMAP_THRESHOLD), "MALLOC_TRIM_THRESHOLD_": str(TRIM_THRESHOLD)},
        },
    ],
    "threads": [
        {"name": "2_threads", "threads": 2},
        {"name": "2_threads_passive", "threads": 2, "env": {"OMP_WAIT_POLICY": "PASSIVE"}},
        {"name": "1_thread", "threads": 1},
    ],
    "channels_last": [{"name": "base"}, {"name": "channels_last", "args": ["--channels-last"]}],
    "channels_last_fit": [
        {"name": "allocator", "args": ["--mallopt"]},
        {"name": "allocator_channels_last", "args": ["--mallopt", "--channels-last"]},
    ],
    "precision": [
        {"name": "float32", "args": ["--mallopt", "--precision", "float32"]},
        {"name": "bf16", "args": ["--mallopt", "--precision", "bf16"]},
    ],
}
LEVERS["threads_contended"] = [{**v, "competitor": True} for v in LEVERS["threads"]]


# -- the child: one variant's training steps ----------------------------------------------------------


def to_channels_last(net) -> None:
    """The grid encoder's convolutions on channels-last tensors: weights, and every convolution's input."""
    import torch

    for conv in net.encoder.convs:
        conv.to(memory_format=torch.channels_last)
        conv.register_forward_pre_hook(lambda _m, args: (args[0].contiguous(memory_format=torch.channels_last),))


def usage() -> tuple[float, float, int, int, int, int, float]:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime, r.ru_stime, r.ru_minflt, r.ru_majflt, r.ru_nvcsw, r.ru_nivcsw, time.perf_counter()


def flops_per_window(net, m, dev, precision: str, xb, yb) -> float:
    """Floating-point operations of one training step's forward and backward per window
    (``torch.utils.flop_counter``: convolutions and matrix products, the GRU's included), counted on a
    copy of the network so that the measured steps and their numbers are untouched."""
    import copy

    import torch.nn.functional as F
    from torch.utils.flop_counter import FlopCounterMode

    clone = copy.deepcopy(net)
    with FlopCounterMode(display=False) as counter:
        with m._autocast(dev, precision):
            logits = clone(xb).float()
        F.cross_entropy(logits, yb).backward()
    return counter.get_total_flops() / xb.shape[0]


def child(args: argparse.Namespace) -> dict[str, Any]:
    applied = keep_freed_memory() if args.mallopt else None  # what CnnGru.fit sets
    import torch
    import torch.nn.functional as F
    from bench_models import load_windows

    from sphri.models.cnn_gru import CnnGru

    win = load_windows(args.windows)
    x, y = win.x, np.asarray(win.y)
    classes, y_idx = np.unique(y, return_inverse=True)
    m = CnnGru(geometry=win.geometry, threads=args.threads, precision=args.precision)
    dev = torch.device("cpu")
    precision, why = m._choose(dev)
    torch.set_num_threads(args.threads)
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(0)
    net = m._network(x.shape[2], len(classes))
    net.x_mean.fill_(float(x.mean(dtype=np.float64)))
    net.x_std.fill_(float(x.astype(np.float64).std(ddof=1)))
    if args.channels_last:
        to_channels_last(net)
    net.train()
    opt = torch.optim.AdamW(net.parameters(), lr=m.lr, weight_decay=m.weight_decay)
    xt, yt = torch.from_numpy(np.ascontiguousarray(x)), torch.from_numpy(y_idx.astype(np.int64))
    gen = torch.Generator().manual_seed(0)
    batches: list[torch.Tensor] = []
    while len(batches) < args.warmup + args.steps:
        batches += m._batches(xt.shape[0], gen)
    fpw = flops_per_window(net, m, dev, precision, xt[batches[0]], yt[batches[0]])
    losses, rows, windows = [], [], []
    for i, b in enumerate(batches[: args.warmup + args.steps]):
        u0 = usage()
        with m._autocast(dev, precision):
            logits = net(xt[b]).float()
        loss = F.cross_entropy(logits, yt[b])
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        losses.append(loss.item())
        u1 = usage()
        if i >= args.warmup:
            rows.append([b - a for a, b in zip(u0, u1)])
            windows.append(len(b))
    d = np.array(rows)
    checksum = float(sum(p.detach().double().abs().sum() for p in net.parameters()))
    return {
        "precision": precision,
        "precision_reason": why,
        "grid_shape": list(win.geometry.grid_shape) if win.geometry.grid_shape else None,
        "threads": torch.get_num_threads(),
        "mallopt": applied,
        "env": {
            k: os.environ[k]
            for k in ("OMP_WAIT_POLICY", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")
            if k in os.environ
        },
        "steps": args.steps,
        "user_s": d[:, 0].tolist(),
        "sys_s": d[:, 1].tolist(),
        "minflt": d[:, 2].astype(int).tolist(),
        "majflt": d[:, 3].astype(int).tolist(),
        "nvcsw": d[:, 4].astype(int).tolist(),
        "nivcsw": d[:, 5].astype(int).tolist(),
        "wall_s": d[:, 6].tolist(),
        "maxrss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "flops_per_window": fpw,
        "windows_per_step": float(np.mean(windows)),
        "losses": losses,
        "weights_checksum": checksum,
    }


# -- the parent: variants interleaved, ratios -------------------------------------------------------------


def matmul_peaks() -> dict[str, float]:
    """GFLOP per CPU s of a one-thread 1024 x 1024 matrix product in float32 and in bf16: the practical
    peak each precision's training steps are read against (``share_of_peak``)."""
    import torch
    from profile_cnn_gru import matmul_gflops

    return {"float32": round(matmul_gflops(), 1), "bf16": round(matmul_gflops(dtype=torch.bfloat16), 1)}


def run_variant(variant: dict, windows: Path, args: argparse.Namespace) -> dict[str, Any]:
    """One child process of ``variant`` (with a spinning competitor when it asks for one) -> its row."""
    threads = int(variant.get("threads", args.threads))
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", "--windows", str(windows)]
    cmd += ["--threads", str(threads), "--steps", str(args.steps), "--warmup", str(args.warmup)]
    cmd += ["--precision", args.precision]  # a variant's own --precision, after it, wins
    cmd += list(variant.get("args", []))
    env = {**os.environ, **variant.get("env", {})}
    for var in ("OMP_WAIT_POLICY", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_"):
        if var not in variant.get("env", {}):
            env.pop(var, None)
    env["PYTHONPATH"] = os.pathsep.join([str(HERE.parent), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    load0 = os.getloadavg()[0]
    spinner = None
    if variant.get("competitor"):
        spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    finally:
        if spinner is not None:
            spinner.kill()
            spinner.wait()
    if proc.returncode != 0:
        raise SystemExit(f"variant {variant['name']} failed (exit {proc.returncode}):\n{proc.stderr[-3000:]}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out.update(variant=variant["name"], competitor=bool(spinner), loadavg_1min_start=load0)
    out["loadavg_1min_end"] = os.getloadavg()[0]
    return out


def per_step(row: dict) -> dict[str, float]:
    """Means per measured step: user, sys and total CPU s, wall s, minor faults, context switches, and
    the GFLOP the step computed per CPU second."""
    user, sys_ = float(np.mean(row["user_s"])), float(np.mean(row["sys_s"]))
    return {
        "gflop_per_cpu_s": row["flops_per_window"] * row["windows_per_step"] / 1e9 / (user + sys_),
        "cpu_s": user + sys_,
        "user_s": user,
        "sys_s": sys_,
        "sys_share": sys_ / (user + sys_) if user + sys_ > 0 else 0.0,
        "wall_s": float(np.mean(row["wall_s"])),
        "minflt": float(np.mean(row["minflt"])),
        "nvcsw": float(np.mean(row["nvcsw"])),
        "nivcsw": float(np.mean(row["nivcsw"])),
    }


def summarize(rows: list[dict], variants: list[dict], peak: dict[str, float] | None = None) -> dict[str, Any]:
    """Per variant: median over rounds of the per-step means; ratios baseline / variant (median and range
    of the per-round ratios); whether its losses and weights equal the baseline's bit for bit; with
    ``peak`` (GFLOP per CPU s of a one-thread matrix product, per precision), the share of it reached."""
    base = variants[0]["name"]
    by = {v["name"]: [r for r in rows if r["variant"] == v["name"]] for v in variants}
    out: dict[str, Any] = {"baseline": base, "variants": {}, "peak": peak}
    for name, rs in by.items():
        steps = [per_step(r) for r in rs]
        entry: dict[str, Any] = {
            k: round(float(np.median([s[k] for s in steps])), 5 if k.endswith("_s") else 3) for k in steps[0]
        }
        if out.get("peak"):
            entry["share_of_peak"] = round(entry["gflop_per_cpu_s"] / out["peak"][rs[0]["precision"]], 3)
        entry["maxrss_mib"] = round(float(np.median([r["maxrss_mib"] for r in rs])), 1)
        entry["precision"] = rs[0]["precision"]
        entry["threads"] = rs[0]["threads"]
        if name != base:
            bsteps = [per_step(r) for r in by[base]]
            for key in ("cpu_s", "wall_s"):
                per_round = [b[key] / s[key] for b, s in zip(bsteps, steps)]
                entry[f"{key}_ratio"] = round(float(np.median([b[key] for b in bsteps])) / entry[key], 3)
                entry[f"{key}_ratio_rounds"] = [round(v, 3) for v in per_round]
            entry["losses_equal_baseline"] = all(r["losses"] == by[base][0]["losses"] for r in rs)
            entry["weights_equal_baseline"] = all(r["weights_checksum"] == by[base][0]["weights_checksum"] for r in rs)
            if not entry["losses_equal_baseline"]:
                diff = [abs(a - b) for r in rs for a, b in zip(r["losses"], by[base][0]["losses"])]
                entry["max_loss_difference"] = float(max(diff))
        out["variants"][name] = entry
    out["baseline_repeatable"] = all(r["losses"] == by[base][0]["losses"] for r in by[base])
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--quick", action="store_true", help="res 18, alloc and channels_last, 15 steps, 2 rounds (make bench)"
    )
    ap.add_argument("--res", type=int, nargs="+", default=None, help="resolutions (default 18 1)")
    ap.add_argument(
        "--levers",
        nargs="+",
        choices=sorted(LEVERS),
        default=None,
        help="default: all (alloc, channels_last with --quick)",
    )
    ap.add_argument("--rounds", type=int, default=None, help="interleaved rounds (default 3, 2 with --quick)")
    ap.add_argument(
        "--steps", type=int, default=None, help="measured steps (default 40 at res > 4, 30 below, 15 with --quick)"
    )
    ap.add_argument("--warmup", type=int, default=3, help="unmeasured steps first (default 3)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads of alloc and channels_last (default 1)")
    ap.add_argument("--participants", type=int, default=8, help="synthetic study size (default 8)")
    ap.add_argument("--repetitions", type=int, default=10, help="synthetic study size (default 10)")
    ap.add_argument("--name", default=None, help="default cnn_levers (cnn_levers_quick with --quick)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--windows", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--mallopt", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--channels-last", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument(
        "--precision",
        default="auto",
        choices=["auto", "float32", "bf16"],
        help="model.precision of every variant but the precision lever's (default auto, as fit does)",
    )
    args = ap.parse_args(argv)
    if args.child:
        args.steps = args.steps or 20
        print(json.dumps(child(args)))
        return 0
    for key in ("rounds", "steps", "warmup", "threads", "participants", "repetitions"):
        value = getattr(args, key)
        if value is not None and value < (0 if key == "warmup" else 1):
            ap.error(f"--{key}={value} is invalid: must be >= {0 if key == 'warmup' else 1}")
    res_list = args.res or ([18] if args.quick else [18, 1])
    # the threads levers' 2-thread runs take minutes a step where other work shares the cores: not quick
    levers = args.levers or (["alloc", "channels_last"] if args.quick else list(LEVERS))
    rounds = args.rounds or (2 if args.quick else 3)
    name = args.name or ("cnn_levers_quick" if args.quick else "cnn_levers")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")

    from bench_models import describe_windows, get_windows, save_windows

    t0 = time.perf_counter()
    out: dict[str, Any] = {
        "command": "python bench/bench_cnn_levers.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "date": time.strftime("%Y-%m-%d %H:%M %Z"),
        "machine": {**machine(), "affinity_cores": len(os.sched_getaffinity(0))},
        "levers": {lv: LEVERS[lv] for lv in levers},
        "rounds": rounds,
        "peak": matmul_peaks(),
        "res": {},
    }
    log.info("one-thread matrix-product peak, GFLOP per CPU s: %s", out["peak"])
    with tempfile.TemporaryDirectory(prefix="bench_cnn_levers_") as tmp:
        for res in res_list:
            win, source, note = get_windows("pipeline", res, args.participants, args.repetitions, seed=0)
            path = save_windows(win, str(Path(tmp) / f"windows_res{res}"))
            args.res = res
            steps = args.steps or (15 if args.quick else (40 if res > 4 else 30))
            run_args = argparse.Namespace(**{**vars(args), "steps": steps})
            entry: dict[str, Any] = {"data": describe_windows(win, source, note, args), "steps": steps, "levers": {}}
            out["res"][str(res)] = entry
            for lever in levers:
                variants = LEVERS[lever]
                rows = []
                for r in range(rounds):
                    for variant in variants if r % 2 == 0 else variants[::-1]:
                        row = run_variant(variant, path, run_args)
                        row["round"] = r
                        rows.append(row)
                        s = per_step(row)
                        log.info(
                            "res %d %s/%s round %d: %.4f CPU s (sys %.0f %%), %.4f wall s, %.0f minor faults per step",
                            res,
                            lever,
                            variant["name"],
                            r,
                            s["cpu_s"],
                            100 * s["sys_share"],
                            s["wall_s"],
                            s["minflt"],
                        )
                entry["levers"][lever] = {"summary": summarize(rows, variants, out["peak"]), "rows": rows}
                out["wall_s"] = round(time.perf_counter() - t0, 1)
                out["loadavg_1min_end"] = os.getloadavg()[0]
                write_json(name, out)
    path_out = write_json(name, out)
    for res, entry in out["res"].items():
        for lever, data in entry["levers"].items():
            for vname, v in data["summary"]["variants"].items():
                print(
                    f"res {res} {lever:18s} {vname:18s} CPU s/step {v['cpu_s']:.4f} (sys {100 * v['sys_share']:.0f} %)"
                    f" faults/step {v['minflt']:.0f}"
                    + f" {v['gflop_per_cpu_s']:.1f} GFLOP/CPU s ({100 * v.get('share_of_peak', 0):.1f} % of peak)"
                    + (f"  CPU ratio {v['cpu_s_ratio']} wall ratio {v['wall_s_ratio']}" if "cpu_s_ratio" in v else "")
                )
    print(f"wrote {path_out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
