"""The stage table: sphri's chain, stated once.

Two tables, read by everything that needs to know the chain's shape:

- :data:`COMPONENTS`: one row per config group a user picks a component for
  (``encoder=ellipse``): the protocol its class must implement, the module
  that registers its schemas, and whether its settings are MLflow params.
  :mod:`sphri.config` (group list, protocol check, schema registration,
  cache-key hashing), ``sphri list`` / ``validate`` and the
  MLflow tracker derive from it.
- :data:`STAGES`: one row per stage the runner caches: the group whose
  component computes it, the stages whose results it reads (their cache keys
  enter its key), whether it is kept on disk, what its cache entry must
  decode into and which module declares its compute. The gesture chain (hand
  to evaluate) and the scenario study's two rows (``sessions``, generated or
  read by the ``data`` component; ``body_contact``, their contacts with every
  link by the ``contact`` component's settings) share this one table and its
  hand and robot rows. :func:`sphri.pipeline.make_pipeline` wires the stages
  from it (the one wiring every caller uses: jobs, streaming, episode coding,
  the scenario study, model export) lazily: a stage is keyed and computed
  only when it, or a stage below it, is asked for, so a gesture job never
  touches the study's rows nor the study the encoder's.
  :meth:`sphri.pipeline.Pipeline.get` refuses a stage that reads a result its
  row does not lead to, so the table and the cache keys cannot drift apart.

Adding a component to an existing group needs no change here (one module,
one YAML). A new stage is a row here plus its compute, a
:class:`sphri.pipeline.StageCompute` in the one registry
:data:`sphri.pipeline.COMPUTE`, declared by the module the row's
``compute_module`` names: :mod:`sphri.pipeline` for the chain's rows,
:mod:`sphri.sessions.labelling` for the study's (above the chain: the runner
imports it by name when such a row is first wired, as :mod:`sphri.config`
imports a component's ``schema_module``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sphri.types import Contacts, CVResult, GestureDataset, Layout, RunMeta, SurfaceMap, WindowPlan


@dataclass(frozen=True)
class Component:
    """A config group whose component the user chooses."""

    group: str
    """Config group (``encoder``), also the command-line spelling (``encoder=ellipse``)."""
    methods: tuple[str, ...]
    """Methods its class must implement (the protocol a plugin is checked against)."""
    schema_module: str
    """Module whose import registers the group's schemas in Hydra's ConfigStore."""
    params: bool = True
    """Its settings are logged as MLflow params and printed by ``cli validate``."""
    result: bool = True
    """Its settings and ``VERSION`` define a job's result (false: how a job is recorded, not what it computes)."""
    per_fit: bool = False
    """Instantiated for each fit with the skin's geometry (a model), not once per chain."""


@dataclass(frozen=True)
class Stage:
    """A cached stage (of the gesture chain or the scenario study)."""

    name: str
    """Stage name (cache folder, log lines, a job's ``time/<name>_s`` in MLflow)."""
    groups: tuple[str, ...]
    """Config groups whose components compute it (their ``VERSION`` enters the key)."""
    inputs: tuple[str, ...] = ()
    """Stages whose results it reads; their keys enter its key."""
    optional: dict[str, tuple[str, bool]] = field(default_factory=dict)
    """Inputs a component may do without: ``{input: (capability attribute, default)}``;
    the input is used when the component's attribute (or the default) is true."""
    persisted: bool = False
    """Kept in the on-disk cache (a cost decision: see :mod:`sphri.pipeline`)."""
    contract: Any = None
    """Type(s) a persisted entry must decode into, else it is recomputed."""
    revision: str = ""
    """Appended to the components' ``VERSION`` in the key: a change of the stage's own compute."""
    compute_module: str = "sphri.pipeline"
    """Module whose import declares the stage's compute in :data:`sphri.pipeline.COMPUTE`."""


#: Config groups of the chain, in stage order.
COMPONENTS: tuple[Component, ...] = (
    Component("data", ("load",), "sphri.data.schema"),
    Component("hand", ("build",), "sphri.hand.schema", params=False),
    Component("robot", ("build",), "sphri.robots.schema"),
    Component("contact", ("compute",), "sphri.contact.schema"),
    Component("surface", ("fit",), "sphri.surface.schema"),
    Component("layout", ("build",), "sphri.layout.schema"),
    Component("encoder", ("encode",), "sphri.encode.schema"),
    Component("noise", ("apply",), "sphri.noise.schema"),
    Component("filter", ("apply",), "sphri.filter.schema"),
    Component("window", ("plan", "assemble"), "sphri.window.schema"),
    Component("model", ("fit", "predict"), "sphri.models.schema", per_fit=True),
    Component("cv", ("run",), "sphri.evaluate.schema"),
    Component("tracking", ("log_job",), "sphri.tracking.schema", params=False, result=False),
)

