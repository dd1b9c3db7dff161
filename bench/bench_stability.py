"""Data-size stability: how many participants and repetitions a resolution sweep needs.

The question: is the saturation point of a Random Forest resolution sweep
(the report's rule: the coarsest resolution certified, with 95 % confidence,
to keep every finer one within 1 point of accuracy of the best, or within the
smallest tolerance the data can certify when that is larger,
:func:`sphri.report.saturation.certified_saturation`)
a property of the skin, or
of how little data the sweep had? The benchmark runs the sweep once on the
largest synthetic dataset of the grid and then, for every cell (P
participants x R repetitions per gesture) of the grid, on the subset made
of P participants' first R repetitions of every gesture: a LOSO accuracy
per participant and resolution, the saturation point, its participant
bootstrap interval and its distance from the largest cell's point. With
``draws`` > 1, cells with fewer participants than the largest are also
run on other random participant subsets, so the spread of the point over
equally sized studies shows beside its bootstrap interval.

Run time against error (the Pareto plot): a cell's cost is what its sweep
costs (CPU seconds): its LOSO fits, measured, plus its share (by trials)
of the data, contact, encoding and feature costs of the largest dataset.
Errors: the bootstrap interval's width and the distance of the point from
the largest cell's, both in mm of taxel pitch along the arm.

The Random Forest is the pipeline's (``conf/model/rf.yaml``); its 32
features depend on each trial alone, so they are computed once per
resolution on the largest dataset and every cell's LOSO fits its forests on
those rows (a test in ``tests/stress`` checks that this equals running the
model on the windows).

Sizes: full = P in {4, 8, 12, 18}, R in {5, 10, 20}, resolutions 1, 2, 4,
8, 12, 18, 24, 3 draws; ``--quick`` = P in {4, 8, 12}, R in {5, 10, 20},
the same resolutions, 1 draw (under 3 minutes on 2 cores). Writes
``outputs/bench/stability.json`` and ``outputs/bench/stability.png``.

    python bench/bench_stability.py [--quick]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import OUT, begin, figure, run_info, write_json  # noqa: E402
from bench_pipeline import STAGES, MemoryProbe, StageProbe, compose_cfg  # noqa: E402

from sphri.models.rf import RandomForest  # noqa: E402
from sphri.types import WindowedFrames  # noqa: E402

FULL = {
    "participants": [4, 8, 12, 18],
    "repetitions": [5, 10, 20],
    "resolutions": [1, 2, 4, 8, 12, 18, 24],
    "draws": 3,
    "n_boot": 2000,
}
QUICK = {
    "participants": [4, 8, 12],
    "repetitions": [5, 10, 20],
    "resolutions": [1, 2, 4, 8, 12, 18, 24],
    "draws": 1,
    "n_boot": 1000,
}


class FeatureForest(RandomForest):
    """The pipeline's Random Forest on precomputed features: ``x`` is (n, 1, 32), the features themselves."""

    def transform(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x)
        if x.ndim != 3 or x.shape[1] != 1:
            raise ValueError(f"FeatureForest expects (n, 1, 32) precomputed features, got {x.shape}")
        return x[:, 0, :]


def feature_windows(windows: WindowedFrames, features: np.ndarray, rows: np.ndarray) -> WindowedFrames:
    """``windows`` restricted to ``rows``, with ``x`` replaced by the (n, 1, 32) features of those rows."""
    return WindowedFrames(
        x=features[rows][:, None, :],
        y=windows.y[rows],
        groups=windows.groups[rows],
        geometry=windows.geometry,
        trial_row=windows.trial_row[rows],
        n_dropped=0,
    )


def repetition_rank(trials) -> np.ndarray:
    """(N_trials,) int64 0-based repetition of each trial within its (participant, gesture), by trial order."""
    order = trials.sort_values(["participant", "gesture", "trial_ordinal"]).index
    rank = trials.loc[order].groupby(["participant", "gesture"]).cumcount()
    return rank.reindex(trials.index).to_numpy(dtype=np.int64)


def loso_scores(
    model_params: dict,
    windows: WindowedFrames,
    features: np.ndarray,
    rows: np.ndarray,
    participants: list[str],
    seed: int,
) -> tuple[np.ndarray, float, float]:
    """Per-participant LOSO accuracy (in ``participants`` order), CPU and wall seconds."""
    from sphri.evaluate.cv import LeaveOneSubjectOut

    sub = feature_windows(windows, features, rows)
    c0, t0 = time.process_time(), time.perf_counter()
    result = LeaveOneSubjectOut(workers=1, progress=False).run(lambda: FeatureForest(**model_params), sub, seed)
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    acc = {f.fold: f.accuracy for f in result.folds}
    return np.array([acc.get(p, np.nan) for p in participants]), cpu, wall


