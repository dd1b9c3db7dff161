"""Why the whole-body study's rubs touch longer than planned: contact span / plan with each session step switched off.

The study's plausibility check (:mod:`sphri.sessions.plausibility`, ``contact_plan_ratio``) reads rub at 1.50x (the
drawing hand in contact 7 frames before its planned contact phase and 6.5 after, median), while the arm study's
rubs read 1.02x (``outputs/bench/arm_contact_plan.json``). This regenerates every rub session of the full
``+experiment=scenario_study robot=reachy2`` study (the study's own random streams, as
``bench/bench_hold_contact_gap.py``), measures the drawing hand's contact with the robot as the study does (exact
capsule-vs-mesh contact with every link, :func:`sphri.sessions.contact.body_contacts`, first to last frame in
contact inside the touch) and its ratio to the planned contact phase, once as generated and once per variant with
one step the session generator adds around the gesture trial switched off (monkeypatched here, not in the package):

- ``no_hold``: without :func:`hold_contact` (no pull onto the own link in the plan);
- ``no_settle``: without :func:`settle_hands` (hands may press into the robot);
- ``no_settle_no_hold``: the gesture trial as placed on the part (plus scale, padding, robot motion);
- ``scale_1``: ``duration_scale`` 1 (no index resampling);
- ``robot_still``: the robot at its final pose during the approach;
- ``one_handed``: two-handed sessions drawn one-handed (no second hand, no padding to a longer trial);
- ``raw``: all of the above off: the gesture generator's trial alone, placed on the part.

and two variants of what the gesture generator is given (not a session step; the arm study gives it the whole
link, sampled 20000 times, and measures contact against that same link):

- ``whole_link`` (``raw_whole_link``: with ``raw``'s steps off): the generator places the hand on the part's whole
  link (:func:`part_link` returning every face), not on the touchable patch of the drawn part;
- ``samples_20000``: the part's patch sampled 20000 times (:class:`LinkSurface`'s default) instead of 6000.

``arm_study_by_effector``: the arm study's own trials of the gesture (18 participants x 10, as
``bench/bench_arm_contact_plan.py``) split by the plan's effector. Per touch also: the plan's effector (palm or finger pads), frames before / after the plan, the capsules in contact outside the plan, and (``full``) how many
of those out-of-plan contact frames the hand was moved by settling and how far the raw placement's hand was from
its own link there (``raw_gap_mm``: <= 0 already touching before any session step).

    python bench/bench_rub_overrun.py [--gesture rub]

Writes ``outputs/bench/rub_overrun[_GESTURE].json``.
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

VARIANTS = (
    "full",
    "no_hold",
    "no_settle",
    "no_settle_no_hold",
    "scale_1",
    "robot_still",
    "one_handed",
    "raw",
    "whole_link",
    "raw_whole_link",
    "samples_20000",
)


def _contact_rows(out, lk7, hand, robot, contact):
    """Contacts of hand 1 (drawing hand) of one session: (frames, capsules, links)."""
    from sphri.sessions.contact import body_contacts
    from sphri.sessions.synthetic import one_session, tree_of

    bc = body_contacts(one_session(out, lk7, hand, tree_of(robot).links, "rub"), robot, contact)
    m = bc.hand == 1
    return bc.frame[m].astype(np.int64), bc.capsule[m].astype(np.int64), bc.link[m].astype(np.int64)


def _measure(out, lk7, info, hand, robot, contact) -> dict:
    n_app, n_touch = int(info["touch_start_frame"]), int(info["touch_frames"])
    f, c, lnk = _contact_rows(out, lk7, hand, robot, contact)
    rel = f - n_app
    keep = (rel >= 0) & (rel < n_touch)
    rel, c, lnk = rel[keep], c[keep], lnk[keep]
    a, b = int(info["plan_first_frame"]), int(info["plan_last_frame"])
    row = {"touch_frames": n_touch, "plan_frames": b - a + 1 if a >= 0 else 0, "plan": [a, b]}
    if rel.size == 0 or a < 0:
        return row | {"span_frames": 0, "ratio": None}
    lo, hi = int(rel.min()), int(rel.max())
    outside = (rel < a) | (rel > b)
    return row | {
        "span_frames": hi - lo + 1,
        "ratio": round((hi - lo + 1) / (b - a + 1), 3),
        "early_frames": a - lo,
        "late_frames": hi - b,
        "capsules_outside_plan": sorted({int(x) for x in c[outside]}),
        "links_outside_plan": sorted({int(x) for x in lnk[outside]}),
        "outside_frames": sorted({int(x) for x in rel[outside]}),
    }


def arm_by_effector(gesture: str, participants: int, repetitions: int) -> dict:
    """The arm study's own trials of ``gesture`` (``bench/bench_arm_contact_plan.py``'s trials: ``data=synthetic`` on
    the default robot's arm) split by the plan's effector (palm, finger pads): trials, median contact/plan ratio,
    share above 1.4x, median frames before / after the plan."""
    from bench_arm_contact_plan import arm_trials, per_trial

    from sphri.data import gestures as gmod

    real_plan, effectors = gmod._PLANS[gesture], []

    def plan_of(d):
        out = real_plan(d)
        effectors.append(out.effector)
        return out

    gmod._PLANS[gesture] = plan_of
    try:
        ds, phase, contacts, _ = arm_trials(participants, repetitions, [])
    finally:
        gmod._PLANS[gesture] = real_plan
    rows = [r for r in per_trial(ds, phase, contacts) if r["gesture"] == gesture]
    out: dict = {"participants": participants, "repetitions": repetitions, "plans_drawn": len(effectors)}
    if len(effectors) != len(rows):  # plans not one per trial in trial order: no split
        return out | {"trials": len(rows), "split": None}
    for eff in sorted(set(effectors)):
        rs = [r for r, e in zip(rows, effectors) if e == eff and r["plan"] > 0]
        ratio = np.array([r["span"] / r["plan"] for r in rs])
        hit = [r for r in rs if r["span"] > 0]
        out[eff] = {
            "trials": len(rs),
            "contact_plan_ratio_median": round(float(np.median(ratio)), 3) if rs else None,
            "share_above_1_4": round(float(np.mean(ratio > 1.4)), 3) if rs else None,
            "frames_before_plan_median": float(np.median([r["before"] for r in hit])) if hit else None,
            "frames_after_plan_median": float(np.median([r["after"] for r in hit])) if hit else None,
        }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gesture", default="rub")
    args = ap.parse_args()
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.data.gestures import Style
    from sphri.data.handfk import HandRig
    from sphri.hand.kinematics import quat_to_matrix
    from sphri.sessions import synthetic as syn

    t0 = time.perf_counter()
    cfg = compose(["+experiment=scenario_study", "robot=reachy2"])
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    contact = instantiate(cfg.contact)
    gen = instantiate(cfg.data)
    table = syn.load_priors(gen.priors, [p.name for p in robot.parts], list(robot.tree.joint_names))
    names = list(table["scenarios"])
    rig = HandRig.from_hand(hand)
    real = {
        k: getattr(syn, k)
        for k in ("settle_hands", "hold_contact", "_draw_session", "_robot_motion", "part_link", "LinkSurface")
    }
    cap: dict = {}
    off: set[str] = set()

    def settle(out, lk, *a, **kw):
        cap.setdefault("raw", np.array(out))
        if "settle" in off:
            return np.array(out), 0
        res = real["settle_hands"](out, lk, *a, **kw)
        cap.setdefault("settled", np.array(res[0]))
        return res

    def hold(out, *a, **kw):
        return (np.array(out), 0) if "hold" in off else real["hold_contact"](out, *a, **kw)

    def draw(rng, s, k):
        dr = real["_draw_session"](rng, s, k)
        if "scale" in off:
            dr.scale = 1.0
        if "two" in off:
            dr.two_hands = False
        return dr

    def motion(*a, **kw):
        poses = real["_robot_motion"](*a, **kw)
        return np.repeat(poses[-1:], len(poses), axis=0) if "motion" in off else poses

    def patch(robot_, part, *a, **kw):
        if "patch" not in off:
            return real["part_link"](robot_, part, *a, **kw)
        from sphri.types import Link

        lk = robot_.links[next(p for p in robot_.parts if p.name == part).link]
        return Link(name=part, vertices=lk.vertices, faces=lk.faces, watertight=lk.watertight)

    def surface(link, n_samples=20000, **kw):
        return real["LinkSurface"](link, n_samples=20000 if "samples" in off else n_samples, **kw)

    switch = {
        "full": set(),
        "no_hold": {"hold"},
        "no_settle": {"settle"},
        "no_settle_no_hold": {"settle", "hold"},
        "scale_1": {"scale"},
        "robot_still": {"motion"},
        "one_handed": {"two"},
        "raw": {"settle", "hold", "scale", "motion", "two"},
        "whole_link": {"patch"},
        "raw_whole_link": {"settle", "hold", "scale", "motion", "two", "patch"},
        "samples_20000": {"samples"},
    }
    syn.settle_hands, syn.hold_contact, syn._draw_session, syn._robot_motion = settle, hold, draw, motion
    syn.part_link, syn.LinkSurface = patch, surface
    from sphri.data import gestures as gmod

    real_plan = gmod._PLANS[args.gesture]

    def plan_of(d):
        out = real_plan(d)
        cap.setdefault("effector", out.effector)
        return out

    gmod._PLANS[args.gesture] = plan_of
    rows = []
    for k in range(1, gen.participants + 1):
        style = Style.draw(np.random.default_rng([gen.seed, k, 0]), gen.spread)
        for rep in range(1, gen.repetitions + 1):
            for si, scen in enumerate(names):
                seed = [gen.seed, k, si + 1, rep]
                dr = real["_draw_session"](np.random.default_rng(seed), table["scenarios"][scen], k)
                if dr.gesture != args.gesture:
                    continue
                row = {
                    "participant": k,
                    "scenario": scen,
                    "repetition": rep,
                    "part": dr.part,
                    "two_hands": dr.two_hands,
                    "duration_scale": round(dr.scale, 3),
                    "robot_motion": table["scenarios"][scen]["robot_motion"],
                }
                for v in VARIANTS:
                    off.clear()
                    off.update(switch[v])
                    cap.clear()
                    out, lk7, info = gen._session(np.random.default_rng(seed), style, rig, robot, {}, table, scen, k)
                    row[v] = _measure(out, lk7, info, hand, robot, contact)
                    row.setdefault("effector", cap.get("effector"))
                    if v == "full" and row[v].get("outside_frames"):
                        # out-of-plan contact frames: moved by settling? the raw placement's gap to the own link there
                        n_app = int(info["touch_start_frame"])
                        fr = np.asarray(row[v]["outside_frames"]) + n_app
                        moved = np.any(
                            np.abs(cap["settled"][fr, 1, :, :3] - cap["raw"][fr, 1, :, :3]) > 1e-9, axis=(1, 2)
                        )
                        lk = np.zeros((*lk7.shape[:2], 4, 4))
                        lk[..., :3, :3] = quat_to_matrix(lk7[..., 3:].astype(np.float64))
                        lk[..., :3, 3] = lk7[..., :3]
                        lk[..., 3, 3] = 1.0
                        li = {n: i for i, n in enumerate(syn.tree_of(robot).links)}
                        own = li[next(x for x in robot.parts if x.name == dr.part).link]
                        gap, _ = syn.own_link_gap(cap["raw"][fr, 1], lk[fr, own], robot, hand, own, 0.1)
                        row[v]["outside_moved_by_settle"] = int(moved.sum())
                        row[v]["raw_gap_mm_outside"] = [
                            round(float(g) * 1e3, 1) if np.isfinite(g) else None for g in gap
                        ]
                rows.append(row)
                print(
                    f"P{k} {scen} r{rep} {dr.part} two={dr.two_hands} scale={dr.scale:.2f}: "
                    + ", ".join(
                        f"{v} {row[v]['ratio']} ({row[v].get('early_frames')}/{row[v].get('late_frames')})"
                        for v in VARIANTS
                    ),
                    flush=True,
                )
    syn.settle_hands, syn.hold_contact, syn._draw_session, syn._robot_motion = (
        real["settle_hands"],
        real["hold_contact"],
        real["_draw_session"],
        real["_robot_motion"],
    )
    syn.part_link, syn.LinkSurface = real["part_link"], real["LinkSurface"]
    gmod._PLANS[args.gesture] = real_plan

    def med(v, key):
        x = [r[v][key] for r in rows if r[v].get("ratio") is not None]
        return float(np.median(x)) if x else None

    summary = {
        v: {
            "touches_with_contact": sum(r[v].get("ratio") is not None for r in rows),
            "contact_plan_ratio_median": med(v, "ratio"),
            "early_frames_median": med(v, "early_frames"),
            "late_frames_median": med(v, "late_frames"),
            "capsules_outside_plan": sorted({c for r in rows for c in r[v].get("capsules_outside_plan", [])}),
        }
        for v in VARIANTS
    }
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": "python bench/bench_rub_overrun.py " + " ".join(sys.argv[1:]),
        "what": __doc__.splitlines()[0],
        "config": "+experiment=scenario_study robot=reachy2",
        "gesture": args.gesture,
        "variants": {v: sorted(s) for v, s in switch.items()},
        "summary": summary,
        "arm_study_by_effector": arm_by_effector(args.gesture, 18, 10),
        "touches": rows,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    for v, s in summary.items():
        print(v, s)
    print("arm study by effector:", result["arm_study_by_effector"])
    print(write_json("rub_overrun" + ("" if args.gesture == "rub" else "_" + args.gesture), result))


if __name__ == "__main__":
    main()
