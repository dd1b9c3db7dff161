"""Configuration: typed schemas, registration, composition and validation.

Schemas live next to their code (``sphri/<stage>/schema.py``), one base per
group (a :class:`ComponentSchema` naming its ``group``) and a subclass per component; each
stage's module calls :func:`store` for its components, which files them as
``schema_<group>_<name>``, apart from the choices. YAML files under ``conf/``
opt into a schema through their defaults list
(``- /schema_encoder_ellipse@_here_``), so a wrong key or type fails at
composition, and hold only what differs from it. Value ranges are field
metadata (:func:`setting`) checked by :class:`Schema`, which :func:`validate`
triggers for every group before any stage runs, re-raising problems as
:class:`ConfigError` naming the key (``<GROUP>.<field>``).
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import importlib
import math
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from sphri import stages as _stages


def _find_conf_dir() -> Path:
    """The config tree: ``conf/`` at the top of a source checkout (editable
    installs read it in place, so edits take effect), else ``sphri/conf``
    inside an installed wheel, where the build copies it (pyproject.toml maps
    the package ``sphri.conf`` onto the repository's ``conf/``)."""
    package = Path(__file__).resolve().parent
    for candidate in (package.parent / "conf", package / "conf"):
        if (candidate / "config.yaml").is_file():
            return candidate
    raise FileNotFoundError(
        f"sphri's config tree (config.yaml) was found neither at {package.parent / 'conf'} (source checkout) "
        f"nor at {package / 'conf'} (installed wheel): reinstall sphri"
    )


CONF_DIR = _find_conf_dir()
"""The config directory: ``conf/`` of the checkout, or the copy inside the installed package."""

# The chain's groups and their protocols are stated once, in sphri.stages.
STAGE_GROUPS = _stages.STAGE_GROUPS
STAGE_METHODS = _stages.STAGE_METHODS

#: Groups that the primary config lists in its defaults; ``+group=x`` on the
#: command line is accepted for these and means ``group=x`` (see
#: :func:`normalize_overrides`).
DEFAULT_GROUPS: tuple[str, ...] = STAGE_GROUPS + ("debug", "experiment", "sensitivity")

#: Modules whose import registers schemas in the ConfigStore (each group's, from
#: :data:`sphri.stages.COMPONENTS`, and the scenario study's).
SCHEMA_MODULES: tuple[str, ...] = tuple(c.schema_module for c in _stages.COMPONENTS) + ("sphri.sessions.schema",)


class ConfigError(ValueError):
    """A configuration value is invalid; the message names the key."""


#: Checks across groups (``fn(cfg)`` raising :class:`ConfigError`), registered
#: by the schema modules with :func:`cross_check`; :func:`validate` runs them.
CROSS_CHECKS: list = []


def cross_check(fn):
    """Register ``fn(cfg)``, a check of how components combine (e.g. encoder and layout)."""
    if fn not in CROSS_CHECKS:
        CROSS_CHECKS.append(fn)
    return fn


def schema_name(group: str, name: str) -> str:
    """The ConfigStore name of a schema: a root-level entry (like ``sphri_root``), not an option of the
    group, so a schema is never a choice nor listed by completion or ``glob(...)`` sweeps
    (``encoder=ellipse`` picks ``conf/encoder/ellipse.yaml``)."""
    return f"schema_{group}_{name}"


def store(group: str, name: str, node: type) -> None:
    """Register a component schema ``node`` as ``schema_<group>_<name>`` (a YAML opts in as the module
    docstring says; ``_target_`` lives in the schema), and the group's base schema (the class of ``node``'s
    bases that sets ``GROUP``) as ``schema_<group>_base``."""
    cs = ConfigStore.instance()
    cs.store(name=schema_name(group, name.removesuffix("_schema")), node=node)
    base = next((c for c in getattr(node, "__mro__", ()) if "GROUP" in vars(c) and c is not Schema), None)
    if base is not None:
        cs.store(name=schema_name(group, "base"), node=base)


def component_node(group: str, name: str, conf_dir: Path | None = None) -> DictConfig:
    """``conf/<group>/<name>.yaml`` merged onto the schema it opts into: one component's settings,
    typed, ``_target_`` included, without composing the whole config (interpolations to the root,
    such as ``${seed}``, stay unresolved)."""
    register_schemas()
    path = (conf_dir or CONF_DIR) / group / f"{name}.yaml"
    raw = OmegaConf.load(path)
    if not isinstance(raw, DictConfig):
        raise ConfigError(f"{path}: a component config must be a mapping of settings, got a list")
    defaults = [str(d) for d in raw.pop("defaults", [])]
    entry = next((d for d in defaults if d.startswith("/schema_")), None)
    if entry is None:
        return raw
    schema = ConfigStore.instance().load(entry[1:].removesuffix("@_here_") + ".yaml").node
    merged = OmegaConf.merge(schema, raw)
    assert isinstance(merged, DictConfig)  # a mapping merged onto a dataclass schema
    return merged


def build(node: DictConfig, **kwargs: Any) -> Any:
    """Instantiate a component from its config node (plain Python containers)."""
    from hydra.utils import instantiate

    return instantiate(node, _convert_="all", **kwargs)


def plain(node: Any) -> Any:
    """Resolved plain-Python copy of a config node (for hashing and logging)."""
    return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node


#: Field metadata key of a setting that cannot change a result (``setting(..., runtime=True)``).
RUNTIME_META = "sphri_runtime"


#: Field metadata key of a setting's range (a :class:`Range`), checked by :class:`Schema`.
RANGE_META = "sphri_range"


@dataclass(frozen=True)
class Range:
    """What values a setting accepts: ``[lo, hi]`` (open ends with ``*_open``, ``None`` unbounded), an
    integer, or one of ``choices``. :meth:`check` raises :class:`ConfigError` naming the key."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple | None = None
    integer: bool = False
    optional: bool = False

    def check(self, key: str, value: Any) -> None:
        if value is None and self.optional:
            return
        bounds = (self.lo, self.hi, self.lo_open, self.hi_open)
        if self.choices is not None:
            require_choice(key, value, self.choices)
        elif not self.integer:
            require_range(key, value, *bounds)
        else:
            try:
                whole = not isinstance(value, bool) and int(value) == value
            except (TypeError, ValueError, OverflowError):
                whole = False
            require(whole and _within(value, *bounds), key, value, f"must be an integer in {_interval(*bounds)}")


def setting(
    default: Any = dataclasses.MISSING,
    *,
    default_factory: Any = dataclasses.MISSING,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
    choices: Iterable[Any] | None = None,
    integer: bool = False,
    optional: bool = False,
    runtime: bool = False,
    range: Range | None = None,
    metadata: dict | None = None,
) -> Any:
    """A schema field with its range as metadata: :class:`Schema` checks it at composition, naming
    the key as ``<GROUP>.<field>`` (the prefix derived from the schema's group, never typed).
    ``optional``: None passes. ``runtime``: a setting that cannot change a job's result (how many
    threads or worker processes, progress display, chunk sizes); it is left out of the config hash and
    of every stage key (:func:`result_config`), so changing it never recomputes a stage or reruns a
    finished job (numbers may still differ at float rounding where a thread count changes the order of
    a reduction: ``docs/RELIABILITY.md`` says where). ``range``: a
    :class:`Range` object shared with a check outside the schema (instead of ``lo``/``hi``/...)."""
    meta = dict(metadata or {})
    if range is not None:
        meta[RANGE_META] = range
    elif any(x is not None for x in (lo, hi, choices)) or integer:
        meta[RANGE_META] = Range(
            lo, hi, lo_open, hi_open, None if choices is None else tuple(choices), integer, optional
        )
    if runtime:
        meta[RUNTIME_META] = True
    if default_factory is not dataclasses.MISSING:
        return field(default_factory=default_factory, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass
class Schema:
    """Base of every schema dataclass (each group's base schema sets ``GROUP``; hardware settings
    leave it empty). ``__post_init__`` checks every field declared with :func:`setting` against its
    range, then :meth:`check` (rules across fields); errors name ``<GROUP>.<field>``."""

    GROUP: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            rng = f.metadata.get(RANGE_META)
            if rng is not None:
                rng.check(self.key(f.name), getattr(self, f.name))
        self.check()

    def check(self) -> None:
        """Checks that involve more than one field (none by default)."""

    @classmethod
    def key(cls, name: str) -> str:
        """The full key of field ``name`` as a user spells it: ``<GROUP>.<name>``."""
        return f"{cls.GROUP}.{name}" if cls.GROUP else name


@dataclass
class ComponentSchema(Schema):
    """Base of a config group's base schema, which names its group as a class keyword
    (``class ContactSchema(ComponentSchema, group="contact")`` sets ``GROUP``): range errors name
    ``<group>.<field>``, :func:`store` files it as ``schema_<group>_base`` and a plugin's YAML may opt
    into it (``defaults: [/schema_<group>_base@_here_, _self_]``), giving its own ``_target_``."""

    _target_: str = "???"

    def __init_subclass__(cls, group: str = "", **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if group:
            cls.GROUP = group


S = TypeVar("S", bound=Schema)


def load_schema(schema: type[S], *nodes: Any) -> S:
    """``schema``'s defaults with ``nodes`` (configs or ``OmegaConf.from_dotlist`` lists) merged on, checked;
    a problem is one :class:`ConfigError` naming ``<GROUP>.<key>``."""
    try:
        return OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(schema), *nodes))  # type: ignore[return-value]
    except ConfigError:
        raise
    except OmegaConfBaseException as exc:
        key = getattr(exc, "full_key", None)
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConfigError(f"{schema.key(key) if key else schema.GROUP}: {first}") from None


def runtime_fields(schema: Any) -> tuple[str, ...]:
    """Names of the fields of the schema dataclass ``schema`` declared with ``setting(..., runtime=True)``."""
    if not (isinstance(schema, type) and dataclasses.is_dataclass(schema)):
        return ()
    return tuple(f.name for f in dataclasses.fields(schema) if f.metadata.get(RUNTIME_META))


#: Root keys of a config that say how a job is run or recorded, not what it computes: left out of the
#: config hash (:func:`sphri.pipeline.config_hash`) and never a reason to tell two jobs' results apart.
NOT_RESULT_KEYS: tuple[str, ...] = ("cache", "output_dir", "resume", "plugins", "hydra", "debug", "experiment")


def runtime_keys() -> frozenset[str]:
    """``<group>.<field>`` of every runtime setting (``setting(..., runtime=True)``) of the registered schemas:
    the MLflow params two jobs may differ in while computing the same result (``cv.progress``, ``model.n_jobs``)."""
    out: set[str] = set()
    for node in _schema_nodes():
        schema = OmegaConf.get_type(node)
        group = getattr(schema, "GROUP", None)
        if isinstance(group, str):
            out.update(f"{group}.{f}" for f in runtime_fields(schema))
    return frozenset(out)


def _schema_nodes(prefix: str = "schema_") -> list[Any]:
    """The nodes of the registered schemas (:func:`store`) whose ConfigStore name starts with ``prefix``."""
    register_schemas()
    repo = ConfigStore.instance().repo
    return [e.node for n, e in repo.items() if isinstance(n, str) and n.startswith(prefix) and hasattr(e, "node")]


def result_neutral(param: str, runtime: frozenset[str] | None = None) -> bool:
    """True for a job param (``<group>.<key>``, a root key, ``run.<key>``) that cannot change a job's result:
    a runtime setting (``runtime``: :func:`runtime_keys`, computed when not given), a group that only records
    the job (``tracking``), a root key of :data:`NOT_RESULT_KEYS`, or where the job ran (``run.device``)."""
    head = param.split(".", 1)[0]
    if head in NOT_RESULT_KEYS or head == "run":
        return True
    if head in _stages.STAGE_GROUPS and head not in _stages.RESULT_GROUPS:
        return True
    return param in (runtime_keys() if runtime is None else runtime)


def result_config(node: Any) -> Any:
    """``plain(node)`` without the fields its schema declares with ``setting(..., runtime=True)``: what a
    stage key and the config hash are made of, so that runtime settings never change either."""
    out = plain(node)
    if isinstance(node, DictConfig) and isinstance(out, dict):
        for name in runtime_fields(OmegaConf.get_type(node)):
            out.pop(name, None)
    return out


def require(ok: bool, key: str, value: Any, expected: str) -> None:
    """Raise :class:`ConfigError` unless ``ok``: ``key=value is invalid: expected``."""
    if not ok:
        raise ConfigError(f"{key}={value!r} is invalid: {expected}")


def require_range(
    key: str,
    value: float,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
) -> None:
    """Check ``lo <= value <= hi`` (open ends with ``*_open``); NaN and +-inf are always refused
    (no physical setting is infinite: an unbounded side is written as ``lo``/``hi`` None)."""
    finite = "a finite number " if isinstance(value, float) and not math.isfinite(value) else ""
    require(
        _within(value, lo, hi, lo_open, hi_open),
        key,
        value,
        f"must be {finite}in {_interval(lo, hi, lo_open, hi_open)}",
    )


def _within(value: Any, lo: float | None, hi: float | None, lo_open: bool, hi_open: bool) -> bool:
    if isinstance(value, float) and not math.isfinite(value):
        return False
    above = lo is None or (value > lo if lo_open else value >= lo)
    below = hi is None or (value < hi if hi_open else value <= hi)
    return bool(above and below)


def _interval(lo: float | None, hi: float | None, lo_open: bool, hi_open: bool) -> str:
    """``[lo, hi]`` as the errors write it: an open or unbounded end in parentheses, unbounded as ``inf``."""
    lb, rb = "(" if lo_open or lo is None else "[", ")" if hi_open or hi is None else "]"
    return f"{lb}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}{rb}"


def require_choice(key: str, value: Any, choices: Iterable[Any]) -> None:
    """Raise :class:`ConfigError` unless ``value`` is one of ``choices``: ``key=value is invalid: allowed values``."""
    choices = list(choices)
    require(value in choices, key, value, f"allowed values: {choices}")


@dataclass
class CacheConfig:
    """On-disk stage cache (``outputs/cache/`` by default)."""

    enabled: bool = True
    dir: str = "outputs/cache"


@dataclass
class RootConfig:
    """Top-level keys of ``conf/config.yaml`` besides the component groups."""

    seed: int = 0
    cache: CacheConfig = field(default_factory=CacheConfig)
    output_dir: str = "outputs"
    """Where runs, the cache and the MLflow store live (relative to cwd)."""
    resume: bool = True
    """In a multirun, skip jobs whose config already has a FINISHED MLflow run."""
    plugins: list[str] = field(default_factory=list)
    """Packages besides ``sphri`` whose classes a config may name as ``_target_``
    (a lab's own encoder, layout or model in its own package, e.g. ``[mylab]``)."""
    data: Any = None
    hand: Any = None
    robot: Any = None
    contact: Any = None
    surface: Any = None
    layout: Any = None
    encoder: Any = None
    noise: Any = None
    filter: Any = None
    window: Any = None
    model: Any = None
    cv: Any = None
    tracking: Any = None
    debug: Any = None
    experiment: Any = None
    variant: str | None = None
    """Name of the assumption variant a job belongs to (set by ``conf/sensitivity/<name>.yaml``; the
    report computes the requirement per variant). None outside a sensitivity study."""


@functools.cache
def register_schemas() -> None:
    """Import every stage's schema module (once per process)."""
    ConfigStore.instance().store(name="sphri_root", node=RootConfig)
    for mod in SCHEMA_MODULES:
        importlib.import_module(mod)


_PLUS_GROUP = re.compile(r"^\+(?P<group>[A-Za-z_][\w/]*)=(?P<value>.*)$")

#: Keys read under their owner's name for one release (deprecated spelling -> the key): ``encoder.res=18``
#: is ``layout.res=18``, in a single run, a sweep (``-m encoder.res=2,4``) and a sweeper's params.
RENAMED_KEYS = {"encoder.res": "layout.res"}
_RENAMED = re.compile(r"^(?P<pre>[+~]*)(?P<key>" + "|".join(re.escape(k) for k in RENAMED_KEYS) + r")(?P<rest>=.*)?$")
_renamed_said: set[str] = set()


def _renamed(override: str) -> str:
    """``override`` with a deprecated key (:data:`RENAMED_KEYS`) spelled as its owner's; the first use of
    each such key in a process prints one line on stderr."""
    m = _RENAMED.match(override)
    if m is None:
        return override
    old, new = m.group("key"), RENAMED_KEYS[m.group("key")]
    if old not in _renamed_said:
        _renamed_said.add(old)
        print(f"sphri: {old} is deprecated, write {new} ({old} is read as {new} for one release)", file=sys.stderr)
    return f"{m.group('pre')}{new}{m.group('rest') or ''}"


def normalize_overrides(overrides: Sequence[str]) -> list[str]:
    """Accept ``+robot=reachy`` as well as ``robot=reachy``, and a deprecated key as its owner's (:data:`RENAMED_KEYS`).

    ``robot`` (like every group of :data:`DEFAULT_GROUPS`) is in the primary defaults list so that plain
    ``python -m sphri`` runs on the built-in robot; Hydra refuses to *append* a group that is already there,
    so ``+group=value`` for such a group is rewritten to ``group=value``. Anything else passes through.
    """
    out = []
    for o in overrides:
        m = _PLUS_GROUP.match(o)
        if m and m.group("group") in DEFAULT_GROUPS:
            out.append(f"{m.group('group')}={m.group('value')}")
        else:
            out.append(_renamed(o))
    return out


def _search_dirs(overrides: Sequence[str]) -> list[Path]:
    """sphri's config folder and the ``file://`` folders a ``hydra.searchpath=[...]`` override adds."""
    dirs = [CONF_DIR]
    for o in overrides:
        key, _, value = o.lstrip("+").partition("=")
        if key == "hydra.searchpath":
            dirs += [Path(m) for m in re.findall(r"file://([^,\]\s'\"]+)", value)]
    return dirs


def check_choices(overrides: Sequence[str]) -> None:
    """Refuse a component choice (``encoder=elipse``) that names no YAML file, with the real options
    and the closest one. Runs before Hydra composes anything."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import Glob

    plain = [o for o in overrides if not o.startswith("-") and "=" in o]
    try:
        parsed = OverridesParser.create().parse_overrides(plain)
    except Exception:  # a malformed override: Hydra's own message names it
        return
    dirs = _search_dirs(overrides)
    for o in parsed:
        group = o.key_or_group
        if group not in DEFAULT_GROUPS or o.is_delete():
            continue
        options = sorted({p.stem for d in dirs for p in (d / group).glob("*.yaml")})
        given = o.value()
        if isinstance(given, Glob):  # glob(...) picks among the options (Hydra needs its loader to expand it)
            values = given.filter(options)
            if not values:
                raise ConfigError(
                    f"{o.input_line} is invalid: the glob matches no {group} option; options: {', '.join(options)}"
                )
            continue
        values = list(o.sweep_string_iterator()) if o.is_sweep_override() else [o.value()]
        for value in values:
            if isinstance(value, str) and value not in options:
                raise ConfigError(
                    f"{group}={value} is invalid: no such {group} option; options: "
                    f"{', '.join(options)}{close_match(value, options)}"
                )


def compose(overrides: Sequence[str] = (), config_name: str = "config", check: bool = True) -> DictConfig:
    """Compose the config outside a Hydra app (CLI, tests, notebooks).

    Raises :class:`ConfigError` with the offending key on any problem. ``check=False`` skips
    :func:`validate` (ranges, cross-component rules, mandatory values): ``cli show`` uses it to
    print the settings of a config that does not run as it stands.

    Hydra composes each distinct set of group choices (and other structural overrides) once per
    process; plain value overrides (``layout.res=18``) are then set on a copy as Hydra sets them
    (:func:`set_values`): see :class:`_ComposeMemo`.
    """
    register_schemas()
    overrides = normalize_overrides(overrides)
    check_choices(overrides)
    try:
        cfg = _MEMO.compose(config_name, overrides)
    except ConfigError:
        raise
    except Exception as exc:  # hydra raises several types; all are config problems
        raise ConfigError(_explain(exc)) from exc
    _check_bool_overrides(cfg, overrides)
    if check:
        validate(cfg)
    return cfg


def compose_with_hydra(config_name: str, overrides: Sequence[str]) -> DictConfig:
    """Hydra's own composition of ``overrides`` (no memo, no sphri checks; Hydra's exceptions)."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    if GlobalHydra.instance().is_initialized():
        GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return hydra_compose(config_name=config_name, overrides=list(overrides), return_hydra_config=False)


class _ComposeMemo:
    """Hydra's compositions by structural overrides, per process: composing is most of a warm
    in-process job (docs/BENCHMARKS.md), and the callers that compose many configs (tests, ``sphri validate``,
    the scenario study, notebooks) mostly change plain values. Hand-written because Hydra has no cache of its
    own across compositions; it uses Hydra's compose API only.

    The key: the structural overrides (:func:`split_overrides`) and what else a composition reads
    (:meth:`sources`; every YAML under the search path's folders counts, so a search path is a config folder).
    The plain overrides are set on a deep copy by :func:`set_values`, so the one-line errors are Hydra's
    (``tests/test_compose_memo.py`` compares both paths, configs and errors).

    ``size``: the compositions kept, least recently used dropped first. A composed config holds about
    0.28 MB (tracemalloc, the default config), so 128 keep at most about 36 MB; 128 rather than 32
    because one process that checks every component (``sphri show``, the tests of every YAML, every
    schema's defaults and every experiment's jobs) composes 114 distinct ones.
    """

    def __init__(self, size: int = 128) -> None:
        self.size = size
        self.bases: dict[tuple, DictConfig] = {}

    def compose(self, config_name: str, overrides: list[str]) -> DictConfig:
        import copy

        split = None if any("pkg://" in o for o in overrides) else self.split(overrides)
        if split is None:  # not parsed here, or files not fingerprinted here: Hydra composes it
            return compose_with_hydra(config_name, overrides)
        structural, plain = split
        key = (config_name, tuple(structural), self.sources(overrides))
        base = self.bases.pop(key, None)
        if base is None:
            base = compose_with_hydra(config_name, structural)
            # a process's first composition stores Hydra's own nodes in the ConfigStore: key it as it is now
            key = (config_name, tuple(structural), self.sources(overrides))
        self.bases[key] = base  # most recently used last
        while len(self.bases) > self.size:
            self.bases.pop(next(iter(self.bases)))
        cfg = copy.deepcopy(base)
        set_values(cfg, plain)
        return cfg

    @staticmethod
    def split(overrides: list[str]) -> tuple[list[str], list[Any]] | None:
        """:func:`split_overrides` with the groups of sphri's search path."""
        dirs = _search_dirs(overrides)
        return split_overrides(overrides, lambda key: _is_group(key, dirs))

    @staticmethod
    def sources(overrides: Sequence[str]) -> tuple:
        """What else a composition reads: each config file (path, size, mtime), the ConfigStore's nodes and,
        for a relative search path, the working directory."""
        dirs = _search_dirs(overrides)
        files = tuple(
            (str(p), st.st_size, st.st_mtime_ns) for d in dirs for p in sorted(d.rglob("*.yaml")) for st in [p.stat()]
        )
        cwd = os.getcwd() if any(not d.is_absolute() for d in dirs) else ""
        return files, _store_nodes(ConfigStore.instance().repo), cwd


def split_overrides(overrides: Sequence[str], is_group: Callable[[str], bool]) -> tuple[list[str], list[Any]] | None:
    """``(structural override strings, plain parsed overrides)``, or None where Hydra's parser refuses one.

    *Plain*: what Hydra applies after the defaults list as a config override, a ``key=value`` change of
    a key that is not a config group (``is_group``), not ``hydra.*``, not a sweep, not a dict value, no
    ``@package``; set them with :func:`set_values`. Everything else is *structural* (Hydra composes it).
    :func:`compose` and the sweeper's job composer (``hydra_plugins/sphri_sweeper``) split with it.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import OverrideType

    try:
        parsed = OverridesParser.create().parse_overrides(list(overrides))
    except Exception:  # noqa: BLE001 - Hydra's composition says what is malformed
        return None
    structural: list[str] = []
    plain: list[Any] = []
    for o in parsed:
        key = o.key_or_group
        if (
            o.type == OverrideType.CHANGE
            and o.package is None
            and not o.is_sweep_override()
            and not key.startswith("hydra")
            and "/" not in key
            and not isinstance(o.value(), dict)
            and not is_group(key)
        ):
            plain.append(o)
        else:
            structural.append(str(o.input_line))
    return structural, plain


def _is_group(key: str, dirs: Sequence[Path]) -> bool:
    """``key`` names a config group (a folder of a search dir, or a group of the ConfigStore)."""
    return isinstance(ConfigStore.instance().repo.get(key), dict) or any((d / key).is_dir() for d in dirs)


def _store_nodes(repo: dict, prefix: str = "") -> tuple:
    """``(path, id of its node)`` of every ConfigStore entry: a node stored again is a new object."""
    out: list = []
    for name, value in repo.items():
        if isinstance(value, dict):
            out += _store_nodes(value, f"{prefix}{name}/")
        else:
            out.append((prefix + name, id(value)))
    return tuple(out)


def set_values(cfg: DictConfig, overrides: Sequence[Any]) -> None:
    """Set plain value overrides as Hydra's ``ConfigLoaderImpl._apply_overrides_to_config`` does (its
    change branch, the same exceptions and messages, so :func:`_explain` says the same line)."""
    from hydra.errors import ConfigCompositionException
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

    for o in overrides:
        try:
            OmegaConf.update(cfg, o.key_or_group, o.value(), merge=True)
        except (ConfigAttributeError, ConfigKeyError) as ex:
            append = f"Could not override '{o.key_or_group}'.\nTo append to your config use +{o.input_line}"
            raise ConfigCompositionException(append) from ex
        except OmegaConfBaseException as ex:
            merging = ConfigCompositionException(f"Error merging override {o.input_line}")
            raise merging.with_traceback(ex.__traceback__) from ex


_MEMO = _ComposeMemo()


def _check_bool_overrides(cfg: DictConfig, overrides: Sequence[str]) -> None:
    """A boolean field given something other than true/false: OmegaConf turns ``encoder.binary=-1``
    (any integer) into True without a word (found by the fuzz campaign, tests/fuzz)."""
    import yaml

    for item in overrides:
        key, sep, text = item.lstrip("+").partition("=")
        if not sep or item.startswith("~") or "(" in text:
            continue
        try:
            value = OmegaConf.select(cfg, key.strip(), throw_on_missing=False)
            given = yaml.safe_load(text)
        except Exception:  # noqa: BLE001 - not a plain key=value: Hydra has judged it already
            continue
        if (
            isinstance(value, bool)
            and isinstance(given, (int, float))
            and not isinstance(given, bool)
            and not (given in (0, 1) and type(given) is int)
        ):
            raise ConfigError(f"{key.strip()}={text} is invalid: must be true or false")


def registered_targets(group: str) -> list[str]:
    """The ``_target_`` classes of sphri's components registered in ``group`` (their schemas in Hydra's
    ConfigStore), sorted."""
    targets = {n.get("_target_") for n in _schema_nodes(schema_name(group, "")) if isinstance(n, DictConfig)}
    return sorted(t for t in targets if isinstance(t, str) and t.startswith("sphri."))


def check_target(group: str, target: Any, plugins: Sequence[str] = ()) -> None:
    """``group._target_`` names a class of ``sphri`` or of a listed plugin package implementing the stage.

    sphri's own targets are not imported here (their schemas already typed
    them); a plugin's class is imported, so that a typo or a missing method
    fails at composition, not deep in a stage.
    """
    if not isinstance(target, str) or not target:
        raise ConfigError(f"{group}._target_={target!r} is invalid: must name a class")
    package = target.split(".", 1)[0]
    if package == "sphri":
        known = registered_targets(group)
        if known and target not in known:
            close = difflib.get_close_matches(target, known, n=1, cutoff=0.6)
            raise ConfigError(
                f"{group}._target_={target!r} is invalid: not a registered {group} component"
                + (f"; did you mean {close[0]!r}?" if close else "")
                + f" (registered: {', '.join(known)}; pick one with {group}=NAME)"
            )
        return
    if package not in plugins:
        raise ConfigError(
            f"{group}._target_={target!r} is invalid: must name a class inside sphri, or of a package "
            f"listed in plugins (e.g. plugins=[{package}] to allow your own components)"
        )
    import inspect

    from hydra.utils import get_class

    try:
        cls = get_class(target)
    except Exception as exc:  # ImportError, AttributeError, or "not a class"
        raise ConfigError(f"{group}._target_={target!r} cannot be imported as a class: {exc}") from None
    missing = [m for m in STAGE_METHODS.get(group, ()) if not callable(getattr(cls, m, None))]
    if not inspect.isclass(cls) or missing:
        raise ConfigError(
            f"{group}._target_={target!r} does not implement the {group} protocol: "
            f"missing {', '.join(missing) or 'a class'} (see docs/ARCHITECTURE.md, 'Your own component')"
        )


def _explain(exc: BaseException) -> str:
    """One line for a composition error: Hydra wraps OmegaConf's error (which names the key) in its
    own multi-line message with a hint that is wrong for typed nodes ("use +model.lr=0.1", which
    sphri refuses too); the key's own error is found in the chain and said as sphri says it."""
    from omegaconf.errors import ConfigAttributeError, ConfigKeyError, ValidationError

    cause: BaseException | None = exc
    while cause is not None and not (isinstance(cause, OmegaConfBaseException) and getattr(cause, "full_key", None)):
        cause = cause.__cause__ or cause.__context__
    if cause is not None:
        key = str(cause.full_key)
        typ = getattr(cause, "object_type", None)
        if isinstance(cause, (ConfigKeyError, ConfigAttributeError)) and dataclasses.is_dataclass(typ):
            names = [f.name for f in dataclasses.fields(typ) if f.name != "_target_"]
            owner = key.rsplit(".", 1)[0] if "." in key else "the top level"
            return (
                f"{key} is not a known key{close_match(key.rsplit('.', 1)[-1], names)}; {owner} has: {', '.join(names)}"
            )
        first = next((ln.strip() for ln in str(cause).splitlines() if ln.strip()), type(cause).__name__)
        if isinstance(cause, ValidationError):
            return f"{key} is invalid: {first}"
        return f"{key}: {first}"
    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()]
    lines = [ln for ln in lines if not ln.startswith("Set the environment variable HYDRA_FULL_ERROR")]
    # keep Hydra's lists of available options, one line
    return " ".join(lines[:20]) if lines else type(exc).__name__