def prepare(size: dict, memory: MemoryProbe, cache_dir: str) -> dict:
    """The largest dataset through the chain at every resolution: windows, features and costs."""
    from hydra.utils import instantiate

    from sphri.cache import StageCache
    from sphri.layout.units import describe
    from sphri.pipeline import make_pipeline

    p_max, r_max = max(size["participants"]), max(size["repetitions"])
    cache = StageCache(root=cache_dir)
    per_res = []
    upstream_cpu = 0.0
    model_params = None
    for k, res in enumerate(size["resolutions"]):
        cfg = compose_cfg(p_max, r_max, res)
        probe = StageProbe(memory)
        p = probe.install(make_pipeline(cfg, cache))
        for name in STAGES[:-1]:  # everything but the evaluation (the last of them is the model's input)
            p.get(name)
        c0 = time.process_time()
        windows = p.get(STAGES[-2])
        model = instantiate(cfg.model, _partial_=True, _convert_="all")(geometry=windows.geometry)
        features = model.transform(windows.x)
        feat_cpu = time.process_time() - c0
        if model_params is None:
            model_params = {k2: v for k2, v in model.get_params().items() if k2 != "geometry"}
        stats = probe.stats
        if k == 0:
            upstream_cpu = sum(
                s["cpu_s"] for n, s in stats.items() if n in ("hand", "robot", "data", "contact", "surface", "plan")
            )
        per_res.append(
            {
                "res": res,
                "n_taxels": int(windows.x.shape[2]),
                "pitch_u_mm": describe(p.get("layout"), p.get("surface"))["pitch_u_mm"],
                "encode_cpu_s": sum(stats[n]["cpu_s"] for n in ("layout", "encode", "noise", "filter") if n in stats)
                + feat_cpu,
                "features": features,
                "windows": windows,
            }
        )
        print(
            f"  res {res:3d}: {windows.x.shape[2]:5d} taxels, encode + features {per_res[-1]['encode_cpu_s']:.1f} s CPU",
            flush=True,
        )
        data = p.get("data")
        del windows
    return {
        "data": data,
        "per_res": per_res,
        "upstream_cpu_s": upstream_cpu,
        "model_params": model_params,
        "seed": int(cfg.seed),
    }


def run_grid(size: dict, prep: dict) -> dict:
    from sphri.report.analysis import RuleSettings
    from sphri.report.saturation import certified_saturation

    data = prep["data"]
    first = prep["per_res"][0]["windows"]
    trial_row = first.trial_row
    for r in prep["per_res"]:
        assert np.array_equal(r["windows"].trial_row, trial_row), "windows differ in trials across resolutions"
    rank = repetition_rank(data.trials)[trial_row]
    groups = np.asarray(first.groups)
    everyone = sorted(np.unique(groups))
    n_all = len(trial_row)
    res = np.array(size["resolutions"])
    pitch = np.array([r["pitch_u_mm"] for r in prep["per_res"]])
    shared_cpu = prep["upstream_cpu_s"] + sum(r["encode_cpu_s"] for r in prep["per_res"])
    cells = []
    for n_p in size["participants"]:
        n_draws = 1 if n_p == len(everyone) else size["draws"]
        for n_r in size["repetitions"]:
            for draw in range(n_draws):
                chosen = (
                    everyone[:n_p]
                    if draw == 0
                    else sorted(np.random.default_rng([draw, n_p]).choice(everyone, n_p, replace=False).tolist())
                )
                rows = np.flatnonzero(np.isin(groups, chosen) & (rank < n_r))
                scores = np.full((n_p, len(res)), np.nan)
                cpu = wall = 0.0
                for j, r in enumerate(prep["per_res"]):
                    s, c, w = loso_scores(prep["model_params"], r["windows"], r["features"], rows, chosen, prep["seed"])
                    scores[:, j] = s
                    cpu += c
                    wall += w
                sat, _ = certified_saturation(scores, RuleSettings().primary, n_boot=size["n_boot"], seed=0)
                lo, hi = sat.interval if sat.interval is not None else (sat.index, sat.index)
                cells.append(
                    {
                        "participants": n_p,
                        "repetitions": n_r,
                        "draw": draw,
                        "chosen": chosen,
                        "n_trials": int(rows.size),
                        "loso_cpu_s": cpu,
                        "loso_wall_s": wall,
                        "cost_cpu_s": cpu + shared_cpu * rows.size / n_all,
                        "mean_accuracy": sat.stats.mean.tolist(),
                        "se_accuracy": sat.stats.se.tolist(),
                        "saturation_res": int(res[sat.index]),
                        "saturation_pitch_mm": float(pitch[sat.index]),
                        "saturation_index": sat.index,
                        "best_res": int(res[sat.best_index]),
                        "interval_res": [int(res[lo]), int(res[hi])],
                        "interval_pitch_mm": [float(pitch[hi]), float(pitch[lo])],
                        "interval_steps": int(hi - lo),
                        "interval_width_mm": float(pitch[lo] - pitch[hi]),
                        "at_finest": bool(sat.at_finest),
                        "note": sat.note,
                    }
                )
                c = cells[-1]
                print(
                    f"  P={n_p:2d} R={n_r:2d} draw {draw}: {rows.size:4d} trials, saturation res {c['saturation_res']} "
                    f"[{c['interval_res'][0]}, {c['interval_res'][1]}], acc {max(c['mean_accuracy']):.3f}, "
                    f"LOSO {cpu:.1f} s CPU",
                    flush=True,
                )
    ref = next(
        c
        for c in cells
        if c["participants"] == max(size["participants"])
        and c["repetitions"] == max(size["repetitions"])
        and c["draw"] == 0
    )
    for c in cells:
        c["steps_from_reference"] = abs(c["saturation_index"] - ref["saturation_index"])
        c["mm_from_reference"] = abs(c["saturation_pitch_mm"] - ref["saturation_pitch_mm"])
        c["reference_in_interval"] = c["interval_res"][0] <= ref["saturation_res"] <= c["interval_res"][1]
    return {
        "resolutions": res.tolist(),
        "pitch_u_mm": pitch.tolist(),
        "shared_cpu_s": shared_cpu,
        "cells": cells,
        "reference": {
            k: ref[k]
            for k in (
                "participants",
                "repetitions",
                "saturation_res",
                "saturation_pitch_mm",
                "interval_res",
                "interval_width_mm",
            )
        },
    }


