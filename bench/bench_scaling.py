"""Scaling benchmark: time per stage against the number of frames and against the number of taxels.

Frames. The chain runs (no cache, stage by stage in chain order, exclusive
times) on synthetic data of growing size: a fixed number of participants
and more repetitions per gesture, so that the number of LOSO folds stays
the same and every stage should grow linearly with the frames. For each
stage the log-log slope of time against the dataset's frames is fitted
(least squares; 1 = linear), over all sizes and between the two largest
(fixed overheads flatten the small sizes), with an affine fit
(overhead + cost per frame) beside it; stages that do not depend on the frames
(hand, robot, surface, layout) are reported, not fitted.

Taxels. On the largest dataset's contacts and window plan, the stages
after the contact stage run at several resolutions: layout (grid), encoder
(ellipse), noise (salt and pepper), window assembly and the Random
Forest's features; the slope is fitted against the number of taxels N.
Encoder accuracy and speed against references are bench_encode's subject,
not this one's.

Times: CPU seconds of all threads (the fits use them: they depend less on
other processes than wall seconds) and wall seconds, best of ``repeat``
runs after a warm-up run on the smallest size. Writes
``outputs/bench/scaling.json`` and ``outputs/bench/scaling.png``.

    python bench/bench_scaling.py [--quick]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import OUT, begin, figure, run_info, write_json  # noqa: E402
from bench_pipeline import STAGES, MemoryProbe, StageProbe, compose_cfg  # noqa: E402

FULL = {"participants": 4, "repetitions": [3, 6, 12, 24], "resolutions": [2, 4, 9, 18, 36, 72, 100], "repeat": 2}
QUICK = {"participants": 3, "repetitions": [4, 8, 16], "resolutions": [2, 4, 9, 18, 36, 72], "repeat": 1}
#: Below this many CPU seconds at the largest size a stage is too fast for its slope to mean much.
MIN_FIT_S = 0.05
#: Stages whose work does not depend on the dataset's frames.
CONSTANT = ("hand", "robot", "surface", "layout")


def loglog_slope(x: np.ndarray, y: np.ndarray) -> dict:
    """How time ``y`` grows with size ``x``.

    ``slope``: least-squares slope of log y against log x over every size
    (1 = linear; fixed overheads pull it below 1 at small sizes);
    ``slope_top``: the slope between the two largest sizes (the growth
    where overheads matter least); ``r2`` of the log-log fit; ``overhead_s``
    and ``per_unit_s``: an affine fit ``y = overhead + per_unit * x``;
    ``time_ratio`` / ``size_ratio`` of the largest and smallest sizes.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    ok = (x > 0) & (y > 0)
    if ok.sum() < 2:
        return {"slope": float("nan"), "slope_top": float("nan"), "r2": float("nan"), "n_points": int(ok.sum())}
    x, y = x[ok], y[ok]
    lx, ly = np.log(x), np.log(y)
    slope, icpt = np.polyfit(lx, ly, 1)
    resid = ly - (slope * lx + icpt)
    ss = ((ly - ly.mean()) ** 2).sum()
    per_unit, overhead = np.polyfit(x, y, 1)
    return {
        "slope": float(slope),
        "slope_top": float((ly[-1] - ly[-2]) / (lx[-1] - lx[-2])),
        "r2": float(1 - (resid**2).sum() / ss) if ss > 0 else 1.0,
        "n_points": int(ok.sum()),
        "overhead_s": float(overhead),
        "per_unit_s": float(per_unit),
        "time_ratio": float(y[-1] / y[0]),
        "size_ratio": float(x[-1] / x[0]),
        "largest_s": float(y[-1]),
    }


def run_chain(participants: int, repetitions: int, res: int, memory: MemoryProbe):
    """The whole chain without a cache, stage by stage; (pipeline, per-stage stats)."""
    from sphri.cache import StageCache
    from sphri.pipeline import make_pipeline

    cfg = compose_cfg(participants, repetitions, res)
    probe = StageProbe(memory)
    p = probe.install(make_pipeline(cfg, StageCache(root="/nonexistent", enabled=False)))
    for name in STAGES:
        p.get(name)
    return p, probe.stats