def resolved_setting(cfg: DictConfig, key: str) -> str:
    """``cfg.<key>`` resolved, as text; a :class:`ConfigError` naming the key and its value as written
    when an interpolation in it does not resolve (``${oc.env:NOPE}``: no such environment variable)."""
    try:
        return str(OmegaConf.select(cfg, key, throw_on_missing=True))
    except OmegaConfBaseException as exc:
        raw = OmegaConf.to_container(cfg, resolve=False).get(key)  # type: ignore[union-attr]
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        why = why.replace("KeyError raised while resolving interpolation: ", "").strip('"')
        raise ConfigError(f"{key}={raw} is invalid: {why}") from None


def check_output_dir(
    output_dir: str, key: str = "output_dir", shown: str | None = None, overwrite: bool | None = None
) -> None:
    """``output_dir`` can hold runs, the cache and the MLflow store: not empty (``cache.dir`` would be
    ``/cache``), not an existing file or below one, every name within the file system's limit, and a folder
    not there yet one its nearest existing parent lets be made (probed with an empty folder, removed at
    once; nothing else is created here). ``key``: the setting the errors name (``out`` of ``sphri coverage``),
    ``shown`` the value they quote (default ``output_dir``). ``overwrite``: for a folder written whole (a
    dataset), False refuses a folder that exists and is not empty (new files are never mixed with old ones),
    True lets the writer replace it (:func:`sphri.fsutil.replace_dir`); None (a folder that accumulates) neither."""
    shown = output_dir if shown is None else shown
    if not output_dir.strip():
        raise ConfigError(
            f"{key}='' is invalid: give a folder" + (" (default: outputs)" if key == "output_dir" else "")
        )
    path = Path(output_dir).expanduser()
    try:
        limit = os.pathconf(next((p for p in (path, *path.parents) if p.exists()), Path(".")), "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    long = [part for part in path.parts if len(part.encode()) > limit]
    if long:
        raise ConfigError(
            f"{key} is invalid: the name {long[0][:40]}... is {len(long[0].encode())} bytes long, "
            f"more than this file system's {limit}"
        )
    if path.is_symlink() and not path.exists():  # a folder made there would land wherever the link points
        raise ConfigError(
            f"{key}={shown} is invalid: {path} is a link to {os.readlink(path)}, which does not exist; give a folder"
        )
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                raise ConfigError(f"{key}={shown} is invalid: {p} is a file, not a folder")
            if not os.access(p, os.W_OK | os.X_OK):
                raise ConfigError(f"{key}={shown} is invalid: {p} is read-only; give a writable folder")
            try:  # some file systems (/proc, /sys) refuse new folders although their permissions allow them
                if p != path:
                    os.rmdir(tempfile.mkdtemp(prefix=".sphri-probe-", dir=p))
            except OSError as exc:
                why = f"no folder can be made in {p} ({exc.strerror or exc}); give a writable folder"
                raise ConfigError(f"{key}={shown} is invalid: {why}") from None
            break
    if overwrite is False and path.is_dir() and any(path.iterdir()):
        raise ConfigError(
            f"{key}={shown} is invalid: {path} exists and is not empty (never mixed with new files); "
            "give a new folder, or overwrite=true to replace it whole"
        )


#: What ``output_dir`` holds besides runs, by name: never part of an analysis' ``out`` folder.
MANAGED = {"mlflow.db": "the MLflow store", "mlartifacts": "the MLflow artifacts"}


def check_out_apart(out: str, cfg: DictConfig, key: str = "out") -> None:
    """``out`` (an analysis' folder, every file of which is logged as its MLflow artifacts) must neither be,
    hold nor lie inside ``output_dir``'s MLflow store, artifacts or stage cache (``cache.dir``)."""
    target = Path(out).expanduser().resolve()
    base = Path(str(cfg.output_dir)).expanduser().resolve()
    managed = [(base / name, what) for name, what in MANAGED.items()]
    cache = cfg.get("cache")
    if cache is not None and cache.get("dir"):
        managed.append((Path(str(cache.dir)).expanduser().resolve(), "the stage cache (cache.dir)"))
    for path, what in managed:
        if path == target or target in path.parents:
            raise ConfigError(
                f"{key}={out} is invalid: it holds {path} ({what}), whose files would be logged as this "
                "run's artifacts; give a folder of its own"
            )
        if path in target.parents:
            raise ConfigError(f"{key}={out} is invalid: it lies inside {path} ({what}); give a folder of its own")


def check_output_file(path: str, key: str = "out", overwrite: bool | None = None) -> None:
    """A file to be written at ``path`` (``sphri export out=FILE``): not empty, not an existing folder, its
    folder one :func:`check_output_dir` accepts. Checked before any computing: the write comes last.
    ``overwrite=False``: an existing file is refused (``overwrite=true`` replaces it)."""
    if not path.strip():
        raise ConfigError(f"{key}='' is invalid: give a file name")
    p = Path(path).expanduser()
    if p.is_dir():
        raise ConfigError(f"{key}={path} is invalid: {p} is a folder; give a file name (e.g. {p / 'model.sphrimodel'})")
    if overwrite is False and (p.exists() or p.is_symlink()):
        raise ConfigError(f"{key}={path} is invalid: {p} exists; give another name, or overwrite=true to replace it")
    check_output_dir(str(p.parent), key=key, shown=path)


def validate(cfg: DictConfig) -> None:
    """Check every component's values before any stage runs.

    Instantiating each group's structured node runs its schema's
    ``__post_init__`` range checks. A ``_target_`` must name a class in
    ``sphri`` or in a package listed in ``plugins``; a plugin's class is
    imported and checked against its stage's protocol (:data:`STAGE_METHODS`).
    """
    plugins = tuple(str(p) for p in (cfg.get("plugins") or ()))
    for group in STAGE_GROUPS:
        node = cfg.get(group)
        if node is None:
            raise ConfigError(f"{group}: no component chosen (pick one with {group}=NAME)")
        target = node.get("_target_") if isinstance(node, DictConfig) else None
        check_target(group, target, plugins)
        try:
            OmegaConf.to_object(node)
        except ConfigError as exc:
            msg = str(exc)
            raise ConfigError(msg if msg.startswith(group + ".") else f"{group}.{msg}") from None
        except OmegaConfBaseException as exc:
            raise ConfigError(_explain(exc)) from None
    check_known_keys(cfg)
    if not 0 <= cfg.seed < 2**63:  # seeds reach numba kernels as 64-bit integers
        raise ConfigError(f"seed={cfg.seed} is invalid: must be in [0, 2**63)")
    check_output_dir(resolved_setting(cfg, "output_dir"))
    variant = cfg.get("variant")
    if variant is not None and not re.fullmatch(r"[A-Za-z0-9_.-]+", str(variant)):
        raise ConfigError(f"variant={variant!r} is invalid: a name of letters, digits, '_', '.' or '-'")
    for check in CROSS_CHECKS:
        check(cfg)


def check_inputs(cfg: DictConfig) -> None:
    """Every file and folder a component is configured to read exists: ``cli validate``, each job
    and each job of a sweep call it after :func:`validate`, before any stage starts, so a wrong path
    fails like a wrong value and leaves no half-run (or FAILED MLflow run) behind; then what a schema checks
    in those files (:func:`sphri.inputs.check_contents`: a URDF robot's link names). Not part of
    :func:`validate`, which checks a config on its own (a config may name files made later)."""
    from sphri.inputs import check_contents, missing_inputs

    for group in STAGE_GROUPS:
        missing = missing_inputs(cfg.get(group))
        if missing:
            field, path, kind = missing[0]
            more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
            where = "" if path.parent.is_dir() else f"; its folder {path.parent} does not exist either"
            raise ConfigError(f"{group}.{field}={str(path)!r} is invalid: no such {kind}{where}{more}")
        check_contents(cfg.get(group))


def close_match(word: str, choices: Iterable[str]) -> str:
    """`` (did you mean X?)`` for the closest of ``choices`` to ``word``, or ``""``."""
    best = difflib.get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {best[0]}?)" if best else ""