#: The cached stages, each after its inputs: the gesture chain in the order it computes them, then the study's.
STAGES: tuple[Stage, ...] = (
    Stage("hand", ("hand",)),
    Stage("robot", ("robot",)),
    # synthetic gestures are placed on the robot's surface; a recorded dataset is not
    Stage(
        "data",
        ("data",),
        ("hand", "robot"),
        optional={"robot": ("USES_ROBOT", True)},
        persisted=True,
        contract=GestureDataset,
    ),
    Stage("contact", ("contact",), ("data", "robot", "hand"), persisted=True, contract=Contacts),
    Stage("surface", ("surface",), ("robot",), persisted=True, contract=SurfaceMap),
    # a layout placed by contact density (layout=density without a file) reads the contacts
    Stage(
        "layout",
        ("layout",),
        ("surface", "robot", "contact"),
        optional={"contact": ("uses_contacts", False)},
        persisted=True,
        contract=Layout,
    ),
    Stage("plan", ("window",), ("contact", "data"), persisted=True, contract=WindowPlan),
    Stage("encode", ("encoder",), ("contact", "layout", "plan")),
    Stage("noise", ("noise",), ("encode", "plan")),
    Stage("filter", ("filter",), ("noise",)),
    Stage("evaluate", ("cv", "model"), ("filter", "plan", "layout"), persisted=True, contract=(CVResult, RunMeta)),
    # the scenario study (sphri.sessions): free-interaction sessions, generated or read by the data component
    # (data=synthetic_sessions | sessions), and their contacts with every link of the whole robot
    Stage(
        "sessions",
        ("data",),
        ("hand", "robot"),
        optional={"robot": ("USES_ROBOT", True)},
        persisted=True,
        compute_module="sphri.sessions.labelling",
    ),
    Stage(
        "body_contact",
        ("contact",),
        ("sessions", "robot", "hand"),
        persisted=True,
        revision="wb1",
        compute_module="sphri.sessions.labelling",
    ),
)

#: Config groups of the chain, in stage order (from :data:`COMPONENTS`).
STAGE_GROUPS: tuple[str, ...] = tuple(c.group for c in COMPONENTS)

#: What a component of each group must implement (from :data:`COMPONENTS`).
STAGE_METHODS: dict[str, tuple[str, ...]] = {c.group: c.methods for c in COMPONENTS}

#: Groups whose settings are MLflow params (from :data:`COMPONENTS`).
PARAM_GROUPS: tuple[str, ...] = tuple(c.group for c in COMPONENTS if c.params)

#: Groups whose settings and ``VERSION`` define a job's result (from :data:`COMPONENTS`).
RESULT_GROUPS: tuple[str, ...] = tuple(c.group for c in COMPONENTS if c.result)

#: Groups whose component is instantiated per fit, not once per chain (from :data:`COMPONENTS`).
PER_FIT_GROUPS: frozenset[str] = frozenset(c.group for c in COMPONENTS if c.per_fit)

#: Stages kept on disk, and what their entries must decode into (from :data:`STAGES`; the study's rows have no contract).
PERSISTED: frozenset[str] = frozenset(s.name for s in STAGES if s.persisted)
CONTRACTS: dict[str, Any] = {s.name: s.contract for s in STAGES if s.contract is not None}

STAGE_BY_NAME: dict[str, Stage] = {s.name: s for s in STAGES}


def stage_inputs(stage: Stage, component: Any) -> tuple[str, ...]:
    """The inputs ``stage`` reads when computed by ``component`` (optional ones by its capability flags)."""
    out = []
    for name in stage.inputs:
        if name in stage.optional:
            attr, default = stage.optional[name]
            if not bool(getattr(component, attr, default)):
                continue
        out.append(name)
    return tuple(out)


def upstream(name: str, components: dict[str, Any]) -> frozenset[str]:
    """Every stage whose result ``name`` depends on (its inputs, theirs, ...), for these components."""
    seen: set[str] = set()
    todo = [name]
    while todo:
        stage = STAGE_BY_NAME[todo.pop()]
        for dep in stage_inputs(stage, components.get(stage.groups[0])):
            if dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return frozenset(seen)


def _check_table(stages: tuple[Stage, ...]) -> None:
    groups = set(STAGE_GROUPS)
    names: set[str] = set()
    for s in stages:
        unknown = [g for g in s.groups if g not in groups]
        late = [i for i in s.inputs if i not in names]
        if unknown or late or not set(s.optional) <= set(s.inputs):
            raise AssertionError(f"stage table row {s.name!r}: unknown groups {unknown}, inputs not earlier {late}")
        names.add(s.name)


_check_table(STAGES)
