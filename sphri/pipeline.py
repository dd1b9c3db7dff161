"""The pipeline runner: stages in order, each a pure function of its inputs
and its config subtree, with outputs cached on disk.

Every stage's cache key is known *before* anything runs (it hashes the
stage's config subtree, the keys of its inputs and the component's
``VERSION``), so evaluation is lazy: the runner asks for the final result,
keys it and what it reads, and only computes, or loads, what a missing entry
needs; a stage nothing asks for is not even keyed (a gesture job never wires
the scenario study's rows, the study never the encoder's). Running the same
command twice loads one small entry; changing ``layout.res`` recomputes the
layout, encoder and below, never data or contact.

The stages, their inputs and which are kept on disk are the table in
:mod:`sphri.stages`; how each is computed is :data:`COMPUTE`, once (the
study's rows declared by the module their row names), and
:func:`make_pipeline` is the one wiring every caller uses (jobs, streaming,
episode coding, the scenario study, model export), handing data in memory as
``inputs=`` where it has it (keyed by content, :func:`content_key`). Which stages are kept on disk is a cost decision: data,
contact, surface, layout, the window plan and the evaluation are worth
storing; encoded frames are cheap to recompute and large at fine
resolutions (a res-50 grid is ~0.4 GB per sweep point); the noisy and
filtered windows (``noise``: the encoded frames assembled into per-trial
windows, then noise on every slot; ``filter``: the skin-side temporal filter,
the model's input) are cheaper still.
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from hydra.utils import get_class, instantiate
from omegaconf import DictConfig, OmegaConf

from sphri.cache import StageCache, stage_key
from sphri.config import NOT_RESULT_KEYS, ConfigError, build, result_config
from sphri.finite import require_finite
from sphri.inputs import input_fingerprints, memo_at, memo_for
from sphri.integrity import load_key, stable_hash
from sphri.layout.schema import layout_res
from sphri.stages import (
    PER_FIT_GROUPS,
    RESULT_GROUPS,
    STAGE_BY_NAME,
    STAGE_GROUPS,
    STAGES,
    stage_inputs,
)
from sphri.types import CVResult, FoldRecord, GestureDataset, RunMeta, TaxelGeometry, WindowPlan

log = logging.getLogger(__name__)


@dataclass
class StageRecord:
    """How one stage was obtained in this run."""

    name: str
    key: str
    source: str  # "computed", "cache" or "skipped" (not needed: downstream was cached)
    seconds: float = 0.0


@dataclass
class RunResult:
    """Everything a job reports: the evaluation and where it came from."""

    cv: CVResult
    meta: RunMeta
    """Dataset, robot, resolution (physical units) and window facts."""
    stages: dict[str, StageRecord]
    config_hash: str

    def summary(self) -> dict[str, float]:
        from sphri.evaluate.metrics import summarize

        return summarize(self.cv)


@dataclass
class _Node:
    name: str
    key: str
    compute: Callable[[], Any]
    persist: bool
    path_key: str = ""
    """The key with input files named by path only (finds the entry a changed file replaces)."""
    files: dict[str, str] = field(default_factory=dict)
    """``{path: fingerprint}`` of every file behind this stage, its inputs' included."""
    reads: frozenset[str] = frozenset()
    """Stages this one may read while computing: its inputs and everything upstream of them."""
    value: Any = None
    done: bool = False


@dataclass
class Memo:
    """Stage values shared in memory by the pipelines of one process, by stage key.

    The scenario study wires several chains (its sessions, a gesture chain per region, one per
    coded link) on the same hand and robot: with one memo they are built once.
    """

    stages: frozenset[str] = frozenset({"hand", "robot"})
    """The stages kept (those not stored on disk and costly to rebuild)."""
    values: dict[tuple[str, str], Any] = field(default_factory=dict)


