"""Plausibility of synthetic sessions' hands against the robot and the arm study (``summary.json``: ``plausibility``).

Three checks of :func:`plausibility`, from the sessions' contact rows (:class:`BodyContacts`) and the generator's
draws (``SessionDataset.truth``):

- **penetration**: the 95th percentile of the contact rows' depth (mm) must not exceed the skin compliance
  (``data.compliance_mm``);
- **on the drawn part**: of the (frame, hand) pairs in contact, the share whose contacts all lie on the link of
  the body part the generator drew for that hand (target :data:`ON_PART_TARGET`);
- **timing**: placing a gesture on the whole body must keep the gesture's own timing (no stretch, contact held
  for the planned phase). Per gesture, judged when it has at least :data:`MIN_TOUCHES` touches, both ratios
  inside :data:`TIMING_BAND` (the trial-length band, :data:`sphri.data.lengths.BANDS` ``quantile``):

  - *duration*: the median of the drawing hand's own trial length (s, rest to rest, ``trial_frames`` of the
    truth table: time-scaled, without the padding to a two-handed touch's longer trial) over the VR dataset's
    median arm trial (:data:`VR_MEDIAN_TRIAL_FRAMES`, at :data:`VR_FRAME_RATE_HZ`);
  - *contact, paired*: the median over touches of the drawing hand's measured contact span (first to last
    frame in contact with any link, inside the touch) over its planned contact phase (``plan_first_frame`` to
    ``plan_last_frame``, the generator's plan for that very touch): 1.0 is contact held exactly for the plan.
    The arm study itself holds 1.00-1.03x for every gesture (its own trials with the exact contact stage,
    ``outputs/bench/arm_contact_plan.json``), so the ratio is judged as it stands, not over the arm study's.

  Reported, not judged: ``touches_reached_share``, the share of touches in which the drawing hand touches any
  link at all (``n_reached`` per gesture): a touch whose drawn spot other links block (the hand is moved back
  along its approach until it clears them, and held contact gives up beyond :data:`sphri.sessions.synthetic.HOLD_MAX_GAP_M`) has none;
  and the calibration against CoST, the median contact fraction (span over the drawing
  hand's own trial) over the arm study's (:func:`arm_reference`: CoST's median contact duration, lognormal
  with CoST's mean and SD, over the VR median trial), with beside it the 2.5-97.5 % range of the median of
  the gesture's count of draws from that lognormal over its median (:func:`cost_sampling_interval`). It is not
  judged because at the study's counts it tests which participants drew the gesture, not the hands: the arm
  study's own generator, resampled at the study's counts, falls outside the band in 4-53 % of draws
  (``outputs/bench/timing_band_noise.json``), and with 120 participants every gesture's median is inside it on
  every body part, a touch's planned contact phase being the same frame for frame on the arm as on its part
  (``outputs/bench/session_timing_structure.json``).
"""

from __future__ import annotations

import functools

import numpy as np
import pandas as pd

from sphri.data.lengths import BANDS
from sphri.data.reference_stats import COST_DURATION_MS, VR_FRAME_RATE_HZ, VR_MEDIAN_TRIAL_FRAMES

#: Share of contact (frame, hand) pairs on the drawn part's link a plausible generator reaches.
ON_PART_TARGET = 0.90
#: Touches of a gesture below which its timing is reported but not judged.
MIN_TOUCHES = 5
#: Accepted ratio of a gesture's median duration (sessions / arm study) and of its median paired contact
#: (measured span / planned span).
TIMING_BAND = BANDS["quantile"]
#: Truth-table columns the timing check reads (sessions version 5 on).
TRUTH_COLUMNS = ("touch_start_frame", "touch_frames", "trial_frames", "plan_first_frame", "plan_last_frame")
#: Monte Carlo draws of :func:`cost_sampling_interval` (seeded).
SAMPLING_DRAWS = 20000


def arm_reference(gesture: str) -> tuple[float, float]:
    """The arm study's (median trial duration s, median contact fraction) of ``gesture`` (see module)."""
    trial_s = VR_MEDIAN_TRIAL_FRAMES["arm"][gesture] / VR_FRAME_RATE_HZ
    mean, sd = COST_DURATION_MS[gesture]
    median_s = mean / np.sqrt(1.0 + (sd / mean) ** 2) / 1e3
    return float(trial_s), float(median_s / trial_s)


@functools.lru_cache(maxsize=256)
def _median_quantiles(n: int) -> tuple[float, float]:
    """The 2.5 and 97.5 % quantiles of the median of ``n`` standard normal draws (seeded Monte Carlo)."""
    z = np.random.default_rng([0, n]).standard_normal((SAMPLING_DRAWS, n))
    lo, hi = np.quantile(np.median(z, axis=1), [0.025, 0.975])
    return float(lo), float(hi)


def cost_sampling_interval(gesture: str, n: int) -> tuple[float, float]:
    """The 2.5-97.5 % range of the median of ``n`` contact durations drawn from CoST's lognormal of ``gesture``
    (its mean and SD), over that lognormal's median: where a median of ``n`` touches lies by chance alone."""
    mean, sd = COST_DURATION_MS[gesture]
    sigma = float(np.sqrt(np.log1p((sd / mean) ** 2)))
    lo, hi = _median_quantiles(max(int(n), 1))
    return float(np.exp(sigma * lo)), float(np.exp(sigma * hi))


def _r(x: float, nd: int = 3) -> float | None:
    return None if not np.isfinite(x) else round(float(x), nd)