def frames_scaling(size: dict, memory: MemoryProbe) -> tuple[dict, object]:
    rows = []
    last = None
    run_chain(size["participants"], size["repetitions"][0], 18, memory)  # warm-up: numba caches, imports
    for reps in size["repetitions"]:
        best = None
        for _ in range(size["repeat"]):
            p, stats = run_chain(size["participants"], reps, 18, memory)
            if best is None or sum(s["cpu_s"] for s in stats.values()) < sum(s["cpu_s"] for s in best[1].values()):
                best = (p, stats)
        p, stats = best
        data, plan = p.get("data"), p.get("plan")
        row = {
            "repetitions": reps,
            "n_frames": data.n_frames,
            "n_trials": len(data.trials),
            "encoded_frames": int(plan.selected_frames().size),
            "stages": {k: {"cpu_s": v["cpu_s"], "wall_s": v["wall_s"]} for k, v in stats.items()},
        }
        rows.append(row)
        print(
            f"  {reps:3d} repetitions: {data.n_frames:7d} frames, "
            + ", ".join(f"{k} {v['cpu_s']:.2f}" for k, v in stats.items() if v["cpu_s"] > 0.01),
            flush=True,
        )
        last = p
    frames = np.array([r["n_frames"] for r in rows])
    fits = {}
    for name in STAGES:
        if name in CONSTANT:
            continue
        cpu = np.array([r["stages"][name]["cpu_s"] for r in rows])
        wall = np.array([r["stages"][name]["wall_s"] for r in rows])
        fits[name] = {"cpu": loglog_slope(frames, cpu), "wall": loglog_slope(frames, wall)}
    return {"participants": size["participants"], "sizes": rows, "fits": fits}, last


def taxels_scaling(p, resolutions, repeat: int) -> dict:
    """Layout, encoder, window assembly, noise and features at several res on one dataset's contacts."""
    from sphri.encode.ellipse import EllipseEncoder
    from sphri.layout.grid import GridLayout
    from sphri.models.features import extract_features
    from sphri.noise.components import SaltPepperNoise, apply_to_windows
    from sphri.pipeline import trial_keys
    from sphri.window.onset import OnsetWindow

    data, contacts, surface, plan = p.get("data"), p.get("contact"), p.get("surface"), p.get("plan")
    link = p.get("robot").link_for("arm")
    fi = plan.selected_frames()
    tk = trial_keys(data)[plan.kept]  # one key per window (noise is applied to the windows)
    window = OnsetWindow(frames=plan.length)

    def timed(fn):
        best = None
        for _ in range(repeat):
            c0, t0 = time.process_time(), time.perf_counter()
            out = fn()
            t = (time.process_time() - c0, time.perf_counter() - t0)
            if best is None or t[0] < best[0]:
                best = t
        return out, {"cpu_s": best[0], "wall_s": best[1]}

    rows = []
    for res in resolutions:
        lay, t_layout = timed(lambda: GridLayout().build(link, surface, res))
        frames, t_enc = timed(lambda: EllipseEncoder().encode(contacts, link, surface, lay, fi))
        clean, t_win = timed(lambda: window.assemble(frames, plan, data, lay, surface))  # noqa: F821 (bound on the line above)
        windows, t_noise = timed(lambda: apply_to_windows(SaltPepperNoise(), clean, tk, 0))  # noqa: F821
        _, t_feat = timed(lambda: extract_features(windows.x, windows.geometry))  # noqa: F821
        rows.append(
            {
                "res": res,
                "n_taxels": lay.n_taxels,
                "grid_shape": list(lay.grid_shape),
                "stages": {"layout": t_layout, "encode": t_enc, "noise": t_noise, "window": t_win, "features": t_feat},
            }
        )
        print(
            f"  res {res:3d}: {lay.n_taxels:6d} taxels, "
            + ", ".join(f"{k} {v['cpu_s']:.2f}" for k, v in rows[-1]["stages"].items()),
            flush=True,
        )
        del frames, clean, windows
    n = np.array([r["n_taxels"] for r in rows])
    fits = {
        name: {
            "cpu": loglog_slope(n, [r["stages"][name]["cpu_s"] for r in rows]),
            "wall": loglog_slope(n, [r["stages"][name]["wall_s"] for r in rows]),
        }
        for name in rows[0]["stages"]
    }
    return {"encoded_frames": int(fi.size), "n_windows": int(plan.kept.sum()), "sizes": rows, "fits": fits}