def check_known_keys(cfg: DictConfig, prefix: str = "") -> None:
    """Refuse keys that no schema declares, e.g. ``+model.n_estimator=5`` or ``+seeed=3``.

    Hydra lets ``+key=value`` add a key even to a structured (typed) node;
    every node typed by a dataclass schema may hold only that schema's
    fields. Untyped nodes (``Any`` fields such as ``debug``) are not checked.
    """
    keys = [k for k in cfg.keys() if prefix or k != "hydra"]  # Hydra's own node (compose with return_hydra_config)
    typ = OmegaConf.get_type(cfg)
    names = [f.name for f in dataclasses.fields(typ)] if dataclasses.is_dataclass(typ) else None
    unknown = next((k for k in keys if names is not None and k not in names), None)
    if names is not None and unknown is not None:
        raise ConfigError(
            f"{prefix}{unknown!s} is not a known key{close_match(str(unknown), names)}; "
            f"{(prefix.rstrip('.') or 'the top level')} has: {', '.join(n for n in names if n != '_target_')}"
        )
    for key in keys:
        node = cfg._get_node(key)
        if isinstance(node, DictConfig) and not node._is_missing() and not node._is_none():
            check_known_keys(node, f"{prefix}{key!s}.")


def field_docs(schema: type) -> dict[str, str]:
    """``{field: docstring}`` of a schema dataclass (the string literal under each field, bases included).

    Python keeps no attribute docstrings at run time, so they are read from the classes' source; a class
    without source (or without docstrings) gives an empty dict for its fields.
    """
    out: dict[str, str] = {}
    for cls in reversed(getattr(schema, "__mro__", (schema,))):
        if dataclasses.is_dataclass(cls):
            out.update(_own_field_docs(cls))
    return out


