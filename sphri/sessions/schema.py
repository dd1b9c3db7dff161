"""Config schemas of the session data components (``data`` group) and of the scenario study.

``data=synthetic_sessions`` (:class:`sphri.sessions.synthetic.SyntheticSessions`)
and ``data=sessions`` (:class:`sphri.sessions.format.SessionData`) feed the
scenario study (``sphri coverage +experiment=scenario_study``), not
the classification chain. :class:`ScenarioStudySchema` holds the study's own
settings (``experiment.scenario_study.*`` in ``conf/experiment/scenario_study.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from sphri.config import Schema, cross_check, load_schema, require, require_choice, setting, store
from sphri.data.schema import DataSchema
from sphri.figures import valid_formats


def check_scenarios(key: str, scenarios: list[str] | None) -> None:
    """A selection of scenarios: null (all) or a non-empty list of unique names."""
    if scenarios is not None:
        require(
            len(scenarios) > 0 and len(set(scenarios)) == len(scenarios),
            key,
            scenarios,
            "a non-empty list of unique scenario names (or null for all)",
        )


@dataclass
class SyntheticSessionsSchema(DataSchema):
    """``data=synthetic_sessions``: built-in synthetic scenario sessions (SYNTHETIC)."""

    _target_: str = "sphri.sessions.synthetic.SyntheticSessions"
    seed: int = setting(0, lo=0)
    """Participant k's sessions use the random streams (seed, k, scenario, repetition)."""
    participants: int | None = setting(12, lo=1, optional=True)
    """Participants (the study's 12)."""
    repetitions: int | None = setting(3, lo=1, optional=True)
    """Repetitions of each scenario (the study's three)."""
    scenarios: list[str] | None = None
    """Which scenarios of the priors table (null: all five)."""
    priors: str | None = None
    """The YAML table of assumptions (None: sphri/sessions/scenario_priors.yaml)."""
    frame_rate_hz: float = setting(30.0, lo=5.0, hi=1000.0)
    """Frames per second."""
    variability: float = setting(1.0, lo=0.0, hi=5.0)
    """Spread of the touches' gesture generator: hand size, styles, depths (``data=synthetic``'s
    ``data.variability``: 1 = calibrated to real people, 0 = interchangeable participants)."""
    compliance_mm: float = setting(5.0, lo=0.0, hi=30.0)
    """Skin compliance (mm): the deepest a synthetic hand's capsule may press into the touched link; it stays
    clear of every other link."""

    def check(self) -> None:
        check_scenarios(self.key("scenarios"), self.scenarios)


@dataclass
class SessionDataSchema(DataSchema):
    """``data=sessions``: recorded sessions in the session format (``sphri/sessions/format.py``)."""

    _target_: str = "sphri.sessions.format.SessionData"
    root: str | None = None
    """The sessions folder (holds sessions.json); required."""
    participants: int | None = setting(None, lo=1, optional=True)
    """The first N participants (null: all)."""
    repetitions: int | None = setting(None, lo=1, optional=True)
    """Repetitions 1..N (null: all)."""
    scenarios: list[str] | None = None
    """Which scenarios (null: all)."""
    quat_tolerance: float = setting(1e-3, lo=0.0, lo_open=True, hi=0.5)
    """A stored quaternion's norm may differ from 1 by this much."""
    duplicates: str = "refuse"
    """Two participant ids with near-identical sessions (a copied folder): refuse, warn (load both) or off."""

    def check(self) -> None:
        from sphri.data.duplicates import DUPLICATE_POLICIES

        self.check_root("set the sessions folder (the one holding sessions.json)")
        check_scenarios(self.key("scenarios"), self.scenarios)
        require_choice(self.key("duplicates"), self.duplicates, DUPLICATE_POLICIES)


