"""Session touches' contact-phase fraction: the arm against Reachy 2's body parts, many participants (chance or structure?).

The whole-body study's timing check (:mod:`sphri.sessions.plausibility`) judges a gesture's median contact fraction
(first to last contact frame of the drawing hand over the touch's rest-to-rest length) against the arm study's
reference (:func:`~sphri.sessions.plausibility.arm_reference`). This measures the generator's own contact phase
(the plan's touches, :func:`sphri.data.synthetic.contact_phase`; no contact computation) of session-style touches:

1. ``surfaces``: ``--participants`` participants drawn as ``data=synthetic_sessions`` draws them (``Style.draw`` on
   the stream ``(seed, k, 0)``), ``--trials`` trials per participant, gesture and surface, each trial one
   ``SyntheticData._participant_region_phases`` call as ``SyntheticSessions._touch`` makes it, on (a) the arm study's
   region (``link_for("arm")`` of the default robot) and (b) Reachy 2 body parts the priors draw (``part_link`` at the
   rest pose, facing the participant); per surface the median of phase span / trial length over the reference;
2. ``study``: the full study's own touches (``data=synthetic_sessions`` defaults, ``robot=reachy2``), redrawn up to
   their touch (session draws, robot motion, the touch trials; no settling): per gesture the median phase fraction of
   the drawing hand over the padded touch length (as the check measures it) and over its own trial's length,
   and the same with ``--participants`` participants;
3. ``arm_like_parts_check``: pat and tap with ``--participants`` participants for ``--seeds`` seeds, touches on
   arm-like parts (upper arm, forearm) against the others, on the session's own random stream and a fresh one.

    python bench/bench_session_timing_structure.py [--participants 120] [--trials 5] [--seeds 10]

Writes ``outputs/bench/session_timing_structure.json``.
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

GESTURES_MEASURED = ("rub", "tap", "pat", "push")
#: Reachy 2 parts the priors draw for these gestures, and the start position the surface faces.
PARTS = {
    "head": "front",
    "shoulder_l": "left",
    "upper_arm_l": "left",
    "torso_front_upper": "front",
    "torso_back_upper": "rear",
    "gripper_l": "front_left",
    "forearm_l": "left",
}


def span_fraction(phase: np.ndarray, n: int) -> float:
    f = np.flatnonzero(phase)
    return (f.max() - f.min() + 1) / n if f.size else 0.0


def redraw_study(sess, participants: int, table: dict, style_of, rig, robot, arm_surface) -> dict[str, dict]:
    """The study's sessions of participants 1..``participants`` redrawn up to their touch (session draws, robot
    motion, each hand's touch trial as ``SyntheticSessions._touches`` draws it; no settling): per gesture the
    median contact-phase fraction of the drawing hand over the padded touch length (the two hands' longer trial,
    what the check divides by) and over the drawing hand's own trial, and the median touch length both ways; the
    padded fraction on arm-like parts (upper arm, forearm) and the others apart; and, from a copy of the session's
    random stream at the drawing hand's touch, the same trial drawn on ``arm_surface`` (the arm study's region):
    its median fraction over the same sessions (``..._same_stream_on_arm``)."""
    import copy

    from sphri.sessions import synthetic as ss
    from sphri.sessions.plausibility import arm_reference

    names = list(table["scenarios"])
    fps = sess.frame_rate_hz
    rows = []
    cache: dict = {}
    for k in range(1, participants + 1):
        style = style_of(np.random.default_rng([sess.seed, k, 0]), sess.spread)
        for rep in range(1, sess.repetitions + 1):
            for pos in range(len(names)):
                si = (k - 1 + pos) % len(names)
                s = table["scenarios"][names[si]]
                rng = np.random.default_rng([sess.seed, k, si + 1, rep])
                dr = ss._draw_session(rng, s, k)
                n_app = max(int(round(dr.approach_s * fps)), 2)
                t = np.arange(n_app) / fps
                final = ss._robot_motion(rng, robot, s, float(table["base_speed_m_s"]), dr, t)[-1]
                parts = [dr.part] + ([ss.mirror_part(dr.part)] if dr.two_hands else [])
                gen = sess.trial_generator("arm", dr.gesture)
                _, _, n_arm, ph_arm = gen._participant_region_phases(copy.deepcopy(rng), style, rig, arm_surface, "arm")
                lengths, phases = [], []
                for p in parts:  # as _touches, without placing the poses in the world
                    _, phase = sess._touch(
                        rng,
                        style,
                        rig,
                        robot,
                        cache,
                        p,
                        dr.gesture,
                        final,
                        dr.position,
                        dr.direction,
                        static=s["robot_motion"] == "none",
                    )
                    idx = np.round(np.arange(int(round(len(phase) * dr.scale))) / dr.scale).astype(int)
                    lengths.append(idx.size)
                    phases.append(phase[idx.clip(0, len(phase) - 1)])
                n_touch = max(lengths)
                rows.append(
                    dict(
                        k=k,
                        gesture=dr.gesture,
                        two_hands=dr.two_hands,
                        arm_like=dr.part.startswith(("upper_arm", "forearm")),
                        padded=span_fraction(phases[0], n_touch),
                        own=span_fraction(phases[0], lengths[0]),
                        on_arm=span_fraction(ph_arm, n_arm[0]),
                        n_touch=n_touch,
                        n_own=lengths[0],
                    )
                )
    out: dict[str, dict] = {}
    for g in sorted({r["gesture"] for r in rows}):
        ref_s, ref = arm_reference(g)
        rs = [r for r in rows if r["gesture"] == g]
        col = {
            c: np.array([r[c] for r in rs], dtype=np.float64) for c in ("padded", "own", "on_arm", "n_touch", "n_own")
        }
        out[g] = {
            "touches": len(rs),
            "participants": len({r["k"] for r in rs}),
            "two_handed": int(sum(r["two_hands"] for r in rs)),
            "contact_fraction_ratio_padded": round(float(np.median(col["padded"])) / ref, 3),
            "contact_fraction_ratio_own_trial": round(float(np.median(col["own"])) / ref, 3),
            "contact_fraction_ratio_same_stream_on_arm": round(float(np.median(col["on_arm"])) / ref, 3),
            "duration_ratio_padded": round(float(np.median(col["n_touch"])) / fps / ref_s, 3),
            "duration_ratio_own_trial": round(float(np.median(col["n_own"])) / fps / ref_s, 3),
        }
        arm_like = np.array([r["arm_like"] for r in rs])
        for name, sel in (("arm_like_parts", arm_like), ("other_parts", ~arm_like)):
            if sel.any():
                out[g][name] = {
                    "touches": int(sel.sum()),
                    "contact_fraction_ratio_own_trial": round(float(np.median(col["own"][sel])) / ref, 3),
                    "contact_fraction_ratio_same_stream_on_arm": round(float(np.median(col["on_arm"][sel])) / ref, 3),
                }
        print(f"{participants} participants, {g}: {out[g]}", flush=True)
    return out


def arm_like_check(sess, participants: int, seeds: int, table: dict, rig, robot, arm_surface) -> dict[str, dict]:
    """Pat and tap touches of the study redrawn with ``participants`` participants for each seed 0..``seeds``-1:
    the median contact-phase fraction (over the reference) of touches drawn on arm-like parts (upper arm, forearm)
    and on the others, each trial drawn on ``arm_surface`` from the session's own stream at the touch (what the
    session draws: the phase does not depend on the surface) and from a fresh stream (``(seed, k, scenario,
    repetition, 99)``); Mann-Whitney p of arm-like against other (touches as independent: participants' touches are
    not, so p is a lower bound)."""
    from scipy.stats import mannwhitneyu

    from sphri.data.gestures import Style
    from sphri.data.synthetic import SyntheticData
    from sphri.sessions import synthetic as ss
    from sphri.sessions.plausibility import arm_reference

    names = list(table["scenarios"])
    out: dict[str, dict] = {}
    for g in ("pat", "tap"):
        ref = arm_reference(g)[1]
        rows = []
        per_seed = []
        for seed in range(seeds):
            gen = SyntheticData(seed=seed, participants=1, repetitions=1, regions=["arm"], gestures=[g])
            n0 = len(rows)
            for k in range(1, participants + 1):
                style = Style.draw(np.random.default_rng([seed, k, 0]), sess.spread)
                for rep in range(1, sess.repetitions + 1):
                    for pos in range(len(names)):
                        si = (k - 1 + pos) % len(names)
                        rng = np.random.default_rng([seed, k, si + 1, rep])
                        dr = ss._draw_session(rng, table["scenarios"][names[si]], k)
                        if dr.gesture != g:
                            continue
                        n_app = max(int(round(dr.approach_s * sess.frame_rate_hz)), 2)
                        t = np.arange(n_app) / sess.frame_rate_hz
                        ss._robot_motion(rng, robot, table["scenarios"][names[si]], 0.25, dr, t)  # its draws
                        _, _, n, ph = gen._participant_region_phases(rng, style, rig, arm_surface, "arm")
                        fresh = np.random.default_rng([seed, k, si + 1, rep, 99])
                        _, _, n2, ph2 = gen._participant_region_phases(fresh, style, rig, arm_surface, "arm")
                        arm_like = dr.part.startswith(("upper_arm", "forearm"))
                        rows.append((arm_like, span_fraction(ph, n[0]), span_fraction(ph2, n2[0])))
            r = np.array(rows[n0:], dtype=np.float64)
            a = r[:, 0] > 0
            per_seed.append([round(float(np.median(r[a, 1])) / ref, 3), round(float(np.median(r[~a, 1])) / ref, 3)])
        r = np.array(rows, dtype=np.float64)
        a = r[:, 0] > 0
        e: dict = {
            "touches_arm_like": int(a.sum()),
            "touches_other": int((~a).sum()),
            "per_seed_arm_like_other": per_seed,
        }
        for j, name in ((1, "session_stream"), (2, "fresh_stream")):
            e[name] = {
                "arm_like": round(float(np.median(r[a, j])) / ref, 3),
                "other": round(float(np.median(r[~a, j])) / ref, 3),
                "mann_whitney_p": float(f"{mannwhitneyu(r[a, j], r[~a, j]).pvalue:.3g}"),
            }
        out[g] = e
        print(f"arm-like check {g}: {e}", flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=120)
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--seeds", type=int, default=10, help="seeds of the arm-like parts check (pat, tap)")
    args = ap.parse_args()
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.data.gestures import Style
    from sphri.data.handfk import HandRig
    from sphri.data.linkgeom import LinkSurface
    from sphri.sessions import synthetic as ss
    from sphri.sessions.plausibility import TIMING_BAND, arm_reference

    t0 = time.perf_counter()
    lo, hi = TIMING_BAND
    cfg_arm = compose([])
    cfg = compose(["+experiment=scenario_study", "robot=reachy2"])
    hand = instantiate(cfg.hand).build()
    arm_robot, robot = instantiate(cfg_arm.robot).build(), instantiate(cfg.robot).build()
    sess = instantiate(cfg.data)
    rig = HandRig.from_hand(hand)
    rest = robot.link_poses(np.zeros((1, 3)), {})[0]
    surfaces = {"arm": LinkSurface(arm_robot.link_for("arm"))}
    for part, pos in PARTS.items():
        ang = np.radians(ss.DIRECTIONS[pos])
        towards = np.array([np.cos(ang), np.sin(ang), 0.0])
        surfaces[part] = LinkSurface(ss.part_link(robot, part, rest, towards), n_samples=6000)

    # 1. many participants, the arm against the parts
    fr: dict[tuple[str, str], list[float]] = {}
    per_participant: dict[tuple[str, str, int], list[float]] = {}
    for k in range(1, args.participants + 1):
        style = Style.draw(np.random.default_rng([sess.seed, k, 0]), sess.spread)
        for gi, g in enumerate(GESTURES_MEASURED):
            for si, (name, surf) in enumerate(surfaces.items()):
                gen = sess.trial_generator(name, g)
                for r in range(args.trials):
                    rng = np.random.default_rng([sess.seed, k, 7000 + gi, si, r])
                    _, out, lengths, phase = gen._participant_region_phases(rng, style, rig, surf, name)
                    v = span_fraction(phase, lengths[0])
                    fr.setdefault((g, name), []).append(v)
                    per_participant.setdefault((g, name, k), []).append(v)
        if k % 10 == 0:
            print(f"{k} participants, {time.perf_counter() - t0:.0f} s", flush=True)
    surf_out: dict[str, dict] = {}
    for g in GESTURES_MEASURED:
        ref = arm_reference(g)[1]
        arm = np.asarray(fr[(g, "arm")])
        e: dict = {"reference_contact_fraction": round(ref, 4), "trials_per_surface": int(arm.size)}
        for name in surfaces:
            x = np.asarray(fr[(g, name)])
            boot = np.random.default_rng(0).choice(x, (2000, x.size))
            e[name] = {
                "median_ratio": round(float(np.median(x)) / ref, 3),
                "median_ratio_ci95": [round(float(q) / ref, 3) for q in np.percentile(np.median(boot, 1), [2.5, 97.5])],
                "over_arm": round(float(np.median(x) / np.median(arm)), 3),
                "inside_band": bool(lo <= np.median(x) / ref <= hi),
            }
        parts_all = np.concatenate([fr[(g, p)] for p in PARTS])
        e["all_parts_median_ratio"] = round(float(np.median(parts_all)) / ref, 3)
        # per-participant medians (arm): how far participants spread
        pm = np.array([np.median(per_participant[(g, "arm", k)]) for k in range(1, args.participants + 1)]) / ref
        e["arm_participant_median_ratio_p10_p90"] = [round(float(q), 3) for q in np.percentile(pm, [10, 90])]
        surf_out[g] = e
        print(
            f"{g}: arm {e['arm']['median_ratio']:.2f}x {e['arm']['median_ratio_ci95']}, parts "
            + ", ".join(f"{p} {e[p]['median_ratio']:.2f}" for p in PARTS)
            + f"; all parts {e['all_parts_median_ratio']:.2f}x"
        )

    # 2. the study's own touches (its 12 participants), then as many participants as in 1
    table = ss.load_priors(sess.priors, [p.name for p in robot.parts], list(robot.tree.joint_names))
    study = redraw_study(sess, sess.participants, table, Style.draw, rig, robot, surfaces["arm"])
    many = redraw_study(sess, args.participants, table, Style.draw, rig, robot, surfaces["arm"])
    arm_like = arm_like_check(sess, args.participants, args.seeds, table, rig, robot, surfaces["arm"])
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": "python bench/bench_session_timing_structure.py " + " ".join(sys.argv[1:]),
        "what": __doc__.splitlines()[0],
        "band": [lo, hi],
        "participants": args.participants,
        "trials": args.trials,
        "surfaces": surf_out,
        "study_touches_generator_phase": study,
        "study_redrawn_many_participants": many,
        "arm_like_parts_check": arm_like,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    print(write_json("session_timing_structure", result))


if __name__ == "__main__":
    main()