def loglog_panel(ax, scan: dict, size_key: str, ref_at_first_s: float, xlabel: str, title: str) -> None:
    """CPU seconds per fitted stage against ``scan["sizes"][*][size_key]``, log-log, with a slope-1 line."""
    x = np.array([r[size_key] for r in scan["sizes"]])
    for i, (name, fit) in enumerate(scan["fits"].items()):
        y = np.array([r["stages"][name]["cpu_s"] for r in scan["sizes"]])
        if (y <= 0).all():
            continue
        ax.loglog(x, np.maximum(y, 1e-4), "o-", color=f"C{i}", label=f"{name}: slope {fit['cpu']['slope']:.2f}")
    ref = np.array([x[0], x[-1]], dtype=float)
    ax.loglog(ref, ref / ref[0] * ref_at_first_s, "k--", lw=0.8, label="slope 1 (linear)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("CPU seconds (all threads)")
    ax.set_title(title)
    ax.legend(fontsize=8)


def plot(fr: dict, tx: dict, path: Path) -> None:
    with figure(path, 2, (13, 4.8)) as (fig, axes):
        loglog_panel(
            axes[0],
            fr,
            "n_frames",
            0.05,
            "dataset frames",
            f"time per stage vs frames ({fr['participants']} participants, more repetitions)",
        )
        loglog_panel(
            axes[1],
            tx,
            "n_taxels",
            0.01,
            "taxels N (grid, res along the arm)",
            f"time per stage vs taxels ({tx['encoded_frames']} encoded frames)",
        )
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)


def main(argv: list[str] | None = None) -> int:
    quick, start, t0 = begin(__doc__, "3 participants x 4/8/16 repetitions", argv)
    size = QUICK if quick else FULL
    memory = MemoryProbe()
    print(f"frames: {size['participants']} participants x {size['repetitions']} repetitions", flush=True)
    fr, last = frames_scaling(size, memory)
    print(f"taxels: res {size['resolutions']}", flush=True)
    tx = taxels_scaling(last, size["resolutions"], size["repeat"])
    info = run_info(start, quick, t0, note="slopes fitted to CPU seconds (all threads) on log-log axes; 1 = linear")
    head = {}
    for axis, res in (("frames", fr), ("taxels", tx)):
        for k, v in res["fits"].items():
            c = v["cpu"]
            if c.get("largest_s", 0.0) < MIN_FIT_S:
                head[f"{axis}_slope_{k}"] = f"too fast to fit ({c.get('largest_s', 0.0):.3f} s at the largest size)"
            else:
                head[f"{axis}_slope_{k}"] = c["slope"]
                head[f"{axis}_slope_top_{k}"] = c["slope_top"]
    head["frames_range"] = f"{fr['sizes'][0]['n_frames']}..{fr['sizes'][-1]['n_frames']}"
    head["taxels_range"] = f"{tx['sizes'][0]['n_taxels']}..{tx['sizes'][-1]['n_taxels']}"
    path = write_json("scaling", {"info": info, "headline": head, "frames": fr, "taxels": tx})
    plot(fr, tx, OUT / "scaling.png")
    for k, v in head.items():
        print(f"  {k}: {v:.3f}" if isinstance(v, float) else f"  {k}: {v}")
    print(f"wrote {path} and {OUT / 'scaling.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