@dataclass
class Pipeline:
    """Lazy graph of the chain's stages for one composed config."""

    cfg: DictConfig
    cache: StageCache
    components: dict[str, Any] = field(default_factory=dict)
    """The built component of each config group."""
    versions: dict[str, str] = field(default_factory=dict)
    """``VERSION`` of each group's component."""
    nodes: dict[str, _Node] = field(default_factory=dict)
    records: dict[str, StageRecord] = field(default_factory=dict)
    link_name: str | None = None
    """The robot link the skin covers, by name (None: the link of the config's one region)."""
    memo: Memo | None = None
    """Stage values shared in memory with other pipelines of the process."""
    fingerprints: dict[str, dict[str, str]] | None = None
    """``{group: {path: fingerprint}}`` of the files its components read; None: no stage is wired from the
    table (only those declared with :meth:`add`)."""
    _upstream_s: list[float] = field(default_factory=list, repr=False)
    """Per stage being computed (a stack): wall seconds its upstream stages took."""
    _computing: list[str] = field(default_factory=list, repr=False)

    # --- what a stage's compute reads besides its inputs (sphri.pipeline.COMPUTE) ---------------------------------

    @property
    def res(self) -> int:
        """The grid resolution the layout is built at."""
        return layout_res(self.cfg)

    @property
    def seed(self) -> int:
        """The run's seed (noise, models, folds)."""
        return int(self.cfg.seed)

    @property
    def region(self) -> str:
        """The skin region the chain evaluates (the link's name when the pipeline was given a link)."""
        return self.link_name if self.link_name is not None else chain_region(self.cfg)

    def link(self) -> Any:
        """The robot link the skin covers."""
        robot = self.get("robot")
        return robot.links[self.link_name] if self.link_name is not None else robot.link_for(self.region)

    def link_key(self) -> dict[str, str]:
        """What names the link in the keys of the stages that read it."""
        return {"link": self.link_name} if self.link_name is not None else {"region": self.region}

    def uses(self, name: str) -> bool:
        """Whether the stage being computed reads stage ``name`` (an optional input its component switched on)."""
        return name in self.nodes[self._computing[-1]].reads

    def key(self, name: str) -> str:
        """The cache key of stage ``name``."""
        return self.node(name).key

    def node(self, name: str) -> _Node:
        """Stage ``name``, wired from its row of :data:`sphri.stages.STAGES` (its inputs first) when first asked
        for: its component built, its key computed; nothing is computed."""
        if name in self.nodes or self.fingerprints is None:
            return self.nodes[name]  # wired already, or declared with add() only
        stage = STAGE_BY_NAME[name]
        for dep in stage_inputs(stage, self.components.get(stage.groups[0])):  # its component's capabilities
            self.node(dep)
        how = compute_of(name)
        config = how.config(self) if how.config else result_config(self.cfg[stage.groups[0]])
        files = {path: fp for g in stage.groups for path, fp in self.fingerprints.get(g, {}).items()}
        self.add(name, config, functools.partial(how.compute, self), how.extra(self) if how.extra else None, files)
        return self.nodes[name]

    def given(self, inputs: dict[str, Any]) -> Pipeline:
        """The same chain with ``inputs`` standing for some of its stages (see :func:`make_pipeline`).

        Stages whose key is unchanged (those not below an input) keep the values this pipeline
        already holds: nothing upstream is loaded or computed twice.
        """
        q = make_pipeline(self.cfg, self.cache, inputs, link=self.link_name, memo=self.memo)
        for name, mine in self.nodes.items():
            node = q.node(name)
            if mine.done and not node.done and mine.key == node.key:
                node.value, node.done = mine.value, True
                q.records[name] = StageRecord(name, node.key, "memory")
        return q

    def give(self, name: str, value: Any) -> str:
        """Stand ``value`` (in memory) for stage ``name``, keyed by its content; returns the key."""
        stage = STAGE_BY_NAME[name]
        if stage.contract is not None and not isinstance(value, stage.contract):
            raise TypeError(f"inputs[{name!r}]: expected {stage.contract}, got {type(value).__name__}")
        key = content_key(name, value)
        self.nodes[name] = _Node(name, key, lambda: value, persist=False, path_key=key, value=value, done=True)
        self.records[name] = StageRecord(name, key, "given")
        return key

    def add(
        self,
        name: str,
        config: Any,
        compute: Callable[[], Any],
        extra: dict[str, Any] | None = None,
        files: dict[str, str] | None = None,
    ) -> str:
        """Declare stage ``name`` of :data:`sphri.stages.STAGES`; returns its cache key.

        Its inputs come from the stage table (their keys enter this key) and
        ``compute`` may read only them and what is upstream of them.
        ``extra``: plain values the key also depends on (a region, a
        version); ``files``: ``{path: fingerprint}`` of the files the stage
        itself reads.
        """
        stage = STAGE_BY_NAME[name]
        used = stage_inputs(stage, self.components.get(stage.groups[0]))
        missing = [n for n in used if n not in self.nodes]
        if missing:
            raise RuntimeError(f"stage {name!r} declared before its inputs {missing} (see sphri.stages.STAGES)")
        inputs = {**{n: self.nodes[n].key for n in used}, **(extra or {})}
        version = "-".join(
            [*(self.versions.get(g, "0") for g in stage.groups), *([stage.revision] if stage.revision else [])]
        )
        files = dict(files or {})
        upstream_nodes = [self.nodes[n] for n in used]
        key = stage_key(name, version, config, {**inputs, **({"files": files} if files else {})})
        path_inputs = {
            **inputs,
            **{n.name: n.path_key for n in upstream_nodes},
            **({"files": sorted(files)} if files else {}),
        }
        path_key = stage_key(name, version, config, path_inputs)
        all_files = {k: v for n in upstream_nodes for k, v in n.files.items()} | files
        reads = frozenset(used).union(*(n.reads for n in upstream_nodes))
        self.nodes[name] = _Node(
            name, key, compute, persist=stage.persisted, path_key=path_key, files=all_files, reads=reads
        )
        return key

    def get(self, name: str) -> Any:
        """The stage's value: computed, or loaded from the cache, once per pipeline.

        Its :class:`StageRecord` holds the stage's exclusive wall seconds: the
        time spent in the upstream stages it asked for is not counted.
        """
        if self._computing and name not in self.nodes[self._computing[-1]].reads:
            raise RuntimeError(
                f"stage {self._computing[-1]!r} read stage {name!r}, which is not among its inputs or upstream of "
                "them in sphri.stages.STAGES: its cache key would not change with it"
            )
        node = self.node(name)
        if node.done:
            return node.value
        memo = self.memo if self.memo is not None and name in self.memo.stages else None
        if memo is not None and (name, node.key) in memo.values:
            node.value, node.done = memo.values[(name, node.key)], True
            self.records[name] = StageRecord(name, node.key, "memory")
            return node.value
        t0 = time.perf_counter()
        self._upstream_s.append(0.0)
        computed: list[bool] = []

        def compute() -> Any:
            from sphri._numba import announce_compiles

            announce_compiles()  # a first run says that it compiles kernels instead of looking stuck
            computed.append(True)
            log.info("stage %-9s computing (key %s)", name, node.key)
            self._computing.append(name)
            try:
                return node.compute()
            finally:
                self._computing.pop()

        try:
            if node.persist:
                node.value = self.cache.get_or_compute(
                    name,
                    node.key,
                    compute,
                    contract=STAGE_BY_NAME[name].contract,
                    files=node.files,
                    path_key=node.path_key,
                )
            else:
                node.value = compute()
        finally:
            total = time.perf_counter() - t0
            dt = max(0.0, total - self._upstream_s.pop())
            if self._upstream_s:
                self._upstream_s[-1] += total
        node.done = True
        if memo is not None:
            memo.values[(name, node.key)] = node.value
        source = "computed" if computed else "cache"
        self.records[name] = StageRecord(name, node.key, source, dt)
        log.info("stage %-9s %s in %.2f s", name, "from cache" if source == "cache" else "computed", dt)
        return node.value


