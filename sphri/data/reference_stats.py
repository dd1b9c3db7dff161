"""Published statistics of real social touch that the synthetic generator is calibrated against.

Sources (numbers copied here so sphri runs without the study's files):

- **CoST**: M. M. Jung, M. Poel, R. Poppe, D. K. J. Heylen, "Automatic
  recognition of touch gestures in the corpus of social touch", Journal on
  Multimodal User Interfaces 11 (2017), Table 4 (CC BY 4.0). 31 participants,
  8 x 8 textile pressure grid of 160 x 160 mm (20 mm pitch) at 135 Hz around a
  mannequin forearm. Mean (SD) contact duration in ms (first to last contact,
  repetitions included) and contact area as a fraction of the 8 x 8 sensor.
  CoST calls ``push`` "press".
- **VR**: the manifests of the VR gesture dataset (Crowder, Zhang, Block,
  Yuan, "Requirement-Driven Design of Whole-Body Social Tactile Sensing via
  Virtual Human-Robot Interaction", repository ``dakaraisc/VR-gesture-dataset``
  commit 6a08504): median trial length in frames, whole self-paced trial rest
  to rest, at about 30 Hz tracking; 18 participants, 20 repetitions.

Frame rate. The VR trial lengths only fit CoST's contact durations at about
30 frames per second: at 72 Hz (the headset's rendering rate) a median rub
trial (143 frames) would last 2.0 s rest to rest, shorter than CoST's mean
rub contact alone (2.17 s). The generator therefore runs at
:data:`VR_FRAME_RATE_HZ`.
"""

from __future__ import annotations

#: Sensor area of CoST's 8 x 8 grid (160 x 160 mm), square metres.
COST_SENSOR_AREA_M2 = 0.160 * 0.160

#: CoST Table 4: gesture -> (mean, SD) contact duration in milliseconds.
COST_DURATION_MS: dict[str, tuple[float, float]] = {
    "grab": (1373.0, 715.0),
    "hit": (337.0, 403.0),
    "pat": (709.0, 753.0),
    "poke": (650.0, 502.0),
    "push": (1181.0, 608.0),
    "rub": (2170.0, 1142.0),
    "stroke": (1722.0, 829.0),
    "tap": (564.0, 486.0),
}

#: CoST Table 4: gesture -> (mean, SD) contact area, fraction of the 8 x 8 sensor.
COST_AREA_FRACTION: dict[str, tuple[float, float]] = {
    "grab": (0.59, 0.17),
    "hit": (0.15, 0.05),
    "pat": (0.15, 0.07),
    "poke": (0.08, 0.08),
    "push": (0.23, 0.16),
    "rub": (0.21, 0.10),
    "stroke": (0.20, 0.08),
    "tap": (0.12, 0.07),
}

#: VR gesture dataset manifests: region -> gesture -> median trial length (frames, rest to rest).
VR_MEDIAN_TRIAL_FRAMES: dict[str, dict[str, float]] = {
    "arm": {"grab": 111.0, "hit": 96.0, "pat": 135.0, "poke": 108.5, "push": 101.5, "rub": 143.0, "stroke": 157.0, "tap": 119.5},
    "torso": {"grab": 113.0, "hit": 97.0, "pat": 131.5, "poke": 104.5, "push": 97.5, "rub": 140.0, "stroke": 150.5, "tap": 117.0},
}

#: Frame rate that the VR trial lengths are counted in (Hz); see the module docstring.
VR_FRAME_RATE_HZ = 30.0

#: Calibration tolerances the tests hold the generator to (relative).
DURATION_TOLERANCE = 0.35
TRIAL_LENGTH_TOLERANCE = 0.20


def median_trial_frames(region: str, gesture: str) -> float:
    """Reference median trial length (frames) for a region; regions other than the study's use the arm."""
    table = VR_MEDIAN_TRIAL_FRAMES.get(region, VR_MEDIAN_TRIAL_FRAMES["arm"])
    return table[gesture]
