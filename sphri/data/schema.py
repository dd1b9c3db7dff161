"""Config schemas of the ``data`` group: ``synthetic`` (default) and ``vr_gesture``."""

from __future__ import annotations

from dataclasses import dataclass, field

from sphri.config import require, require_choice, require_range, store
from sphri.data.duplicates import DUPLICATE_POLICIES
from sphri.data.people import Spread
from sphri.inputs import input_path
from sphri.types import GESTURES


def _check_common(seed: int, participants: int | None, repetitions: int | None, regions: list, gestures: list) -> None:
    require_range("data.seed", seed, lo=0)
    if participants is not None:
        require_range("data.participants", participants, lo=1)
    if repetitions is not None:
        require_range("data.repetitions", repetitions, lo=1)
    regions = list(regions)
    require(len(regions) > 0, "data.regions", regions, "at least one skin region, e.g. [arm]")
    require(len(set(regions)) == len(regions), "data.regions", regions, "regions must not repeat")
    require(all(isinstance(r, str) and r for r in regions), "data.regions", regions, "non-empty region names")
    gestures = list(gestures)
    require(len(gestures) > 0, "data.gestures", gestures, f"at least one of {list(GESTURES)}")
    unknown = [g for g in gestures if g not in GESTURES]
    require(not unknown, "data.gestures", gestures, f"unknown {unknown}; allowed: {list(GESTURES)}")
    require(len(set(gestures)) == len(gestures), "data.gestures", gestures, "gestures must not repeat")


#: Position units a recorded dataset may declare (``data.units``), and metres per unit.
POSITION_UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass
class SyntheticDataSchema(Spread):
    """``data=synthetic``: calibrated synthetic gestures (:class:`sphri.data.synthetic.SyntheticData`).

    The variability fields (``variability``, ``length_*``, ``duration_*``,
    ``depth_*``, ...) come from :class:`sphri.data.people.Spread`; each one's
    source is in ``conf/data/synthetic.yaml``.
    """

    _target_: str = "sphri.data.synthetic.SyntheticData"
    seed: int = 0
    participants: int | None = 18
    repetitions: int | None = 20
    regions: list[str] = field(default_factory=lambda: ["arm"])
    gestures: list[str] = field(default_factory=lambda: list(GESTURES))
    root: str | None = None
    frame_rate_hz: float = 30.0
    tracking_rate_hz: float = 30.0
    """Hand-tracking updates per second, jittered 15 % [Q2: Quest hand tracking samples at 30 Hz]."""
    jitter_mm: float = 3.0
    """SD per axis of the tracked hand position per tracking sample (mm) [Q2: 1.1 cm fingertip error, mostly bias]."""
    latency_ms: float = 45.0
    """Delay of the tracked hand behind the real one (ms) [Q2: Abdlkarim et al. 2024, 45 ms]."""
    latency_sd_ms: float = 8.0
    """Sample-to-sample variation of that delay (ms) [assumption]."""
    dropouts_per_trial: float = 0.3
    """Mean number of tracking losses (hand frozen) per trial [assumption]."""
    dropout_max_frames: int = 12
    """A loss lasts 3 to this many frames; the hand jumps to where it is when found [assumption]."""
    jumps_per_trial: float = 0.05
    """Mean number of mis-tracked samples per trial (hand thrown for 1-3 samples) [assumption]."""
    jump_mm: float = 30.0
    """SD per axis of such a jump (mm) [assumption]."""

    def __post_init__(self) -> None:
        _check_common(self.seed, self.participants, self.repetitions, self.regions, self.gestures)
        require(self.root is None, "data.root", self.root, "only data=vr_gesture reads a folder; leave it null here")
        require_range("data.frame_rate_hz", self.frame_rate_hz, lo=1.0, hi=1000.0)
        require_range("data.tracking_rate_hz", self.tracking_rate_hz, lo=1.0, hi=1000.0)
        require_range("data.jitter_mm", self.jitter_mm, lo=0.0, hi=50.0)
        require_range("data.latency_ms", self.latency_ms, lo=0.0, hi=500.0)
        require_range("data.latency_sd_ms", self.latency_sd_ms, lo=0.0, hi=200.0)
        require_range("data.dropouts_per_trial", self.dropouts_per_trial, lo=0.0, hi=10.0)
        require_range("data.dropout_max_frames", self.dropout_max_frames, lo=3, hi=300)
        require_range("data.jumps_per_trial", self.jumps_per_trial, lo=0.0, hi=10.0)
        require_range("data.jump_mm", self.jump_mm, lo=0.0, hi=500.0)
        self.validate("data")


@dataclass
class VRGestureDataSchema:
    """``data=vr_gesture``: the recorded VR gesture dataset (:class:`sphri.data.vr_gesture.VRGestureData`)."""

    _target_: str = "sphri.data.vr_gesture.VRGestureData"
    root: str | None = input_path(None, kind="dir")
    seed: int = 0
    participants: int | None = None
    repetitions: int | None = None
    regions: list[str] = field(default_factory=lambda: ["arm"])
    gestures: list[str] = field(default_factory=lambda: list(GESTURES))
    min_frames: int = 10
    frame_rate_hz: float | None = None
    quat_tolerance: float = 1e-3
    units: str = "m"
    """Units of the pose files' positions: m (the format's), cm or mm (scaled to metres on load)."""
    duplicates: str = "refuse"
    """Two participant ids with near-identical trials (a copied folder): refuse, warn (load both) or off."""

    def __post_init__(self) -> None:
        require(
            isinstance(self.root, str) and self.root != "",
            "data.root",
            self.root,
            "set the dataset folder (the one holding arm/, torso/ and assets/), e.g. data.root=/data/VR-gesture-dataset",
        )
        _check_common(self.seed, self.participants, self.repetitions, self.regions, self.gestures)
        require_range("data.min_frames", self.min_frames, lo=1)
        if self.frame_rate_hz is not None:
            require_range("data.frame_rate_hz", self.frame_rate_hz, lo=1.0, hi=1000.0)
        require_range("data.quat_tolerance", self.quat_tolerance, lo=0.0, lo_open=True, hi=0.5)
        require_choice("data.units", self.units, POSITION_UNITS)
        require_choice("data.duplicates", self.duplicates, DUPLICATE_POLICIES)


store(group="data", name="synthetic_schema", node=SyntheticDataSchema)
store(group="data", name="vr_gesture_schema", node=VRGestureDataSchema)