#: Cache folder of the evaluate stage's finished folds (kept until the evaluation itself is stored).
FOLD_STAGE = "evaluate_fold"


@dataclass
class FoldCache:
    """The finished folds of one evaluation in the stage cache: resume by fold.

    Entry ``<cache>/evaluate_fold/<key>.entry`` per fold, ``key`` a hash of
    the evaluate stage's key and the fold's name (the held-out participant),
    holding a :class:`~sphri.types.FoldRecord` (checksummed like every entry;
    a damaged one is recomputed). A job killed after fold k reruns from fold
    k + 1; once the evaluation's own entry is stored the fold entries are
    removed (:func:`run`). The evaluate stage's key and value do not depend
    on them. Picklable: the CV's worker processes save their own folds.
    """

    cache: StageCache
    evaluate_key: str

    def key(self, fold: str) -> str:
        return stage_key(FOLD_STAGE, "1", {"fold": str(fold)}, {"evaluate": self.evaluate_key})

    def load(self, fold: str) -> FoldRecord | None:
        found, value = self.cache.read(FOLD_STAGE, self.key(fold), FoldRecord)
        return value if found else None

    def save(self, record: FoldRecord) -> None:
        from sphri.codec import EncodeError

        try:
            self.cache.write(FOLD_STAGE, self.key(record.result.fold), record)
        except (EncodeError, OSError) as exc:  # a fold not kept costs a recomputation, never the run
            log.warning("cache: fold %s not kept (%s)", record.result.fold, exc)

    def discard(self, folds: list[str]) -> None:
        """Remove the entries of ``folds`` (after the evaluation they make up is stored)."""
        import contextlib

        for fold in folds:
            with contextlib.suppress(OSError):
                self.cache.path(FOLD_STAGE, self.key(fold)).unlink(missing_ok=True)


