"""The arm study's own contact over its plan: per gesture, measured contact span over the planned contact phase.

The whole-body study's timing check (:mod:`sphri.sessions.plausibility`) judges, per touch, the drawing hand's
measured contact span (first to last frame in contact) over the span of that touch's planned contact phase. This
measures the same ratio on the arm study itself (``data=synthetic`` on the default robot's arm, the reference the
check compares with): ``--participants`` participants x ``--repetitions`` trials per gesture, drawn as
``SyntheticData.load`` draws them (same streams), each trial's planned contact phase from
``SyntheticData._participant_region_phases`` (:func:`sphri.data.synthetic.contact_phase`) and its contacts from the
pipeline's contact stage (``contact`` of the config, ``contact=exact`` by default) against the arm link; per trial
the span from the first to the last frame with any hand capsule in contact over the span from the first to the last
frame of the planned phase. Per gesture: trials, the median ratio and its 25-75 % range, the median frames contact
starts before the plan and ends after it, the share of trials with no contact, and the same split by the planned
phase's length (``by_planned_length``).

    python bench/bench_arm_contact_plan.py [--participants 18] [--repetitions 10] [--name NAME] [overrides ...]

The same generator on Reachy 2's left upper arm (the link alone, as the arm study's single region):

    python bench/bench_arm_contact_plan.py --repetitions 3 --name arm_contact_plan_reachy2_upper_arm robot=reachy2 \
        robot.parts=null robot.groups=null robot.merge=null robot.exclude=null robot.geometry=collision \
        'robot.links=[l_elbow_arm_link]' 'robot.regions={arm:l_elbow_arm_link}'

Writes ``outputs/bench/arm_contact_plan.json`` (``NAME.json``). Trials whose planned touches fall between frames
(no frame inside the plan) are counted, not judged, as the sessions' check skips them.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import header, write_json  # noqa: E402


def arm_trials(participants: int, repetitions: int, overrides: list[str]):
    """(dataset, per-frame planned phase, contacts) of the arm study's trials (see module)."""
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.data.format import make_trials_frame, participant_id
    from sphri.data.gestures import Style
    from sphri.data.handfk import HandRig
    from sphri.data.linkgeom import LinkSurface
    from sphri.data.synthetic import region_stream, trial_records
    from sphri.types import GESTURES, GestureDataset

    cfg = compose(
        ["data=synthetic", f"data.participants={participants}", f"data.repetitions={repetitions}", *overrides]
    )
    gen = instantiate(cfg.data)
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    rig, surf = HandRig.from_hand(hand), LinkSurface(robot.link_for("arm"))
    records, chunks, phases, start = [], [], [], 0
    for k in range(1, gen.participants + 1):
        style = Style.draw(np.random.default_rng([gen.seed, k, 0]), gen.spread, GESTURES)
        rng = np.random.default_rng([gen.seed, k, region_stream("arm")])
        order, poses, lengths, phase = gen._participant_region_phases(rng, style, rig, surf, "arm")
        start = trial_records(records, participant_id(k), "arm", order, lengths, start)
        chunks.append(poses)
        phases.append(phase)
    ds = GestureDataset(
        name="synthetic",
        synthetic=True,
        hand=hand,
        trials=make_trials_frame(records),
        poses=np.ascontiguousarray(np.concatenate(chunks), dtype=np.float32),
        frame_rate_hz=gen.frame_rate_hz,
        repairs={},
    )
    contacts = instantiate(cfg.contact).compute(ds, robot)
    return ds, np.concatenate(phases), contacts, cfg


def per_trial(ds, phase: np.ndarray, contacts) -> list[dict]:
    """One row per trial: gesture, planned and measured span (frames), frames before and after the plan."""
    in_contact = np.zeros(ds.n_frames, dtype=bool)
    in_contact[contacts.frame] = True
    rows = []
    for tr in ds.trials.itertuples():
        s, n = int(tr.start), int(tr.n_frames)
        p = np.flatnonzero(phase[s : s + n])
        c = np.flatnonzero(in_contact[s : s + n])
        row = dict(
            gesture=str(tr.gesture), plan=int(p[-1] - p[0] + 1) if p.size else 0, span=0, before=None, after=None
        )
        if p.size == 0:  # the planned touches fall between frames (as plan_first_frame = -1 in the sessions)
            rows.append(row)
            continue
        if c.size:
            row.update(span=int(c[-1] - c[0] + 1), before=int(p[0] - c[0]), after=int(c[-1] - p[-1]))
        rows.append(row)
    return rows


