"""How often the plausibility timing check's band misses for the arm study's own generator at the study's counts.

The whole-body study judges a gesture's median contact fraction against the arm study's (band 0.7-1.4x,
:mod:`sphri.sessions.plausibility`) from a few touches of a few participants. This draws the arm study's gesture
generator (``data=synthetic``, the arm, 18 participants x ``--repetitions`` trials per gesture), takes each trial's
contact-phase span (first to last frame of the plan's touches over the trial) and resamples participants and trials
at the full Reachy 2 study's counts (touches and distinct participants per gesture, below) ``--draws`` times: the
share of draws whose median lies outside the band, and the 5-95 % range of the median.

    python bench/bench_timing_band_noise.py [--repetitions 10] [--draws 4000]

Writes ``outputs/bench/timing_band_noise.json``.
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

#: (touches, distinct participants) per gesture in the full robot=reachy2 study (summary.json, generator truth).
STUDY_COUNTS = {
    "rub": (7, 6),
    "tap": (19, 11),
    "pat": (29, 11),
    "grab": (31, 12),
    "stroke": (12, 9),
    "push": (73, 12),
    "hit": (5, 5),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repetitions", type=int, default=10)
    ap.add_argument("--draws", type=int, default=4000)
    args = ap.parse_args()
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.data.gestures import Style
    from sphri.data.handfk import HandRig
    from sphri.data.linkgeom import LinkSurface
    from sphri.data.synthetic import SyntheticData, region_stream
    from sphri.sessions.plausibility import TIMING_BAND, arm_reference
    from sphri.types import GESTURES

    t0 = time.perf_counter()
    cfg = compose([])
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    gen = SyntheticData(participants=18, repetitions=args.repetitions)
    rig, surf = HandRig.from_hand(hand), LinkSurface(robot.link_for("arm"))
    per: dict[tuple[str, int], list[float]] = {}
    for k in range(1, gen.participants + 1):
        style = Style.draw(np.random.default_rng([gen.seed, k, 0]), gen.spread, GESTURES)
        rng = np.random.default_rng([gen.seed, k, region_stream("arm")])
        order, _, lengths, phase = gen._participant_region_phases(rng, style, rig, surf, "arm")
        s = 0
        for g, n in zip(order, lengths):
            f = np.flatnonzero(phase[s : s + n])
            s += n
            per.setdefault((g, k), []).append((f.max() - f.min() + 1) / n if f.size else 0.0)
    lo, hi = TIMING_BAND
    rng = np.random.default_rng(1)
    out = {}
    for g, (n_t, n_p) in STUDY_COUNTS.items():
        ref = arm_reference(g)[1]
        allv = np.concatenate([per[(g, k)] for k in range(1, gen.participants + 1)])
        meds = np.empty(args.draws)
        for b in range(args.draws):
            ps = rng.choice(gen.participants, n_p, replace=False) + 1
            who = np.r_[ps, rng.choice(ps, n_t - n_p)]
            meds[b] = np.median([per[(g, int(k))][rng.integers(len(per[(g, int(k))]))] for k in who]) / ref
        out[g] = {
            "touches": n_t,
            "participants": n_p,
            "arm_generator_ratio_median": round(float(np.median(allv)) / ref, 3),
            "outside_band_share": round(float(np.mean((meds < lo) | (meds > hi))), 3),
            "median_ratio_p5": round(float(np.percentile(meds, 5)), 3),
            "median_ratio_p95": round(float(np.percentile(meds, 95)), 3),
        }
        e = out[g]
        print(
            f"{g}: arm generator {e['arm_generator_ratio_median']:.2f}x; {n_t} touches of {n_p} participants: "
            f"outside {lo}-{hi}x in {100 * e['outside_band_share']:.0f} % of draws, median 5-95 % "
            f"{e['median_ratio_p5']:.2f}-{e['median_ratio_p95']:.2f}x"
        )
    result = {
        **header("bench_timing_band_noise.py", __doc__),
        "band": [lo, hi],
        "per_gesture": out,
        "seconds": round(time.perf_counter() - t0, 1),
    }
    print(write_json("timing_band_noise", result))


if __name__ == "__main__":
    main()