def _accepts(fn: Callable[..., Any], name: str) -> bool:
    import inspect

    try:
        params = inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


def chain_region(cfg: DictConfig) -> str:
    """The one skin region the classification chain evaluates."""
    if "regions" not in cfg.data:  # session data (data=synthetic_sessions, sessions) has no trials of one region
        raise ConfigError(
            f"data={str(cfg.data._target_).rsplit('.', 1)[-1]} holds free-interaction sessions, not gesture trials: "
            "run the scenario study (sphri coverage +experiment=scenario_study)"
        )
    regions = list(cfg.data.regions)
    if len(regions) != 1:
        raise ConfigError(
            f"data.regions={regions} is invalid: the classification chain runs on one skin region "
            "at a time (e.g. data.regions=[arm]); compare regions with a multirun"
        )
    return regions[0]


@dataclass(frozen=True)
class StageCompute:
    """How one stage of :mod:`sphri.stages` is computed, declared once for every caller's pipeline."""

    compute: Callable[[Pipeline], Any]
    """The stage's value, from the pipeline: ``p.get`` of its inputs, ``p.components``, ``p.res``, ``p.seed``."""
    config: Callable[[Pipeline], Any] | None = None
    """The config its key hashes (default: the runtime-free subtree of the row's first group)."""
    extra: Callable[[Pipeline], dict[str, Any]] | None = None
    """Plain values its key also depends on (a region, a version)."""


def _data(p: Pipeline) -> Any:
    # a component that declares USES_ROBOT = False (a recorded dataset) gets no robot
    return p.components["data"].load(hand=p.get("hand"), robot=p.get("robot") if p.uses("robot") else None)


def _layout(p: Pipeline) -> Any:
    # a layout placed by contact density (layout=density without a file) reads the contacts
    extra = {"contacts": p.get("contact")} if p.uses("contact") else {}
    return p.components["layout"].build(p.link(), p.get("surface"), p.res, **extra)


def _encode(p: Pipeline) -> Any:
    plan: WindowPlan = p.get("plan")
    frames = p.components["encoder"].encode(
        p.get("contact"), p.link(), p.get("surface"), p.get("layout"), plan.selected_frames()
    )
    # a degenerate chart (a zero scale, a collapsed layout) can divide by zero in a float encoder
    require_finite(frames.values, f"encoder={type(p.components['encoder']).__name__} frames")
    return frames


def _noise(p: Pipeline) -> Any:
    # Noise on the windows as the model sees them (padded slots included), seeded per
    # (seed, trial, slot in the window): see sphri.noise.components.apply_to_windows.
    from sphri.noise.components import apply_to_windows

    dataset: GestureDataset = p.get("data")
    windows = p.components["window"].assemble(
        p.get("encode"), p.get("plan"), dataset, p.get("layout"), p.get("surface")
    )
    return apply_to_windows(p.components["noise"], windows, trial_keys(dataset)[windows.trial_row], p.seed)


def model_factory(cfg: DictConfig) -> Callable[..., Any]:
    """The chain's per-fit component: ``model_factory(cfg)(geometry=...)`` is a new, unfitted model
    (the evaluation's folds, model export and the gesture model of the study all make theirs here)."""
    # instantiate() would turn a dataclass argument into a dict: bind it after.
    return instantiate(cfg.model, _partial_=True, _convert_="all")