def verdict(grid: dict) -> dict:
    """Per (P, R): worst distance from the reference over draws; the cheapest size that is stable."""
    by = {}
    for c in grid["cells"]:
        key = (c["participants"], c["repetitions"])
        by.setdefault(key, []).append(c)
    ref_steps = next(
        c
        for c in grid["cells"]
        if c["participants"] == grid["reference"]["participants"]
        and c["repetitions"] == grid["reference"]["repetitions"]
    )["interval_steps"]
    table = []
    for (n_p, n_r), cs in sorted(by.items(), key=lambda kv: np.mean([c["cost_cpu_s"] for c in kv[1]])):
        worst = max(c["steps_from_reference"] for c in cs)
        width = max(c["interval_steps"] for c in cs)
        table.append(
            {
                "participants": n_p,
                "repetitions": n_r,
                "draws": len(cs),
                "cost_cpu_s": float(np.mean([c["cost_cpu_s"] for c in cs])),
                "worst_steps_from_reference": worst,
                "worst_mm_from_reference": max(c["mm_from_reference"] for c in cs),
                "widest_interval_steps": width,
                "widest_interval_mm": max(c["interval_width_mm"] for c in cs),
                "stable": bool(worst <= 1 and width <= ref_steps + 1),
            }
        )
    # the cheapest size from which every size with at least as many participants and repetitions is
    # stable (a single lucky small cell does not count)
    ok = {(t["participants"], t["repetitions"]): t["stable"] for t in table}
    settled = [
        t for t in table if all(v for (p, r), v in ok.items() if p >= t["participants"] and r >= t["repetitions"])
    ]
    cheapest = settled[0] if settled else None
    return {
        "by_size": table,
        "rule": "stable = every draw's saturation point within one sweep step of the "
        "largest size's, and its bootstrap interval at most one step wider than the largest size's; "
        "stable_from = the cheapest size from which every size with at least as many participants and "
        "repetitions is stable",
        "stable_from": None
        if cheapest is None
        else f"{cheapest['participants']} participants x "
        f"{cheapest['repetitions']} repetitions ({cheapest['cost_cpu_s']:.0f} s CPU per sweep)",
    }


