"""Config schemas of the session data components (``data`` group) and of the scenario study.

``data=synthetic_sessions`` (:class:`sphri.sessions.synthetic.SyntheticSessions`)
and ``data=sessions`` (:class:`sphri.sessions.format.SessionData`) feed the
scenario study (``python -m sphri.coverage +experiment=scenario_study``), not
the classification chain. :class:`ScenarioStudySchema` holds the study's own
settings (``experiment.scenario_study.*`` in ``conf/experiment/scenario_study.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sphri.config import cross_check, require, require_choice, require_range, store


def _check_sizes(participants: int | None, repetitions: int | None, scenarios: list | None) -> None:
    if participants is not None:
        require_range("data.participants", participants, lo=1)
    if repetitions is not None:
        require_range("data.repetitions", repetitions, lo=1)
    if scenarios is not None:
        require(
            len(scenarios) > 0 and len(set(scenarios)) == len(scenarios),
            "data.scenarios",
            scenarios,
            "a non-empty list of unique scenario names (or null for all)",
        )


@dataclass
class SyntheticSessionsSchema:
    """``data=synthetic_sessions``: built-in synthetic scenario sessions (SYNTHETIC)."""

    _target_: str = "sphri.sessions.synthetic.SyntheticSessions"
    seed: int = 0
    participants: int | None = 12
    repetitions: int | None = 3
    scenarios: list[str] | None = None
    priors: str | None = None
    """The YAML table of assumptions (None: sphri/sessions/scenario_priors.yaml)."""
    frame_rate_hz: float = 30.0
    variability: float = 1.0
    """Spread of the touches' gesture generator (``data=synthetic``'s ``data.variability``:
    1 = calibrated to real people, 0 = interchangeable participants)."""

    def __post_init__(self) -> None:
        require_range("data.seed", self.seed, lo=0)
        _check_sizes(self.participants, self.repetitions, self.scenarios)
        require_range("data.frame_rate_hz", self.frame_rate_hz, lo=5.0, hi=1000.0)
        require_range("data.variability", self.variability, lo=0.0, hi=5.0)


@dataclass
class SessionDataSchema:
    """``data=sessions``: recorded sessions in the session format (``sphri/sessions/format.py``)."""

    _target_: str = "sphri.sessions.format.SessionData"
    root: str | None = None
    participants: int | None = None
    repetitions: int | None = None
    scenarios: list[str] | None = None
    quat_tolerance: float = 1e-3
    duplicates: str = "refuse"
    """Two participant ids with near-identical sessions (a copied folder): refuse, warn (load both) or off."""

    def __post_init__(self) -> None:
        from sphri.data.duplicates import DUPLICATE_POLICIES

        require(
            isinstance(self.root, str) and self.root != "",
            "data.root",
            self.root,
            "set the sessions folder (the one holding sessions.json)",
        )
        _check_sizes(self.participants, self.repetitions, self.scenarios)
        require_range("data.quat_tolerance", self.quat_tolerance, lo=0.0, lo_open=True, hi=0.5)
        require_choice("data.duplicates", self.duplicates, DUPLICATE_POLICIES)


@dataclass
class ScenarioStudySchema:
    """Settings of the whole-body scenario study (``experiment.scenario_study``)."""

    study: str = "scenario_study"
    by: str = "scenario"
    """Session column whose values get their own maps and pairwise SWD tests: scenario, start_position,
    repetition or gesture (the coded episode's predicted gesture)."""
    episode_gap_s: float = 2.0
    """An episode ends after at least this many seconds without contact (the study's rule)."""
    min_episode_frames: int = 2
    """Episodes shorter than this (frames) are ignored as grazes."""
    bandwidth_mm: float = 15.0
    """Gaussian smoothing of the whole-body density (geodesic within links)."""
    spacing_mm: float = 8.0
    """Spacing of the surface elements over the whole robot."""
    n_projections: int = 128
    alpha: float = 0.05
    exact_max: int = 12
    n_permutations: int = 9999
    seed: int = 0
    gesture_regions: list[str] = field(
        default_factory=lambda: ["torso_front_upper", "shoulder_r", "upper_arm_r", "gripper_r"]
    )
    """Body parts the gesture model is trained on (synthetic gesture study, data=synthetic; one chain each)."""
    gesture_res: int = 12
    """Skin resolution (encoder.res) of the gesture model."""
    gesture_repetitions: int = 10
    """Training trials per gesture and participant (participants: data.participants)."""
    reach_floor_height_m: float = 0.3
    """Surface turned to the floor (normal within acos(reach_down_cos) of straight down) below this height (m,
    rest pose) is out of a hand's reach; so is surface buried inside another link. Areas, densities per cm^2 and
    budgets count the reachable surface only (``body_part_area.csv``)."""
    reach_down_cos: float = 0.5
    """... 0.5: within 60 degrees of straight down."""
    budget_cm2: float = 2000.0
    """Placement budget: skin area (cm^2) ..."""
    pitch_mm: float = 0.0
    """... or, when > 0 with budget_taxels, a taxel count at this pitch."""
    budget_taxels: int = 0
    patch_cm2: float = 40.0
    """Skin design (``sphri.sessions.skin``): each body part's reachable surface is split into patches of about
    this area (cm^2); placement, the budget curve and the export work on patches."""
    skin_pitch_mm: float = 10.0
    """Taxel pitch (mm) of the budget curve's taxel axis and of the export's taxel counts (pitch_mm when a taxel
    budget is set)."""
    heldout_splits: int = 10
    """Random halvings of the participants for the held-out budget curve (each half scores the other's choice)."""
    export_format: str = "ply"
    """Mesh format of the patch export (ply or stl), in each link's frame."""
    render: bool = True
    """Draw the figures (false: tables, maps and the report's numbers only)."""
    figure_formats: list[str] = field(default_factory=lambda: ["png"])
    """Files written per figure: PNG; add pdf / svg for print (meshes rasterized inside; they take most of the
    figures' time, so only when asked)."""
    view_faces: int = 20000
    """Faces of the robot mesh drawn in the 3-D views (fewer: faster figures, coarser shading)."""

    def __post_init__(self) -> None:
        key = "experiment.scenario_study"
        require_choice(f"{key}.study", self.study, ["scenario_study"])
        require_choice(f"{key}.by", self.by, ["scenario", "start_position", "repetition", "gesture"])
        require_range(f"{key}.episode_gap_s", self.episode_gap_s, lo=0.0, lo_open=True, hi=60.0)
        require_range(f"{key}.min_episode_frames", self.min_episode_frames, lo=1)
        require_range(f"{key}.bandwidth_mm", self.bandwidth_mm, lo=1.0, hi=500.0)
        require_range(f"{key}.spacing_mm", self.spacing_mm, lo=1.0, hi=100.0)
        require(
            self.spacing_mm <= self.bandwidth_mm,
            f"{key}.spacing_mm",
            self.spacing_mm,
            f"must be <= {key}.bandwidth_mm={self.bandwidth_mm}",
        )
        require_range(f"{key}.n_projections", self.n_projections, lo=1, hi=100_000)
        require_range(f"{key}.alpha", self.alpha, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
        require_range(f"{key}.exact_max", self.exact_max, lo=0, hi=20)
        require_range(f"{key}.n_permutations", self.n_permutations, lo=99)
        require(len(self.gesture_regions) > 0, f"{key}.gesture_regions", self.gesture_regions, "at least one body part")
        require_range(f"{key}.gesture_res", self.gesture_res, lo=1, hi=100)
        require_range(f"{key}.gesture_repetitions", self.gesture_repetitions, lo=1)
        require_range(f"{key}.budget_cm2", self.budget_cm2, lo=0.0, lo_open=True)
        require_range(f"{key}.reach_floor_height_m", self.reach_floor_height_m, lo=0.0, hi=3.0)
        require_range(f"{key}.reach_down_cos", self.reach_down_cos, lo=0.0, hi=1.0)
        require_range(f"{key}.pitch_mm", self.pitch_mm, lo=0.0)
        require_range(f"{key}.budget_taxels", self.budget_taxels, lo=0)
        require(
            len(self.figure_formats) > 0 and set(self.figure_formats) <= {"png", "pdf", "svg"},
            f"{key}.figure_formats",
            self.figure_formats,
            "one or more of png, pdf, svg",
        )
        require_range(f"{key}.patch_cm2", self.patch_cm2, lo=1.0, hi=10_000.0)
        require_range(f"{key}.skin_pitch_mm", self.skin_pitch_mm, lo=0.5, hi=200.0)
        require_range(f"{key}.heldout_splits", self.heldout_splits, lo=0, hi=1000)
        require_choice(f"{key}.export_format", self.export_format, ["ply", "stl"])
        require_range(f"{key}.view_faces", self.view_faces, lo=100, hi=1_000_000)
        require(
            (self.pitch_mm > 0) == (self.budget_taxels > 0),
            f"{key}.budget_taxels",
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
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    from sphri.config import ConfigError

    exp = cfg.get("experiment") if hasattr(cfg, "get") else None
    node = exp.get("scenario_study") if exp is not None and hasattr(exp, "get") else None
    if node is None:
        return None
    try:
        return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(ScenarioStudySchema), node))
    except ConfigError:
        raise
    except OmegaConfBaseException as exc:
        key = getattr(exc, "full_key", None) or ""
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConfigError(f"experiment.scenario_study.{key}: {first}") from None


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