@functools.cache
def _own_field_docs(cls: type) -> tuple[tuple[str, str], ...]:
    """``(field, docstring)`` pairs written in ``cls``'s own body (not its bases'), read from its source.

    Cached per class object: ``show`` and the verbs' help read the same bases' docstrings for every
    group, and finding a class's source parses its whole module (docs/BENCHMARKS.md says how long)."""
    import ast
    import inspect
    import textwrap

    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return ()
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    return tuple(
        (stmt.target.id, " ".join(nxt.value.value.split()))
        for stmt, nxt in zip(body, body[1:])
        if isinstance(stmt, ast.AnnAssign)
        and isinstance(stmt.target, ast.Name)
        and isinstance(nxt, ast.Expr)
        and isinstance(nxt.value, ast.Constant)
        and isinstance(nxt.value.value, str)
    )


def _component_fields(schema: type) -> list[str]:
    """The settings a component takes: its schema's fields but ``_target_``."""
    return [f.name for f in dataclasses.fields(schema) if f.name != "_target_"]


class Configured:
    """Base of a component whose settings are exactly its schema's fields.

    ``SCHEMA`` (a schema dataclass) holds each setting's default, docstring
    and range check once; ``Component(**settings)`` builds the schema from
    the settings (running its checks, raising :class:`ConfigError` naming
    the key) and sets every field as an attribute of the same name. A
    component that derives more state does so in :meth:`configured`.
    """

    SCHEMA: Any = None

    def __init__(self, **settings: Any) -> None:
        names = _component_fields(self.SCHEMA)
        unknown = sorted(set(settings) - set(names))
        if unknown:
            raise TypeError(f"{type(self).__name__}: unknown setting(s) {unknown}; its settings: {names}")
        values = self.SCHEMA(**settings)
        for name in names:
            setattr(self, name, getattr(values, name))
        self.configured()

    def configured(self) -> None:
        """Hook run after the settings are set (derived state); nothing by default."""

    def __repr__(self) -> str:
        names = _component_fields(self.SCHEMA)
        return f"{type(self).__name__}({', '.join(f'{n}={getattr(self, n)!r}' for n in names)})"
