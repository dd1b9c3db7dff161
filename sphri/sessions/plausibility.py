"""Plausibility of synthetic sessions' hands against the robot and the arm study (``summary.json``: ``plausibility``).

Three checks of :func:`plausibility`, from the sessions' contact rows (:class:`BodyContacts`) and the generator's
draws (``SessionDataset.truth``):

- **penetration**: the 95th percentile of the contact rows' depth (mm) must not exceed the skin compliance
  (``data.compliance_mm``);
- **on the drawn part**: of the (frame, hand) pairs in contact, the share whose contacts all lie on the link of
  the body part the generator drew for that hand (target :data:`ON_PART_TARGET`);
- **timing**: per gesture, the median touch duration (s, the gesture trial's rest to rest) and the median contact
  fraction (first to last contact frame of the drawing hand over the touch duration) against the arm study's:
  the reference duration is the VR dataset's median arm trial (:data:`VR_MEDIAN_TRIAL_FRAMES`, at
  :data:`VR_FRAME_RATE_HZ`), the reference contact fraction is CoST's median contact duration (lognormal with
  CoST's mean and SD) over it; a ratio is inside when it lies in the trial-length band
  (:data:`sphri.data.lengths.BANDS` ``quantile``). Gestures with fewer than :data:`MIN_TOUCHES` touches are
  reported, not judged.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sphri.data.lengths import BANDS
from sphri.data.reference_stats import COST_DURATION_MS, VR_FRAME_RATE_HZ, VR_MEDIAN_TRIAL_FRAMES

#: Share of contact (frame, hand) pairs on the drawn part's link a plausible generator reaches.
ON_PART_TARGET = 0.90
#: Touches of a gesture below which its timing is reported but not judged.
MIN_TOUCHES = 5
#: Accepted ratio (sessions / arm study) of a gesture's median duration and contact fraction.
TIMING_BAND = BANDS["quantile"]


def arm_reference(gesture: str) -> tuple[float, float]:
    """The arm study's (median trial duration s, median contact fraction) of ``gesture`` (see module)."""
    trial_s = VR_MEDIAN_TRIAL_FRAMES["arm"][gesture] / VR_FRAME_RATE_HZ
    mean, sd = COST_DURATION_MS[gesture]
    median_s = mean / np.sqrt(1.0 + (sd / mean) ** 2) / 1e3
    return float(trial_s), float(median_s / trial_s)


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
    fps = float(ds.frame_rate_hz)
    lo, hi = TIMING_BAND
    gestures = {}
    for g, idx in truth.groupby("gesture").indices.items():
        ref_s, ref_cf = arm_reference(str(g))
        dur = float(np.median(n_touch[idx] / fps))
        cf = float(np.median(span[idx] / n_touch[idx]))
        judged = idx.size >= MIN_TOUCHES
        gestures[str(g)] = {
            "n_touches": int(idx.size),
            "duration_s": round(dur, 3),
            "arm_duration_s": round(ref_s, 3),
            "duration_ratio": round(dur / ref_s, 3),
            "contact_fraction": round(cf, 3),
            "arm_contact_fraction": round(ref_cf, 3),
            "contact_fraction_ratio": round(cf / ref_cf, 3),
            "judged": judged,
            "inside": bool(lo <= dur / ref_s <= hi and lo <= cf / ref_cf <= hi),
        }
    timing_ok = all(v["inside"] for v in gestures.values() if v["judged"])
    return {
        "compliance_mm": float(compliance_mm),
        "penetration_p95_mm": round(p95, 2),
        "penetration_median_mm": round(float(np.median(depth_mm)), 2) if depth_mm.size else 0.0,
        "penetration_max_mm": round(float(depth_mm.max()), 2) if depth_mm.size else 0.0,
        "penetration_ok": bool(p95 <= compliance_mm + 1e-6),
        "on_drawn_part_share": round(share, 4),
        "on_drawn_part_target": ON_PART_TARGET,
        "on_drawn_part_ok": bool(share >= ON_PART_TARGET),
        "timing_band": [lo, hi],
        "gestures": gestures,
        "timing_ok": bool(timing_ok),
        "ok": bool(p95 <= compliance_mm + 1e-6 and share >= ON_PART_TARGET and timing_ok),
    }