def _evaluate(p: Pipeline) -> Any:
    cfg, cache = p.cfg, p.cache
    dataset: GestureDataset = p.get("data")
    windows = p.get("filter")
    geometry: TaxelGeometry = windows.geometry

    factory = model_factory(cfg)

    def make_model():
        return factory(geometry=geometry)

    run_cv = p.components["cv"].run
    # finished folds are kept in the cache as they come (a plugin CV without ``resume`` runs as before)
    kw = {"resume": FoldCache(cache, p.key("evaluate"))} if cache.enabled and _accepts(run_cv, "resume") else {}
    result = run_cv(make_model, windows, p.seed, **kw)
    meta = run_meta(cfg, dataset, p.get("robot"), p.region, p.get("surface"), p.get("layout"), windows)
    return result, meta


#: The compute of every stage of :data:`sphri.stages.STAGES`: the one place each is written. The chain's are
#: here; a row whose ``compute_module`` is another module (the scenario study's, :mod:`sphri.sessions.labelling`)
#: is declared there, ``COMPUTE[name] = StageCompute(...)`` at its import (:func:`compute_of` imports it).
COMPUTE: dict[str, StageCompute] = {
    "hand": StageCompute(lambda p: p.components["hand"].build()),
    "robot": StageCompute(lambda p: p.components["robot"].build()),
    "data": StageCompute(_data),
    "contact": StageCompute(lambda p: p.components["contact"].compute(p.get("data"), p.get("robot"))),
    "surface": StageCompute(lambda p: p.components["surface"].fit(p.link()), extra=lambda p: p.link_key()),
    "layout": StageCompute(_layout),
    "plan": StageCompute(lambda p: p.components["window"].plan(p.get("contact"), p.get("data"))),
    "encode": StageCompute(_encode),
    # assembling the windows is the window component's: its version enters the key
    "noise": StageCompute(
        _noise,
        config=lambda p: {"noise": result_config(p.cfg.noise), "seed": p.seed},
        extra=lambda p: {"window": p.versions["window"]},
    ),
    "filter": StageCompute(lambda p: p.components["filter"].apply(p.get("noise"))),
    "evaluate": StageCompute(
        _evaluate,
        config=lambda p: {"model": result_config(p.cfg.model), "cv": result_config(p.cfg.cv), "seed": p.seed},
    ),
}
if set(COMPUTE) != {s.name for s in STAGES if s.compute_module == __name__}:  # pragma: no cover - a row without
    raise AssertionError(f"sphri.pipeline.COMPUTE {sorted(COMPUTE)} != the chain's stages of sphri.stages.STAGES")


def compute_of(name: str) -> StageCompute:
    """How stage ``name`` is computed: :data:`COMPUTE`, after importing the module its row names."""
    if name not in COMPUTE:
        import importlib

        module = STAGE_BY_NAME[name].compute_module
        importlib.import_module(module)  # declares it (a name, not an import: the study is above the chain)
        if name not in COMPUTE:  # pragma: no cover - a row whose module does not declare it
            raise AssertionError(f"stage {name!r}: {module} declares no sphri.pipeline.COMPUTE[{name!r}]")
    return COMPUTE[name]


class _Components(dict):
    """The built component of each config group, built when a stage of its group is first wired (or asked for)."""

    def __init__(self, cfg: DictConfig) -> None:
        super().__init__()
        self.cfg = cfg

    def __missing__(self, group: str) -> Any:
        if group not in _BUILT_GROUPS:
            raise KeyError(group)
        self[group] = component = build(self.cfg[group])
        return component

    def get(self, group: str, default: Any = None) -> Any:
        try:
            return self[group]
        except KeyError:
            return default


#: The groups whose component a pipeline builds (per-fit ones, the model, are built for each fit).
_BUILT_GROUPS = frozenset(g for s in STAGES for g in s.groups if g not in PER_FIT_GROUPS)


def content_key(stage: str, value: Any) -> str:
    """Key of a value handed to a pipeline (``inputs=``): a hash of its content as the cache would store it."""
    import hashlib
    import json

    from sphri.codec import EncodeError, encode

    try:
        tree, arrays = encode(value)
    except EncodeError as exc:
        raise TypeError(f"inputs[{stage!r}]: a {type(value).__name__} cannot be keyed by its content ({exc})") from None
    h = hashlib.blake2b(json.dumps(tree, sort_keys=True, default=str).encode(), digest_size=16)
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
        h.update(a.data if a.size else b"")
    return stage_key(stage, "given", {"content": h.hexdigest()}, {})