def plot(grid: dict, ver: dict, path: Path) -> None:
    with figure(path, 3, (16, 4.8)) as (fig, axes):
        cells = grid["cells"]
        reps = sorted({c["repetitions"] for c in cells})
        markers = dict(zip(reps, "os^Dv"))
        parts = sorted({c["participants"] for c in cells})
        colors = {p: f"C{i}" for i, p in enumerate(parts)}
        for ax, key, label in (
            (axes[0], "interval_width_mm", "bootstrap interval width (mm of pitch)"),
            (axes[1], "mm_from_reference", "distance from the largest size's point (mm)"),
        ):
            for c in cells:
                ax.scatter(
                    c["cost_cpu_s"],
                    c[key],
                    color=colors[c["participants"]],
                    marker=markers[c["repetitions"]],
                    s=45,
                    alpha=0.8,
                )
            pts = sorted((c["cost_cpu_s"], c[key]) for c in cells)
            front, best = [], np.inf
            for x, y in pts:
                if y < best:
                    front.append((x, y))
                    best = y
            front.append((pts[-1][0], front[-1][1]))
            ax.step([x for x, _ in front], [y for _, y in front], where="post", color="k", lw=0.8, label="Pareto front")
            ax.set_xscale("log")
            ax.set_xlabel("sweep cost (CPU seconds, log)")
            ax.set_ylabel(label)
            ax.grid(True, which="both", alpha=0.3)
        for p in parts:
            axes[0].scatter([], [], color=colors[p], marker="o", label=f"{p} participants")
        for r in reps:
            axes[0].scatter([], [], color="gray", marker=markers[r], label=f"{r} repetitions")
        axes[0].legend(fontsize=7)
        axes[0].set_title("run time vs interval width")
        axes[1].set_title("run time vs shift of the saturation point")
        pitch = np.array(grid["pitch_u_mm"])
        for c in cells:
            if c["draw"] != 0:
                continue
            axes[2].plot(
                pitch,
                c["mean_accuracy"],
                marker=markers[c["repetitions"]],
                color=colors[c["participants"]],
                lw=0.8,
                ms=4,
                alpha=0.8,
            )
            axes[2].axvline(c["saturation_pitch_mm"], color=colors[c["participants"]], lw=0.5, alpha=0.4)
        axes[2].set_xscale("log")
        axes[2].set_xticks(pitch, [f"{x:.0f}" for x in pitch])
        axes[2].minorticks_off()
        axes[2].invert_xaxis()
        axes[2].set_xlabel("taxel pitch along the arm (mm, log; finer to the right)")
        axes[2].set_ylabel("LOSO accuracy (mean over participants)")
        axes[2].set_title("curves (draw 0); lines: saturation points")
        axes[2].grid(True, which="both", alpha=0.3)
        fig.suptitle(f"RF resolution sweep vs synthetic data size; stable from {ver['stable_from']}", fontsize=10)


def main(argv: list[str] | None = None) -> int:
    quick, start, t0 = begin(__doc__, "P in {4, 8, 12}, R in {5, 10, 20}, 1 draw", argv)
    size = QUICK if quick else FULL
    memory = MemoryProbe()
    print(
        f"largest dataset: {max(size['participants'])} participants x {max(size['repetitions'])} repetitions",
        flush=True,
    )
    with tempfile.TemporaryDirectory(prefix="sphri-bench-") as tmp:
        prep = prepare(size, memory, tmp)
    grid = run_grid(size, prep)
    ver = verdict(grid)
    info: dict[str, Any] = run_info(
        start,
        quick,
        t0,
        n_boot=size["n_boot"],
        draws=size["draws"],
        model=prep["model_params"],
    )
    ref = grid["reference"]
    head = {
        "reference_size": f"{ref['participants']} x {ref['repetitions']}",
        "reference_saturation_res": ref["saturation_res"],
        "reference_saturation_pitch_mm": ref["saturation_pitch_mm"],
        "reference_interval_res": f"{ref['interval_res'][0]}..{ref['interval_res'][1]}",
        "stable_from": ver["stable_from"] or "none in the grid",
        "cells": len(grid["cells"]),
        "total_loso_cpu_s": sum(c["loso_cpu_s"] for c in grid["cells"]),
    }
    path = write_json("stability", {"info": info, "headline": head, "verdict": ver, "grid": grid})
    plot(grid, ver, OUT / "stability.png")
    for t in ver["by_size"]:
        print(
            f"  {t['participants']:2d} x {t['repetitions']:2d}: cost {t['cost_cpu_s']:6.1f} s, worst shift "
            f"{t['worst_steps_from_reference']} steps ({t['worst_mm_from_reference']:.1f} mm), widest interval "
            f"{t['widest_interval_steps']} steps, {'stable' if t['stable'] else 'not stable'}"
        )
    print(f"  stable from {ver['stable_from']}; {info['wall_s']:.0f} s in all")
    print(f"wrote {path} and {OUT / 'stability.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
