"""Where the whole-body study's touches lose contact: the drawing hand's contact per gesture and body part.

The study's plausibility check (``summary.json``: ``plausibility``, :mod:`sphri.sessions.plausibility`) compares
each gesture's median contact fraction (first to last contact frame of the drawing hand over the touch) with the
arm study's. This breaks that number down for the sessions of a full study (sessions and contacts from the stage
cache in ``--cache``): per gesture and drawn body part, the touches, the median contact fraction, the share of
touches with no contact at all, and the median number of contact runs (a run: consecutive frames in contact; a
held gesture that keeps contact has one), and, on version-5 sessions (the planned contact phase in the truth
table), the paired ratio the check judges (contact span over the planned phase's), how many frames contact starts
before the plan and ends after it, and which hand capsules touch outside the plan. Parts are grouped by the shape of their link: ``arm-like`` (upper arm,
forearm, whose surface the arm study's generator was built for) and ``other`` (torso, head, shoulders, grippers,
wrists).

    python bench/bench_study_contact_timing.py --cache DIR   # DIR: the stage cache of a full robot=reachy2 study

Writes ``outputs/bench/study_contact_timing.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import machine, write_json  # noqa: E402

#: Body parts on links shaped like the arm study's (a limb segment).
ARM_LIKE = ("upper_arm", "forearm")


def _runs(contact: np.ndarray) -> int:
    """Number of runs of consecutive True values."""
    c = contact.astype(np.int8)
    return int((np.diff(np.r_[0, c]) == 1).sum())


def touches(cache_dir: str) -> list[dict]:
    """One row per generated touch: gesture, part, touch frames, contact span, contact runs, settled frames."""
    from sphri.config import compose
    from sphri.pipeline import Memo, open_cache
    from sphri.sessions.labelling import load_sessions_and_contacts

    cfg = compose(["+experiment=scenario_study", "robot=reachy2", f"cache.dir={cache_dir}", "tracking.enabled=false"])
    _, _, ds, bc, _ = load_sessions_and_contacts(cfg, open_cache(cfg), Memo())
    truth, sess = ds.truth.reset_index(drop=True), ds.sessions.reset_index(drop=True)
    fsi = ds.frame_session_index()
    start = sess["start"].to_numpy(np.int64) + truth["touch_start_frame"].to_numpy(np.int64)
    n_touch = truth["touch_frames"].to_numpy(np.int64)
    rows = []
    for s in range(len(truth)):
        mine = (bc.hand == 1) & (fsi[bc.frame] == s)
        rel, caps = bc.frame[mine] - start[s], bc.capsule[mine]
        keep = (rel >= 0) & (rel < n_touch[s])
        rel, caps = rel[keep], caps[keep]
        frames = np.unique(rel)
        on = np.zeros(n_touch[s], dtype=bool)
        on[frames] = True
        row = {
            "gesture": str(truth.loc[s, "gesture"]),
            "part": str(truth.loc[s, "part"]),
            "touch_frames": int(n_touch[s]),
            "span_frames": int(frames.max() - frames.min() + 1) if frames.size else 0,
            "runs": _runs(on),
            "settled_frames": int(truth.loc[s, "settled_frames"]),
        }
        if "plan_first_frame" in truth and frames.size and truth.loc[s, "plan_first_frame"] >= 0:
            a, b = int(truth.loc[s, "plan_first_frame"]), int(truth.loc[s, "plan_last_frame"])
            out = (rel < a) | (rel > b)
            row |= {
                "plan_frames": b - a + 1,
                "early_frames": a - int(frames.min()),
                "late_frames": int(frames.max()) - b,
                "capsules_outside_plan": sorted({int(c) for c in caps[out]}),
            }
        rows.append(row)
    return rows


def summarize(rows: list[dict]) -> dict:
    """Per gesture, per part kind (arm-like, other): touches, median contact fraction, no-contact share, runs."""
    from sphri.sessions.plausibility import arm_reference

    out: dict = {}
    for g in sorted({r["gesture"] for r in rows}):
        ref = arm_reference(g)[1]
        entry: dict = {"arm_contact_fraction": round(ref, 3)}
        for kind in ("arm-like", "other", "all"):
            sel = [
                r
                for r in rows
                if r["gesture"] == g and (kind == "all" or (r["part"].startswith(ARM_LIKE) == (kind == "arm-like")))
            ]
            if not sel:
                continue
            cf = np.array([r["span_frames"] / r["touch_frames"] for r in sel])
            entry[kind] = {
                "touches": len(sel),
                "contact_fraction_median": round(float(np.median(cf)), 3),
                "ratio_to_arm": round(float(np.median(cf)) / ref, 3),
                "no_contact_share": round(float(np.mean([r["span_frames"] == 0 for r in sel])), 3),
                "contact_runs_median": float(np.median([r["runs"] for r in sel])),
            }
            paired = [r for r in sel if "plan_frames" in r]
            if paired:
                entry[kind] |= {
                    "touches_with_plan_and_contact": len(paired),
                    "contact_plan_ratio_median": round(
                        float(np.median([r["span_frames"] / r["plan_frames"] for r in paired])), 3
                    ),
                    "early_frames_median": float(np.median([r["early_frames"] for r in paired])),
                    "late_frames_median": float(np.median([r["late_frames"] for r in paired])),
                    "capsules_outside_plan": sorted({c for r in paired for c in r["capsules_outside_plan"]}),
                }
        out[g] = entry
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True, help="stage cache holding a full robot=reachy2 study's sessions")
    args = ap.parse_args()
    t0 = time.perf_counter()
    rows = touches(args.cache)
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": "python bench/bench_study_contact_timing.py --cache DIR",
        "what": __doc__.splitlines()[0],
        "touches": len(rows),
        "per_gesture": summarize(rows),
        "seconds": round(time.perf_counter() - t0, 1),
    }
    for g, e in result["per_gesture"].items():
        parts = [
            f"{k}: {v['touches']} touches, contact fraction {v['contact_fraction_median']:.2f} "
            f"({v['ratio_to_arm']:.2f}x arm), none {100 * v['no_contact_share']:.0f} %, runs {v['contact_runs_median']:g}"
            for k, v in e.items()
            if isinstance(v, dict)
        ]
        print(f"{g} (arm {e['arm_contact_fraction']:.2f}): " + "; ".join(parts))
    print(write_json("study_contact_timing", result))


if __name__ == "__main__":
    main()