def make_pipeline(
    cfg: DictConfig,
    cache: StageCache,
    inputs: dict[str, Any] | None = None,
    *,
    link: str | None = None,
    memo: Memo | None = None,
) -> Pipeline:
    """The stages of :data:`sphri.stages.STAGES` for ``cfg``; nothing is wired until asked for, nothing computed
    until :meth:`Pipeline.get`.

    The one wiring of the table: jobs, sweeps, streaming (:mod:`sphri.hardware.source`), episode
    coding (:mod:`sphri.sessions.gestures`), the scenario study (its ``sessions`` and ``body_contact``)
    and model export all call it. A stage is wired when it, or a stage below it, is first asked for
    (:meth:`Pipeline.node`): a gesture job keys only the chain, the study only its rows.

    ``inputs``: values in memory that stand for stages (``{"data": dataset}``): the stages below them
    are computed by the same code, each keyed by the given value's content (:func:`content_key`),
    and cached like any other. ``link``: the robot link the skin covers, by link name
    (default: the link of the config's one region, ``data.regions``). ``memo``: stage values shared
    in memory with other pipelines of the process (:class:`Memo`).
    """
    inputs = dict(inputs or {})
    names = [s.name for s in STAGES]
    unknown = sorted(set(inputs) - set(names))
    if unknown:
        raise ValueError(f"inputs {unknown} are not stages of the chain {names}")
    p = Pipeline(cfg, cache, components=_Components(cfg), versions=component_versions(cfg), link_name=link, memo=memo)
    p.fingerprints = input_fingerprints(cfg, memo_at(cache.root if cache.enabled else None, cache.key))
    for name in names:
        if name in inputs:
            p.give(name, inputs[name])
    return p


def trial_keys(dataset: GestureDataset) -> np.ndarray:
    """(N,) int64 stable id of each trial: a hash of (participant, region, ordinal).

    Seeds per-trial randomness (noise) so that a trial's noise does not depend
    on which other trials are loaded.
    """
    t = dataset.trials
    keys = [
        int(stable_hash([str(pp), str(rg), int(o)])[:15], 16)
        for pp, rg, o in zip(t["participant"], t["region"], t["trial_ordinal"])
    ]
    return np.asarray(keys, dtype=np.int64)


def run_meta(cfg, dataset, robot, region, surface, layout, windows) -> RunMeta:
    """Facts about the run reported in the summary, MLflow and the report."""
    from sphri.layout.units import describe

    return RunMeta(
        dataset=dataset.name,
        synthetic=bool(dataset.synthetic),
        n_participants=int(dataset.trials["participant"].nunique()),
        n_trials=int(len(dataset.trials)),
        n_frames=int(dataset.n_frames),
        frame_rate_hz=float(dataset.frame_rate_hz),
        repairs=dict(dataset.repairs),
        robot=robot.name,
        region=region,
        link=robot.regions.get(region, region),  # a pipeline given a link (episode coding) names it
        surface=surface.kind,
        surface_fit_residual_mm=float(surface.fit_residual_m * 1e3),
        resolution={**describe(layout, surface), "grid_shape": layout.grid_shape},
        n_windows=int(windows.x.shape[0]),
        n_dropped_no_contact=int(windows.n_dropped),
        window_frames=int(windows.x.shape[1]),
        warnings=participant_warnings(cfg, dataset, windows),
    )


def participant_warnings(cfg, dataset, windows) -> list[str]:
    """Named warnings when the folds cover fewer participants than the data was asked for (also logged)."""
    have = {str(g) for g in np.unique(np.asarray(windows.groups))}
    loaded = sorted(str(p) for p in dataset.trials["participant"].unique())
    empty = int(dataset.repairs.get("participant_without_trials", 0))
    asked = cfg.data.get("participants")
    out = []
    lost = [p for p in loaded if p not in have]
    if lost:
        out.append(
            f"participant(s) {lost} have no window with contact: {cfg.cv.get('_target_', '').rsplit('.', 1)[-1]} "
            f"runs on {len(have)} of {len(loaded) + empty} participants"
        )
    if empty:
        out.append(f"{empty} participant(s) without a usable trial left out by the data stage (named in its log)")
    if asked is not None and len(loaded) + empty < int(asked):
        out.append(f"data.participants={asked} but the data holds {len(loaded) + empty}")
    for w in out:
        log.warning("%s", w)
    return out


