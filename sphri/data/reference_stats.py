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

#: CoST's sensor: cells per side of its square grid, and their pitch (m): 8 x 8 cells, 160 x 160 mm.
COST_CELLS = 8
COST_PITCH_M = 0.020

#: Sensor area of CoST's 8 x 8 grid (160 x 160 mm), square metres.
COST_SENSOR_AREA_M2 = (COST_CELLS * COST_PITCH_M) ** 2

#: CoST Table 4, per gesture: (mean, SD) contact duration in milliseconds and (mean, SD) contact area as a
#: fraction of the 8 x 8 sensor.
_COST_TABLE_4: dict[str, tuple[float, float, float, float]] = {
    "grab": (1373.0, 715.0, 0.59, 0.17),
    "hit": (337.0, 403.0, 0.15, 0.05),
    "pat": (709.0, 753.0, 0.15, 0.07),
    "poke": (650.0, 502.0, 0.08, 0.08),
    "push": (1181.0, 608.0, 0.23, 0.16),
    "rub": (2170.0, 1142.0, 0.21, 0.10),
    "stroke": (1722.0, 829.0, 0.20, 0.08),
    "tap": (564.0, 486.0, 0.12, 0.07),
}

#: CoST's participants: the sample size behind each Table 4 mean and SD (each gave 3 variants x 6 repetitions
#: of every gesture, :data:`COST_CAPTURES_PER_GESTURE` captures, not independent of each other).
COST_PARTICIPANTS = 31
COST_CAPTURES_PER_GESTURE = COST_PARTICIPANTS * 3 * 6

#: How the CoST numbers are cited in code and output.
COST_SOURCE = "CoST: Jung et al. 2017, J. Multimodal User Interfaces 11, Table 4 (31 participants)"

#: CoST Table 4: gesture -> (mean, SD) contact duration in milliseconds.
COST_DURATION_MS: dict[str, tuple[float, float]] = {g: (r[0], r[1]) for g, r in _COST_TABLE_4.items()}

#: CoST Table 4: gesture -> (mean, SD) contact area, fraction of the 8 x 8 sensor.
COST_AREA_FRACTION: dict[str, tuple[float, float]] = {g: (r[2], r[3]) for g, r in _COST_TABLE_4.items()}

#: VR gesture dataset manifests, per gesture: median trial length (frames, rest to rest) on the (arm, torso).
_VR_MEDIANS: dict[str, tuple[float, float]] = {
    "grab": (111.0, 113.0),
    "hit": (96.0, 97.0),
    "pat": (135.0, 131.5),
    "poke": (108.5, 104.5),
    "push": (101.5, 97.5),
    "rub": (143.0, 140.0),
    "stroke": (157.0, 150.5),
    "tap": (119.5, 117.0),
}

#: VR gesture dataset manifests: region -> gesture -> median trial length (frames, rest to rest).
VR_MEDIAN_TRIAL_FRAMES: dict[str, dict[str, float]] = {
    region: {g: medians[i] for g, medians in _VR_MEDIANS.items()} for i, region in enumerate(("arm", "torso"))
}

#: A trial-length spread's statistics (see :mod:`sphri.data.lengths`): per region, then per gesture.
REGION_STATISTICS = (
    "participants",
    "between_var",
    "interaction_var",
    "within_sd",
    "participant_median_min",
    "participant_median_max",
    "max_frames",
)
GESTURE_STATISTICS = ("n", "sd_log", "q05", "q25", "q50", "q75", "q95")

#: VR manifests: region -> its REGION_STATISTICS.
_VR_REGIONS: dict[str, tuple[float, ...]] = {
    "arm": (18, 0.0789, 0.0129, 0.1768, 78.0, 223.0, 2071.0),
    "torso": (17, 0.0765, 0.012, 0.1954, 65.0, 175.0, 1956.0),
}

#: VR manifests: gesture -> its GESTURE_STATISTICS on the (arm, torso).
_VR_GESTURES: dict[str, tuple[tuple[float, ...], tuple[float, ...]]] = {
    "hit": ((360, 0.334, 66.95, 80.0, 96.0, 117.0, 177.7), (340, 0.341, 62.0, 77.75, 97.0, 120.0, 168.0)),
    "pat": ((360, 0.396, 82.0, 108.0, 135.0, 176.0, 289.05), (340, 0.393, 72.0, 101.0, 131.5, 166.25, 246.05)),
    "poke": ((360, 0.335, 69.95, 87.0, 108.5, 135.25, 181.05), (339, 0.344, 67.0, 83.0, 105.0, 131.0, 182.2)),
    "push": ((360, 0.356, 71.0, 83.0, 101.5, 128.0, 221.15), (340, 0.357, 64.9, 80.75, 97.5, 121.0, 188.25)),
    "rub": ((360, 0.352, 90.95, 119.0, 143.0, 171.0, 302.1), (339, 0.355, 81.9, 105.5, 140.0, 168.0, 250.0)),
    "stroke": ((359, 0.481, 83.0, 106.0, 157.0, 201.5, 365.1), (340, 0.44, 71.0, 100.75, 150.5, 195.0, 289.45)),
    "tap": ((360, 0.39, 74.95, 94.0, 119.5, 161.25, 260.2), (340, 0.377, 68.0, 91.75, 117.0, 145.25, 211.15)),
    "grab": ((320, 0.333, 76.95, 92.0, 111.0, 127.25, 206.35), (300, 0.381, 66.95, 90.0, 113.0, 137.25, 200.05)),
}

#: The VR manifests' trial-length spread (``sphri stats`` with the manifests, see
#: :mod:`sphri.data.lengths` for the definitions): region -> statistics, per gesture ``n``, ``sd_log``
#: and quantiles q05..q95 (frames). Trials under 10 frames left out. Copied so stats runs without the files.
VR_LENGTH_SPREAD: dict[str, dict] = {
    region: {
        **dict(zip(REGION_STATISTICS, stats, strict=True)),
        "gestures": {g: dict(zip(GESTURE_STATISTICS, rows[i], strict=True)) for g, rows in _VR_GESTURES.items()},
    }
    for i, (region, stats) in enumerate(_VR_REGIONS.items())
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