@dataclass
class ScenarioStudySchema(Schema):
    """Settings of the whole-body scenario study (``experiment.scenario_study``)."""

    GROUP: ClassVar[str] = "experiment.scenario_study"

    study: str = setting("scenario_study", choices=["scenario_study"])
    by: str = setting("scenario", choices=["scenario", "start_position", "repetition", "gesture"])
    """Session column whose values get their own maps and pairwise SWD tests: scenario, start_position,
    repetition or gesture (the coded episode's predicted gesture)."""
    episode_gap_s: float = setting(2.0, lo=0.0, lo_open=True, hi=60.0)
    """An episode ends after at least this many seconds without contact (the study's rule)."""
    min_episode_frames: int = setting(2, lo=1)
    """Episodes shorter than this (frames) are ignored as grazes."""
    bandwidth_mm: float = setting(15.0, lo=1.0, hi=500.0)
    """Gaussian smoothing of the whole-body density (geodesic within links)."""
    spacing_mm: float = setting(8.0, lo=1.0, hi=100.0)
    """Spacing of the surface elements over the whole robot."""
    n_projections: int = setting(128, lo=1, hi=100_000)
    alpha: float = setting(0.05, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    exact_max: int = setting(12, lo=0, hi=20)
    n_permutations: int = setting(9999, lo=99)
    seed: int = 0
    gesture_training: str = setting("auto", choices=["auto", "trials", "episodes"])
    """What the gesture model that labels the coded episodes learns from: ``trials``, the synthetic gesture study
    on ``gesture_regions`` (its chain on each part, ``gesture_res``, ``gesture_repetitions``); ``episodes``, the
    study's own coded episodes, each participant's labelled by a model trained on every other participant's
    episodes with the generator's drawn gestures (generated sessions only; :mod:`sphri.sessions.episode_coder`);
    ``auto``: ``episodes`` for generated sessions, ``trials`` for recorded ones."""
    gesture_regions: list[str] = field(
        default_factory=lambda: ["torso_front_upper", "shoulder_r", "upper_arm_r", "gripper_r"]
    )
    """``gesture_training=trials``: body parts the gesture model is trained on (synthetic gesture study,
    data=synthetic; one chain each)."""
    gesture_res: int = setting(12, lo=1, hi=100)
    """Skin resolution (layout.res) of the gesture chain (both ``gesture_training`` modes)."""
    gesture_noise: bool = False
    """Simulate the skin's noise (the ``noise`` config) in the gesture chain that codes the episodes. Off by
    default: the labels describe what the hands did (the reference study coded its sessions from replays, not from
    a skin), and on the full study the chain's 2 % salt-and-pepper noise lowered agreement with the generator from
    52 % to 46 %, which neither filter recovered at this pitch (``outputs/bench/study_gesture_coding.json``)."""
    gesture_repetitions: int = setting(10, lo=1)
    """``gesture_training=trials``: training trials per gesture and participant (participants: data.participants)."""
    reach_floor_height_m: float = setting(0.3, lo=0.0, hi=3.0)
    """Surface turned to the floor (normal within acos(reach_down_cos) of straight down) below this height (m,
    rest pose) is out of a hand's reach; so is surface buried inside another link. Areas, densities per cm^2 and
    budgets count the reachable surface only (``body_part_area.csv``)."""
    reach_down_cos: float = setting(0.5, lo=0.0, hi=1.0)
    """... 0.5: within 60 degrees of straight down."""
    min_diameter_mm: float = setting(30.0, lo=0.0, hi=1000.0)
    """Mountable surface: a body part narrower than this (mm) is a rod no skin is wrapped around. A part's width is
    the median, over 10 mm slices along its longest principal axis, of the larger extent of the slice's cross-section
    (Reachy 2's antennas: about 25 mm; its next narrowest parts, the pedestal bars: about 64 mm). Parts marked
    ``mountable: false`` in the robot's parts (a joint's rotating shell) are left out as well."""
    min_patch_cm2: float = setting(20.0, lo=0.0, hi=10_000.0)
    """Mountable surface: a body part with less reachable area than this (cm^2) is left out; the skin export drops
    connected pieces of a patch smaller than this."""
    budget_cm2: float = setting(2000.0, lo=0.0, lo_open=True)
    """Placement budget: skin area (cm^2) ..."""
    pitch_mm: float = setting(0.0, lo=0.0)
    """... or, when > 0 with budget_taxels, a taxel count at this pitch."""
    budget_taxels: int = setting(0, lo=0)
    patch_cm2: float = setting(40.0, lo=1.0, hi=10_000.0)
    """Skin design (``sphri.sessions.skin``): each body part's reachable surface is split into patches of about
    this area (cm^2); placement, the budget curve and the export work on patches."""
    skin_pitch_mm: float = setting(10.0, lo=0.5, hi=200.0)
    """Taxel pitch (mm) of the budget curve's taxel axis and of the export's taxel counts (pitch_mm when a taxel
    budget is set)."""
    heldout_splits: int = setting(10, lo=0, hi=1000)
    """Random halvings of the participants for the held-out budget curve (each half scores the other's choice)."""
    export_format: str = setting("ply", choices=["ply", "stl"])
    """Mesh format of the patch export (ply or stl), in each link's frame."""
    render: bool = True
    """Draw the figures (false: tables, maps and the report's numbers only)."""
    figure_formats: list[str] = field(default_factory=lambda: ["png"])
    """Files written per figure: PNG; add pdf / svg for print (meshes rasterized inside; they take most of the
    figures' time, so only when asked)."""
    view_faces: int = setting(20000, lo=100, hi=1_000_000)
    """Faces of the robot mesh drawn in the 3-D views (fewer: faster figures, coarser shading)."""
    sensitivity_draws: int = setting(200, lo=0, hi=100_000)
    """Priors sensitivity (generated sessions only; 0: off): draws of perturbed priors (each weight of a scenario's
    parts and gestures, and the odds of two_hands, times a log-uniform factor in the priors table's ``perturb``
    range), the sessions reweighted by importance; Kendall's tau and the top-k overlap of the mountable parts'
    ranking against the unperturbed one (``priors_sensitivity.csv``, ``summary.json``)."""
    sensitivity_top_k: int = setting(5, lo=1, hi=1000)
    """... the k of the top-k overlap."""
    codes: str | None = None
    """Gestures coded by hand (``sphri code``'s ``codes.csv``, filled): used instead of the gesture model's labels
    for the gesture histogram, counts and ``by=gesture`` maps; several coders get Cohen's kappa (null: the model's)."""
    coder: str | None = None
    """Whose codes in ``codes`` the study uses when several people coded (null: the coder of the first row)."""

    def check(self) -> None:
        require(
            self.spacing_mm <= self.bandwidth_mm,
            self.key("spacing_mm"),
            self.spacing_mm,
            f"must be <= experiment.scenario_study.bandwidth_mm={self.bandwidth_mm}",
        )
        require(
            len(self.gesture_regions) > 0, self.key("gesture_regions"), self.gesture_regions, "at least one body part"
        )
        require(
            valid_formats(self.figure_formats),
            self.key("figure_formats"),
            self.figure_formats,
            "one or more of png, pdf, svg",
        )
        require(
            self.coder is None or bool(self.codes), self.key("coder"), self.coder, "needs codes=PATH (a codes file)"
        )
        require(
            (self.pitch_mm > 0) == (self.budget_taxels > 0),
            self.key("budget_taxels"),
            self.budget_taxels,
            "set both pitch_mm and budget_taxels (a taxel budget) or neither (budget_cm2)",
        )

    @property
    def design_pitch_mm(self) -> float:
        """The pitch taxels are counted at: ``pitch_mm`` with a taxel budget, else ``skin_pitch_mm``."""
        return self.pitch_mm if self.budget_taxels > 0 else self.skin_pitch_mm

    @property
    def budget_m2(self) -> float:
        if self.budget_taxels > 0:
            return self.budget_taxels * (self.pitch_mm * 1e-3) ** 2
        return self.budget_cm2 * 1e-4


store(group="data", name="synthetic_sessions_schema", node=SyntheticSessionsSchema)
store(group="data", name="sessions_schema", node=SessionDataSchema)


def study_settings(cfg) -> ScenarioStudySchema | None:
    """The composed config's ``experiment.scenario_study`` settings, checked (None when absent)."""
    exp = cfg.get("experiment") if hasattr(cfg, "get") else None
    node = exp.get("scenario_study") if exp is not None and hasattr(exp, "get") else None
    if node is None:
        return None
    return load_schema(ScenarioStudySchema, node)


@cross_check
def _check_study(cfg) -> None:
    """The scenario study's settings are valid, and it runs on session data and a whole robot."""
    if study_settings(cfg) is None:
        return
    target = str(cfg.data.get("_target_", ""))
    require(
        target.startswith("sphri.sessions."),
        "data",
        target.rsplit(".", 1)[-1],
        "the scenario study reads sessions: data=synthetic_sessions or data=sessions",
    )
    target = str(cfg.robot.get("_target_", ""))
    whole = target.endswith("KinematicRobot") or (
        target.endswith("urdf.UrdfRobot") and cfg.robot.get("parts") is not None
    )
    require(
        whole,
        "robot",
        cfg.robot.get("name"),
        "the scenario study needs a whole robot with a kinematic tree, e.g. robot=reachy2, robot=reachy_full "
        "or robot=urdf robot.path=... robot.parts=...",
    )