def open_cache(cfg: DictConfig) -> StageCache:
    """The stage cache of ``cfg``; a ``cache.dir`` that cannot be written is refused, naming it."""
    if bool(cfg.cache.enabled):
        import os
        import tempfile
        from pathlib import Path

        root = Path(str(cfg.cache.dir))
        try:
            root.mkdir(parents=True, exist_ok=True)
            fd, probe = tempfile.mkstemp(prefix=".write-test.", dir=root)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            raise ConfigError(
                f"cache.dir={str(cfg.cache.dir)!r} cannot be written ({exc.strerror or exc}); "
                "give a writable folder or cache.enabled=false"
            ) from None
    return StageCache(root=cfg.cache.dir, enabled=bool(cfg.cache.enabled))


def run(cfg: DictConfig, cache: StageCache | None = None) -> RunResult:
    """Run the whole chain for a composed, validated config."""
    if cache is None:
        cache = open_cache(cfg)
    p = make_pipeline(cfg, cache)
    cv, meta = p.get("evaluate")
    done = p.records.get("evaluate")
    if cache.enabled and done is not None and done.source == "computed" and cache.path("evaluate", done.key).is_file():
        FoldCache(cache, done.key).discard([f.fold for f in cv.folds])  # the evaluation's entry holds them now
    for stage in STAGES:  # the stages the evaluation's key reads, in table order
        if stage.name in p.nodes and stage.name not in p.records:
            p.records[stage.name] = StageRecord(stage.name, p.nodes[stage.name].key, "skipped")
    cached = [n for n, r in p.records.items() if r.source == "cache"]
    skipped = [n for n, r in p.records.items() if r.source == "skipped"]
    if cached:
        log.info("from cache: %s; not needed: %s", ", ".join(cached), ", ".join(skipped) or "none")
    compiled = _compile_report()
    if compiled:
        log.info(compiled)
    return RunResult(cv=cv, meta=meta, stages=dict(p.records), config_hash=config_hash(cfg))


def _compile_report() -> str | None:
    """How long this process spent compiling numba kernels (None if it loaded them all from cache)."""
    import sys

    if "sphri._numba" not in sys.modules:
        return None
    from sphri._numba import announce_compiles

    a = announce_compiles()
    if not a.kernels:
        return None
    return f"compiled {a.kernels} numba kernels in {a.seconds:.1f} s (once: later runs load them from numba's cache)"


def component_versions(cfg: DictConfig) -> dict[str, str]:
    """``VERSION`` of each stage group's component class (what its results depend on besides config)."""

    out = {}
    for group in STAGE_GROUPS:
        node = cfg.get(group)
        target = node.get("_target_") if isinstance(node, DictConfig) else None
        if group in RESULT_GROUPS and isinstance(target, str):
            out[group] = str(getattr(get_class(target), "VERSION", "0"))
    return out


def config_hash(cfg: DictConfig) -> str:
    """Hash of what defines a job's result: its config (everything but tracking/cache/hydra and the
    runtime settings, ``sphri.config.setting(..., runtime=True)``), the
    ``VERSION`` of every component and the content fingerprints of the files the components read
    (:mod:`sphri.inputs`), so that a sweep resumed after a component or an input file changed reruns its jobs."""

    c = OmegaConf.to_container(cfg, resolve=True)
    assert isinstance(c, dict)  # a DictConfig's container
    not_result = [g for g in STAGE_GROUPS if g not in RESULT_GROUPS]  # tracking: how a job is recorded
    for k in (*not_result, *NOT_RESULT_KEYS):
        c.pop(k, None)
    for group in STAGE_GROUPS:  # runtime settings (threads, workers, progress, chunks) are not the experiment
        if group in c and isinstance(cfg.get(group), DictConfig):
            c[group] = result_config(cfg[group])
    c["_component_versions"] = component_versions(cfg)
    enabled = cfg.get("cache") is not None and bool(cfg.cache.get("enabled", True))
    fingerprints = input_fingerprints(cfg, memo_for(cfg, load_key("cache") if enabled else None))
    if fingerprints:  # the contents of the files the components read (absent: no files, hash unchanged)
        c["_input_files"] = fingerprints
    return stable_hash(c)
