"""Config schemas of the ``data`` group: ``synthetic`` (default) and ``vr_gesture``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from sphri.config import ComponentSchema, require, setting, store
from sphri.data.duplicates import DUPLICATE_POLICIES
from sphri.data.people import Spread
from sphri.inputs import input_path
from sphri.limits import over_limit
from sphri.types import GESTURES

#: Capsules of the study's hand model and bytes of one capsule pose (xyz + quaternion, float32): the
#: poses of one frame, for the estimate of a synthetic dataset's size.
HAND_CAPSULES = 19
POSE_BYTES = 7 * 4

#: Position units a recorded dataset may declare (``data.units``), and metres per unit.
POSITION_UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass
class DataSchema(ComponentSchema, group="data"):
    """Base of the data group's schemas."""

    if TYPE_CHECKING:
        # Every concrete data schema declares these as dataclass fields; named here for check_common.
        @property
        def regions(self) -> list[str]: ...

        @property
        def gestures(self) -> list[str]: ...

    def check_root(self, hint: str) -> None:
        """A data component that reads files needs its folder (``root``); ``hint`` says which one."""
        root = getattr(self, "root", None)
        require(isinstance(root, str) and root != "", self.key("root"), root, hint)

    def check_common(self) -> None:
        """The checks every data component shares (its selection of trials)."""
        regions = list(self.regions)
        require(len(regions) > 0, self.key("regions"), regions, "at least one skin region, e.g. [arm]")
        require(len(set(regions)) == len(regions), self.key("regions"), regions, "regions must not repeat")
        require(all(isinstance(r, str) and r for r in regions), self.key("regions"), regions, "non-empty region names")
        gestures = list(self.gestures)
        require(len(gestures) > 0, self.key("gestures"), gestures, f"at least one of {list(GESTURES)}")
        unknown = [g for g in gestures if g not in GESTURES]
        require(not unknown, self.key("gestures"), gestures, f"unknown {unknown}; allowed: {list(GESTURES)}")
        require(len(set(gestures)) == len(gestures), self.key("gestures"), gestures, "gestures must not repeat")


@dataclass
class SyntheticDataSchema(Spread, DataSchema):
    """``data=synthetic``: calibrated synthetic gestures (:class:`sphri.data.synthetic.SyntheticData`).

    Calibrated to the VR study's trial lengths (centre AND spread, within and
    between participants), CoST's contact durations and, on a simulated CoST
    sensor, CoST's contact areas (penetration depths,
    ``sphri.data.gestures.DEPTH_M``); ``sphri stats`` prints
    every comparison and flags what falls outside. The variability fields
    (``variability``, ``length_*``, ``duration_*``, ``depth_*``, ...) come
    from :class:`sphri.data.people.Spread`. Each field's docstring names its
    source (``sphri show data=synthetic`` prints them):
    [VR] = the manifests of the VR gesture dataset (Crowder et al.,
    dakaraisc/VR-gesture-dataset 6a08504), arm, all 18 participants,
    measured with ``sphri stats data.root=...``; [CoST] = Jung
    et al. 2017, J. Multimodal User Interfaces 11, Table 4; [Q2] = Abdlkarim
    et al. 2024, Behav. Res. Methods 56:1052-1063 (Meta Quest 2 hand tracking
    against motion capture); [assumption] = no published value, chosen so the
    generator behaves plausibly; change it and rerun the stats.
    """

    _target_: str = "sphri.data.synthetic.SyntheticData"
    seed: int = setting(0, lo=0)
    """Data seed: participant k uses the random streams (seed, k, region)."""
    participants: int | None = setting(18, lo=1, optional=True)
    """Participants participant_01..N (the study had 18; null: 18)."""
    repetitions: int | None = setting(20, lo=1, optional=True)
    """Trials per gesture per participant and region (the study's 20; null: 20)."""
    regions: list[str] = field(default_factory=lambda: ["arm"])
    """Skin regions of the robot to touch (``robot.regions`` keys)."""
    gestures: list[str] = field(default_factory=lambda: list(GESTURES))
    """Gestures to generate."""
    root: str | None = None
    """Unused here (only data=vr_gesture reads a folder): must stay null."""
    frame_rate_hz: float = setting(30.0, lo=1.0, hi=1000.0)
    """Frames per second of the poses (the study's trial lengths count ~30 Hz frames)."""
    tracking_rate_hz: float = setting(30.0, lo=1.0, hi=1000.0)
    """Hand-tracking updates per second, jittered 15 %; each frame holds the latest sample [Q2: Quest hand
    tracking samples at 30 Hz]."""
    jitter_mm: float = setting(3.0, lo=0.0, hi=50.0)
    """SD per axis of the tracked hand position per tracking sample (mm) [Q2: fingertip error 1.1 cm, mostly a
    smooth bias; the sample-to-sample part is taken as a few mm, assumption]."""
    latency_ms: float = setting(45.0, lo=0.0, hi=500.0)
    """Delay of the tracked hand behind the real one (ms) [Q2: Abdlkarim et al. 2024, 45 ms]."""
    latency_sd_ms: float = setting(8.0, lo=0.0, hi=200.0)
    """Sample-to-sample variation of that delay (ms) [assumption]."""
    dropouts_per_trial: float = setting(0.3, lo=0.0, hi=10.0)
    """Mean number of tracking losses (hand frozen) per trial [assumption]."""
    dropout_max_frames: int = setting(12, lo=3, hi=300)
    """A loss lasts 3 to this many frames; the hand jumps to where it is when found [assumption]."""
    jumps_per_trial: float = setting(0.05, lo=0.0, hi=10.0)
    """Mean number of mis-tracked samples per trial (hand thrown for 1-3 samples) [assumption]."""
    jump_mm: float = setting(30.0, lo=0.0, hi=500.0)
    """SD per axis of such a jump (mm) [assumption]."""

    def check(self) -> None:
        self.check_common()
        require(
            self.root is None, self.key("root"), self.root, "only data=vr_gesture reads a folder; leave it null here"
        )
        self.validate("data")
        self.check_size()

    def check_size(self) -> None:
        """Refuse a dataset whose poses alone would not fit in memory (estimated from the study's median
        trial lengths), before it is generated."""
        from sphri.data.reference_stats import VR_MEDIAN_TRIAL_FRAMES

        participants = self.participants or 18
        repetitions = self.repetitions or 20
        per_rep = sum(
            VR_MEDIAN_TRIAL_FRAMES.get(r, VR_MEDIAN_TRIAL_FRAMES["arm"])[g] for r in self.regions for g in self.gestures
        )
        frames = float(participants) * repetitions * per_rep
        why = over_limit(
            f"the poses of {participants} participants x {repetitions} repetitions (about {frames:.3g} frames of "
            f"{HAND_CAPSULES} capsules, before contacts and windows)",
            frames * HAND_CAPSULES * POSE_BYTES,
        )
        require(why is None, self.key("participants"), self.participants, why or "")


