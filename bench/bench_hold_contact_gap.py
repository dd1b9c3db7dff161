"""Held gestures on non-limb parts: how far the drawing hand is off its own link during the contact phase.

Picks the first ``--n`` sessions of the full ``robot=reachy2`` scenario study whose touch is a held gesture (rub,
grab) on a part other than the upper arm or forearm, generates each (the study's own random streams) and measures,
over the frames of the gesture trial's contact phase, the gap (mm) between the drawing hand's nearest capsule and
its own link (exact capsule-vs-mesh distance minus radius; <= 0: touching): as the gesture generator places the
hand (before :func:`settle_hands`), after settling, and as generated (after ``hold_contact`` and settling again;
with ``--no-hold`` without ``hold_contact``: the hands as before it existed). A contact run: consecutive
contact-phase frames touching the own link. ``phase_span_ratio_to_arm``: the contact phase's first to last frame over
the touch, against the arm study's contact fraction (what the plausibility check's contact fraction would read if
the hand touched exactly during the phase). ``duration_factor``: the participant's and the participant x gesture
factors on the contact duration (:func:`sphri.data.gestures.contact_duration`; median 1 over participants).

    python bench/bench_hold_contact_gap.py [--n 8] [--no-hold] [--gestures rub,grab] [--all-parts]

Writes ``outputs/bench/hold_contact_gap[_GESTURES][_all][_nohold].json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import machine, scenario_study, write_json  # noqa: E402

HELD = ("rub", "grab")
ARM_LIKE = ("upper_arm", "forearm")


def _gaps(poses, link_poses, robot, hand, link, mask) -> np.ndarray:
    from sphri.sessions.synthetic import HOLD_MAX_GAP_M, own_link_gap

    gap, _ = own_link_gap(poses[mask], link_poses[mask, link], robot, hand, link, 4 * HOLD_MAX_GAP_M)
    return gap * 1e3


def _stats(g: np.ndarray) -> dict:
    fin = np.where(np.isfinite(g), g, 200.0)
    return {
        "off_share": round(float((g > 0).mean()), 3) if g.size else None,
        "gap_median_mm": round(float(np.median(fin)), 1) if g.size else None,
        "gap_p90_mm": round(float(np.percentile(fin, 90)), 1) if g.size else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--no-hold", action="store_true", help="measure the generator without hold_contact")
    ap.add_argument("--gestures", default=",".join(HELD), help="comma-separated gestures to pick (default rub,grab)")
    ap.add_argument("--all-parts", action="store_true", help="also touches on the upper arm and forearm")
    args = ap.parse_args()

    from sphri.data.gestures import Style
    from sphri.data.handfk import HandRig
    from sphri.hand.kinematics import quat_to_matrix
    from sphri.sessions import synthetic as syn
    from sphri.sessions.plausibility import arm_reference

    t0 = time.perf_counter()
    hand, robot, gen, table = scenario_study()
    names = list(table["scenarios"])
    rig = HandRig.from_hand(hand)
    captured: dict = {}
    real_hold, real_settle = syn.hold_contact, syn.settle_hands

    def settle(out, *a, **kw):
        captured.setdefault("generator", np.array(out))
        return real_settle(out, *a, **kw)

    def hold(out, lk, robot_, hand_, own, phase, away, *a, **kw):
        captured.update(settled=np.array(out), phase=phase, own=own)
        return (out, 0) if args.no_hold else real_hold(out, lk, robot_, hand_, own, phase, away, *a, **kw)

    syn.hold_contact, syn.settle_hands = hold, settle
    rows = []
    for k in range(1, gen.participants + 1):
        style = Style.draw(np.random.default_rng([gen.seed, k, 0]), gen.spread)
        for rep in range(1, gen.repetitions + 1):
            for si, scen in enumerate(names):
                if len(rows) >= args.n:
                    break
                dr = syn._draw_session(np.random.default_rng([gen.seed, k, si + 1, rep]), table["scenarios"][scen], k)
                if dr.gesture not in args.gestures.split(",") or (dr.part.startswith(ARM_LIKE) and not args.all_parts):
                    continue
                rng = np.random.default_rng([gen.seed, k, si + 1, rep])
                captured.clear()
                out, lk7, info = gen._session(rng, style, rig, robot, {}, table, scen, k)
                lk = np.zeros((*lk7.shape[:2], 4, 4))
                lk[..., :3, :3] = quat_to_matrix(lk7[..., 3:].astype(np.float64))
                lk[..., :3, 3] = lk7[..., :3]
                lk[..., 3, 3] = 1.0
                m = captured["phase"][:, 1]
                link = captured["own"][1]
                pre = _gaps(captured["generator"][:, 1], lk, robot, hand, link, m)
                mid = _gaps(captured["settled"][:, 1], lk, robot, hand, link, m)
                post = _gaps(out[:, 1].astype(np.float64), lk, robot, hand, link, m)
                on = post <= 0
                n_app, n_touch = info["touch_start_frame"], info["touch_frames"]
                f = np.flatnonzero(captured["phase"][n_app : n_app + n_touch, 1])
                phase_span = (f.max() - f.min() + 1) / n_touch if f.size else 0.0
                runs = int((np.diff(np.r_[0, on.astype(np.int8)]) == 1).sum())
                rows.append(
                    {
                        "participant": k,
                        "scenario": scen,
                        "repetition": rep,
                        "gesture": dr.gesture,
                        "part": dr.part,
                        "contact_phase_frames": int(m.sum()),
                        "touch_frames": int(n_touch),
                        "duration_factor": round(style.duration * style.duration_g.get(dr.gesture, 1.0), 3),
                        "phase_span_ratio_to_arm": round(phase_span / arm_reference(dr.gesture)[1], 3),
                        "generator": _stats(pre),
                        "settled": _stats(mid),
                        "final": _stats(post),
                        "final_contact_runs_in_phase": runs,
                        "held_frames": int(info.get("held_frames", 0)),
                        "settled_frames": int(info["settled_frames"]),
                    }
                )
                r = rows[-1]
                print(
                    f"P{k} {scen} r{rep} {dr.gesture} {dr.part}: {r['contact_phase_frames']} phase frames; generator "
                    f"off {r['generator']['off_share']}, gap median {r['generator']['gap_median_mm']} mm, p90 "
                    f"{r['generator']['gap_p90_mm']}; settled off {r['settled']['off_share']}, median "
                    f"{r['settled']['gap_median_mm']} mm; final off {r['final']['off_share']}, median "
                    f"{r['final']['gap_median_mm']} mm; runs {runs}",
                    flush=True,
                )
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": "python bench/bench_hold_contact_gap.py " + " ".join(sys.argv[1:]),
        "what": __doc__.splitlines()[0],
        "hold_contact": not args.no_hold,
        "summary": {
            stage: {
                "off_share_median": float(np.median([r[stage]["off_share"] for r in rows])) if rows else None,
                "touches_all_on": int(sum(r[stage]["off_share"] == 0 for r in rows)),
            }
            for stage in ("generator", "settled", "final")
        }
        | {
            "final_contact_runs_median": float(np.median([r["final_contact_runs_in_phase"] for r in rows]))
            if rows
            else None,
            "phase_span_ratio_median": float(np.median([r["phase_span_ratio_to_arm"] for r in rows])) if rows else None,
            "duration_factor_median": float(np.median([r["duration_factor"] for r in rows])) if rows else None,
        },
        "touches": rows,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    tag = ("" if args.gestures == ",".join(HELD) else "_" + args.gestures.replace(",", "_")) + (
        "_all" if args.all_parts else ""
    )
    print(result["summary"])
    print(write_json("hold_contact_gap" + tag + ("_nohold" if args.no_hold else ""), result))


if __name__ == "__main__":
    main()
