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

#: The VR manifests' trial-length spread (``python -m sphri.data.stats`` with the manifests, see
#: :mod:`sphri.data.lengths` for the definitions): region -> statistics, per gesture ``n``, ``sd_log``
#: and quantiles q05..q95 (frames). Trials under 10 frames left out. Copied so stats runs without the files.
VR_LENGTH_SPREAD: dict[str, dict] = {
    "arm": {
        "participants": 18,
        "between_var": 0.0789,
        "interaction_var": 0.0129,
        "within_sd": 0.1768,
        "participant_median_min": 78.0,
        "participant_median_max": 223.0,
        "max_frames": 2071.0,
        "gestures": {
            "hit": {"n": 360, "sd_log": 0.334, "q05": 66.95, "q25": 80.0, "q50": 96.0, "q75": 117.0, "q95": 177.7},
            "pat": {"n": 360, "sd_log": 0.396, "q05": 82.0, "q25": 108.0, "q50": 135.0, "q75": 176.0, "q95": 289.05},
            "poke": {"n": 360, "sd_log": 0.335, "q05": 69.95, "q25": 87.0, "q50": 108.5, "q75": 135.25, "q95": 181.05},
            "push": {"n": 360, "sd_log": 0.356, "q05": 71.0, "q25": 83.0, "q50": 101.5, "q75": 128.0, "q95": 221.15},
            "rub": {"n": 360, "sd_log": 0.352, "q05": 90.95, "q25": 119.0, "q50": 143.0, "q75": 171.0, "q95": 302.1},
            "stroke": {"n": 359, "sd_log": 0.481, "q05": 83.0, "q25": 106.0, "q50": 157.0, "q75": 201.5, "q95": 365.1},
            "tap": {"n": 360, "sd_log": 0.39, "q05": 74.95, "q25": 94.0, "q50": 119.5, "q75": 161.25, "q95": 260.2},
            "grab": {"n": 320, "sd_log": 0.333, "q05": 76.95, "q25": 92.0, "q50": 111.0, "q75": 127.25, "q95": 206.35},
        },
    },
    "torso": {
        "participants": 17,
        "between_var": 0.0765,
        "interaction_var": 0.012,
        "within_sd": 0.1954,
        "participant_median_min": 65.0,
        "participant_median_max": 175.0,
        "max_frames": 1956.0,
        "gestures": {
            "hit": {"n": 340, "sd_log": 0.341, "q05": 62.0, "q25": 77.75, "q50": 97.0, "q75": 120.0, "q95": 168.0},
            "pat": {"n": 340, "sd_log": 0.393, "q05": 72.0, "q25": 101.0, "q50": 131.5, "q75": 166.25, "q95": 246.05},
            "poke": {"n": 339, "sd_log": 0.344, "q05": 67.0, "q25": 83.0, "q50": 105.0, "q75": 131.0, "q95": 182.2},
            "push": {"n": 340, "sd_log": 0.357, "q05": 64.9, "q25": 80.75, "q50": 97.5, "q75": 121.0, "q95": 188.25},
            "rub": {"n": 339, "sd_log": 0.355, "q05": 81.9, "q25": 105.5, "q50": 140.0, "q75": 168.0, "q95": 250.0},
            "stroke": {"n": 340, "sd_log": 0.44, "q05": 71.0, "q25": 100.75, "q50": 150.5, "q75": 195.0, "q95": 289.45},
            "tap": {"n": 340, "sd_log": 0.377, "q05": 68.0, "q25": 91.75, "q50": 117.0, "q75": 145.25, "q95": 211.15},
            "grab": {"n": 300, "sd_log": 0.381, "q05": 66.95, "q25": 90.0, "q50": 113.0, "q75": 137.25, "q95": 200.05},
        },
    },
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