@dataclass
class VRGestureDataSchema(DataSchema):
    """``data=vr_gesture``: the recorded VR gesture dataset (:class:`sphri.data.vr_gesture.VRGestureData`)."""

    _target_: str = "sphri.data.vr_gesture.VRGestureData"
    root: str | None = input_path(None, kind="dir")
    """The dataset folder (holds arm/, torso/, assets/); required."""
    seed: int = setting(0, lo=0)
    """Unused for recorded data (kept so that every data component has it)."""
    participants: int | None = setting(None, lo=1, optional=True)
    """The first N participants by id (null: all 18)."""
    repetitions: int | None = setting(None, lo=1, optional=True)
    """At most N trials per gesture per participant and region, by ordinal (null: all)."""
    regions: list[str] = field(default_factory=lambda: ["arm"])
    """Region folders to read; others are never opened."""
    gestures: list[str] = field(default_factory=lambda: list(GESTURES))
    """Gestures to read (rows filtered in the parquet reader)."""
    min_frames: int = setting(10, lo=1)
    """Trials shorter than this (frames) are dropped and counted (the data has 1-frame trials)."""
    frame_rate_hz: float | None = setting(None, lo=1.0, hi=1000.0, optional=True)
    """Frames per second; null: the manifests' frame_rate_hz, else 30 (the study's ~30 Hz tracking)."""
    quat_tolerance: float = setting(1e-3, lo=0.0, lo_open=True, hi=0.5)
    """A quaternion's norm may differ from 1 by this much before it is re-normalized (and counted)."""
    units: str = setting("m", choices=POSITION_UNITS)
    """Units of the pose files' positions: m (the format's), cm or mm (scaled to metres on load)."""
    duplicates: str = setting("refuse", choices=DUPLICATE_POLICIES)
    """Two participant ids with near-identical trials (a copied folder): refuse, warn (load both) or off."""

    def check(self) -> None:
        self.check_root(
            "set the dataset folder (the one holding arm/, torso/ and assets/), e.g. data.root=/data/VR-gesture-dataset"
        )
        self.check_common()


store(group="data", name="synthetic_schema", node=SyntheticDataSchema)
store(group="data", name="vr_gesture_schema", node=VRGestureDataSchema)