#: Planned contact phase lengths (s) the ratio is also split by: the whole-body study's rub plans are short.
PLAN_BINS_S = ((0.0, 1.0), (1.0, 2.0), (2.0, float("inf")))


def by_plan_length(rs: list[dict], fps: float) -> dict[str, dict]:
    """Per planned-length bin (:data:`PLAN_BINS_S`): trials, median ratio, share above 1.4, frames before/after."""
    out = {}
    for lo, hi in PLAN_BINS_S:
        sel = [r for r in rs if lo * fps <= r["plan"] < hi * fps]
        if not sel:
            continue
        ratio = np.array([r["span"] / r["plan"] for r in sel])
        hit = [r for r in sel if r["span"] > 0]
        out[f"{lo:g}-{hi:g} s"] = {
            "trials": len(sel),
            "contact_plan_ratio_median": round(float(np.median(ratio)), 3),
            "share_above_1_4": round(float(np.mean(ratio > 1.4)), 3),
            "frames_before_plan_median": float(np.median([r["before"] for r in hit])) if hit else None,
            "frames_after_plan_median": float(np.median([r["after"] for r in hit])) if hit else None,
        }
    return out


def summarize(rows: list[dict], fps: float) -> dict[str, dict]:
    out = {}
    for g in sorted({r["gesture"] for r in rows}):
        rs = [r for r in rows if r["gesture"] == g and r["plan"] > 0]
        ratio = np.array([r["span"] / r["plan"] for r in rs])
        hit = [r for r in rs if r["span"] > 0]
        q25, q50, q75 = np.percentile(ratio, [25, 50, 75])
        out[g] = {
            "trials": len(rs),
            "trials_without_planned_frame": sum(r["gesture"] == g and r["plan"] == 0 for r in rows),
            "contact_plan_ratio_median": round(float(q50), 3),
            "contact_plan_ratio_q25_q75": [round(float(q25), 3), round(float(q75), 3)],
            "planned_contact_s_median": round(float(np.median([r["plan"] for r in rs])) / fps, 3),
            "contact_s_median": round(float(np.median([r["span"] for r in rs])) / fps, 3),
            "frames_before_plan_median": float(np.median([r["before"] for r in hit])) if hit else None,
            "frames_after_plan_median": float(np.median([r["after"] for r in hit])) if hit else None,
            "no_contact_share": round(1.0 - len(hit) / len(rs), 3),
            "share_above_1_4": round(float(np.mean(ratio > 1.4)), 3),
            "share_below_0_7": round(float(np.mean(ratio < 0.7)), 3),
            "by_planned_length": by_plan_length(rs, fps),
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=18)
    ap.add_argument("--repetitions", type=int, default=10)
    ap.add_argument("--name", default="arm_contact_plan", help="JSON name under outputs/bench/")
    ap.add_argument("overrides", nargs="*", help="config overrides (robot=..., contact=...)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    ds, phase, contacts, cfg = arm_trials(args.participants, args.repetitions, args.overrides)
    per_gesture = summarize(per_trial(ds, phase, contacts), float(ds.frame_rate_hz))
    for g, e in per_gesture.items():
        print(
            f"{g}: {e['trials']} trials, contact/plan {e['contact_plan_ratio_median']:.3f} "
            f"(25-75 % {e['contact_plan_ratio_q25_q75'][0]:.2f}-{e['contact_plan_ratio_q25_q75'][1]:.2f}), "
            f"{e['frames_before_plan_median']} frames before, {e['frames_after_plan_median']} after"
        )
    result = {
        **header("bench_arm_contact_plan.py", __doc__),
        "robot": str(cfg.robot.name),
        "contact": str(cfg.contact._target_),
        "participants": args.participants,
        "repetitions": args.repetitions,
        "frame_rate_hz": float(ds.frame_rate_hz),
        "per_gesture": per_gesture,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    print(write_json(args.name, result))


if __name__ == "__main__":
    main()