def plausibility(ds, bc, robot, compliance_mm: float) -> dict:
    """The ``plausibility`` block (see module) of sessions ``ds`` with contacts ``bc`` on ``robot``."""
    truth = ds.truth.reset_index(drop=True)
    li = {n: i for i, n in enumerate(ds.links)}
    part_link = {p.name: li.get(p.link, -1) for p in robot.parts}
    sess = ds.sessions.reset_index(drop=True)
    n_s = len(sess)
    # per session: the link each hand should touch (hand 1 the drawn part, hand 0 the mirrored one or none)
    own = np.full((n_s, 2), -1, dtype=np.int64)
    own[:, 1] = [part_link.get(p, -1) for p in truth["part"]]
    two = truth["two_hands"].to_numpy(bool)
    own[two, 0] = [part_link.get(p, -1) for p in truth.loc[two, "second_part"]]
    fsi = ds.frame_session_index()

    depth_mm = np.asarray(bc.depth_m, dtype=np.float64) * 1e3
    p95 = float(np.percentile(depth_mm, 95)) if depth_mm.size else 0.0
    unit = bc.frame.astype(np.int64) * 2 + bc.hand
    on = bc.link == own[fsi[bc.frame], bc.hand]
    units, inv = np.unique(unit, return_inverse=True)
    all_on = np.ones(units.size, dtype=bool)
    np.logical_and.at(all_on, inv, on)
    share = float(all_on.mean()) if units.size else float("nan")

    # timing: touch window per session; contact span of the drawing hand (1) on any link inside it
    start = sess["start"].to_numpy(np.int64) + truth["touch_start_frame"].to_numpy(np.int64)
    n_touch = truth["touch_frames"].to_numpy(np.int64)
    hit = bc.hand == 1
    f1, s1 = bc.frame[hit], fsi[bc.frame[hit]]
    inside = (f1 >= start[s1]) & (f1 < start[s1] + n_touch[s1])
    span = np.zeros(n_s)
    if inside.any():
        df = pd.DataFrame({"s": s1[inside], "f": f1[inside]}).groupby("s")["f"].agg(["min", "max"])
        span[df.index.to_numpy()] = (df["max"] - df["min"] + 1).to_numpy()
    gestures = {
        str(g): _gesture_timing(str(g), idx, truth, span, float(ds.frame_rate_hz))
        for g, idx in truth.groupby("gesture").indices.items()
    }
    timing_ok = all(v["inside"] for v in gestures.values() if v["judged"])
    lo, hi = TIMING_BAND
    return {
        "compliance_mm": float(compliance_mm),
        "penetration_p95_mm": round(p95, 2),
        "penetration_median_mm": round(float(np.median(depth_mm)), 2) if depth_mm.size else 0.0,
        "penetration_max_mm": round(float(depth_mm.max()), 2) if depth_mm.size else 0.0,
        "penetration_ok": bool(p95 <= compliance_mm + 1e-6),
        "on_drawn_part_share": round(share, 4),
        "on_drawn_part_target": ON_PART_TARGET,
        "on_drawn_part_ok": bool(share >= ON_PART_TARGET),
        "touches_reached_share": round(float((span > 0).mean()), 4) if n_s else float("nan"),
        "timing_band": [lo, hi],
        "timing_judges": "duration_ratio and contact_plan_ratio; contact_fraction_ratio (CoST) is reported",
        "gestures": gestures,
        "timing_ok": bool(timing_ok),
        "ok": bool(p95 <= compliance_mm + 1e-6 and share >= ON_PART_TARGET and timing_ok),
    }


def _gesture_timing(g: str, idx: np.ndarray, truth: pd.DataFrame, span: np.ndarray, fps: float) -> dict:
    """One gesture's timing entry (see module) from its touches ``idx`` (rows of ``truth``) and the drawing hand's
    measured contact ``span`` (frames, per touch)."""
    ref_s, ref_cf = arm_reference(g)
    trial = truth["trial_frames"].to_numpy(np.int64)[idx]
    first = truth["plan_first_frame"].to_numpy(np.int64)[idx]
    plan = np.where(first >= 0, truth["plan_last_frame"].to_numpy(np.int64)[idx] - first + 1, 0)
    sp = span[idx]
    paired = sp[plan > 0] / plan[plan > 0]
    dur = float(np.median(trial / fps))
    cpr = float(np.median(paired)) if paired.size else float("nan")
    cf = float(np.median(sp / trial))
    c_lo, c_hi = cost_sampling_interval(g, idx.size)
    lo, hi = TIMING_BAND
    judged = paired.size >= MIN_TOUCHES
    return {
        "n_touches": int(idx.size),
        "n_reached": int((span[idx] > 0).sum()),
        "duration_s": round(dur, 3),
        "arm_duration_s": round(ref_s, 3),
        "duration_ratio": round(dur / ref_s, 3),
        "planned_contact_s": _r(float(np.median(plan[plan > 0])) / fps) if paired.size else None,
        "contact_s": _r(float(np.median(sp)) / fps),
        "contact_plan_ratio": _r(cpr),
        "contact_fraction": round(cf, 3),
        "arm_contact_fraction": round(ref_cf, 3),
        "contact_fraction_ratio": round(cf / ref_cf, 3),
        "cost_sampling_interval": [round(c_lo, 3), round(c_hi, 3)],
        "judged": judged,
        "inside": bool(lo <= dur / ref_s <= hi and lo <= cpr <= hi),
    }
