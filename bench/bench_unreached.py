"""Touches whose drawing hand never reaches the robot: where the hand is during its planned contact phase.

Generates every session of the full ``robot=reachy2`` scenario study (the study's own random streams) and, over
the frames of the drawing hand's planned contact phase, measures the gap (mm) between its nearest capsule and its
own link (exact capsule-vs-mesh distance minus radius; <= 0: touching) as the gesture generator places the hand
(before :func:`settle_hands`) and as generated. A touch is *unreached* when no frame of its phase touches its own
link. Per unreached touch: gesture, part, the median and least gap before and after, the frames
``hold_contact`` pulled and the other links the hand presses into during its phase before settling (what
settling backs it out of); and the count. Takes about 2-4 minutes on 2 cores.

    python bench/bench_unreached.py

Writes ``outputs/bench/unreached_touches.json``.
"""

from __future__ import annotations

import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import machine, scenario_study, write_json  # noqa: E402


def main() -> None:

    from sphri.contact.exact import ExactContact
    from sphri.data.gestures import Style
    from sphri.data.handfk import HandRig
    from sphri.sessions import synthetic as syn
    from sphri.sessions.contact import body_contacts

    t0 = time.perf_counter()
    hand, robot, gen, table = scenario_study()
    names = list(table["scenarios"])
    links = syn.tree_of(robot).links
    contact = ExactContact()
    rig = HandRig.from_hand(hand)
    real = syn.settle_hands
    first: dict = {}

    def spy(out, lk, robot_, hand_, own, comp, away, *a, phase=None, **kw):
        first.setdefault("call", (out.copy(), phase, own, lk, np.array(away)))
        return real(out, lk, robot_, hand_, own, comp, away, *a, phase=phase, **kw)

    syn.settle_hands = spy
    rows, n, cosines = [], 0, []
    try:
        for k in range(1, gen.participants + 1):
            style = Style.draw(np.random.default_rng([gen.seed, k, 0]), gen.spread)
            for rep in range(1, gen.repetitions + 1):
                for si, scen in enumerate(names):
                    first.clear()
                    rng = np.random.default_rng([gen.seed, k, si + 1, rep])
                    out, _, info = gen._session(rng, style, rig, robot, {}, table, scen, k)
                    n += 1
                    before, phase, own, lk, away = first["call"]
                    m, link = phase[:, 1], own[1]
                    if not m.any():
                        continue
                    g0, _ = syn.own_link_gap(before[m, 1], lk[m, link], robot, hand, link, 0.5)
                    g1, _ = syn.own_link_gap(out[m, 1].astype(np.float64), lk[m, link], robot, hand, link, 0.5)
                    # before settling, in its phase: the links other than its own the hand presses into, and how
                    # nearly across the surface it is backed out (|cos| of its own link's normal at the deepest
                    # row and its approach, per frame; settling divides the excess by it, at least 0.25)
                    lk7 = syn.pose7(lk)
                    bc = body_contacts(syn.one_session(before, lk7, hand, links, "unreached"), robot, contact)
                    mine = m[bc.frame] & (bc.hand == 1)
                    own_rows = np.flatnonzero(mine & (bc.link == link))
                    cos = np.nan
                    if own_rows.size:
                        deep = own_rows[np.argsort(-bc.depth_m[own_rows], kind="stable")]
                        _, firsts = np.unique(bc.frame[deep], return_index=True)
                        rows_ = deep[firsts]
                        nrm = np.einsum("kij,kj->ki", lk[bc.frame[rows_], link, :3, :3], bc.normal[rows_])
                        cos = float(np.median(np.abs(nrm @ away[1])))
                    cosines.append((bool((g1 <= 0).any()), cos))
                    if (g1 <= 0).any():
                        continue
                    blocking = sorted({links[i] for i in np.unique(bc.link[mine & (bc.link != link)])})
                    rows.append(
                        {
                            "participant": k,
                            "scenario": scen,
                            "repetition": rep,
                            "gesture": info["gesture"],
                            "part": info["part"],
                            "link": links[link],
                            "two_hands": bool(info["two_hands"]),
                            "phase_frames": int(m.sum()),
                            "gap_before_median_mm": round(float(np.median(g0)) * 1e3, 1),
                            "gap_before_min_mm": round(float(g0.min()) * 1e3, 1),
                            "gap_after_median_mm": round(float(np.median(g1)) * 1e3, 1),
                            "gap_after_min_mm": round(float(g1.min()) * 1e3, 1),
                            "held_frames": int(info["held_frames"]),
                            "other_links_pressed_before_settling": blocking,
                            "approach_cos_median": round(cos, 3),
                        }
                    )
    finally:
        syn.settle_hands = real
    after = np.array([r["gap_after_median_mm"] for r in rows]) if rows else np.zeros(0)
    before = np.array([r["gap_before_min_mm"] for r in rows]) if rows else np.zeros(0)
    out = {
        "what": "touches of the full study whose drawing hand touches its own link in no frame of its planned phase",
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": "python bench/bench_unreached.py",
        "sessions_version": syn.SyntheticSessions.VERSION,
        "sessions": n,
        "unreached": len(rows),
        "gap_before_min_mm_range": [float(before.min()), float(before.max())] if rows else None,
        "gap_after_median_mm_range": [float(after.min()), float(after.max())] if rows else None,
        "blocking_links": dict(
            Counter(x for r in rows for x in r["other_links_pressed_before_settling"]).most_common()
        ),
        "approach_cos_median": {
            "reached_median": float(np.nanmedian([c for r, c in cosines if r])),
            "unreached_median": float(np.nanmedian([c for r, c in cosines if not r])),
            "unreached_below_0_25": int(sum(1 for r, c in cosines if not r and c < 0.25)),
            "reached_below_0_25": int(sum(1 for r, c in cosines if r and c < 0.25)),
            "n_reached": int(sum(1 for r, _ in cosines if r)),
        },
        "seconds": round(time.perf_counter() - t0, 1),
        "touches": rows,
    }
    print(f"{len(rows)} of {n} touches unreached; {write_json('unreached_touches', out)}")


if __name__ == "__main__":
    main()
