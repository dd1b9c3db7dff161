"""The pipeline runner: stages in order, each a pure function of its inputs
and its config subtree, with outputs cached on disk.

Every stage's cache key is known *before* anything runs (it hashes the
stage's config subtree, the keys of its inputs and the component's
``VERSION``), so evaluation is lazy: the runner asks for the final result
and only computes, or loads, what a missing entry needs. Running the same
command twice loads one small entry; changing ``encoder.res`` recomputes the
layout, encoder and below, never data or contact.

The stages, their inputs and which are kept on disk are the table in
:mod:`sphri.stages`. Which stages are kept on disk is a cost decision: data,
contact, surface, layout, the window plan and the evaluation are worth
storing; encoded frames are cheap to recompute and large at fine
resolutions (a res-50 grid is ~0.4 GB per sweep point); the noisy and
filtered windows (``noise``: the encoded frames assembled into per-trial
windows, then noise on every slot; ``filter``: the skin-side temporal filter,
the model's input) are cheaper still.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from hydra.utils import get_class, instantiate
from omegaconf import DictConfig, OmegaConf

from sphri.cache import StageCache, stable_hash, stage_key
from sphri.config import ConfigError, build, result_config
from sphri.encode.schema import grid_res
from sphri.inputs import input_fingerprints, memo_at
from sphri.stages import CONTRACTS, PERSISTED, STAGE_BY_NAME, STAGE_GROUPS, stage_inputs
from sphri.types import CVResult, FoldRecord, GestureDataset, RunMeta, TaxelGeometry

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
    _upstream_s: list[float] = field(default_factory=list, repr=False)
    """Per stage being computed (a stack): wall seconds its upstream stages took."""
    _computing: list[str] = field(default_factory=list, repr=False)

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
        version = "-".join(self.versions.get(g, "0") for g in stage.groups)
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
            name, key, compute, persist=name in PERSISTED, path_key=path_key, files=all_files, reads=reads
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
        node = self.nodes[name]
        if node.done:
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
                    name, node.key, compute, contract=CONTRACTS.get(name), files=node.files, path_key=node.path_key
                )
            else:
                node.value = compute()
        finally:
            total = time.perf_counter() - t0
            dt = max(0.0, total - self._upstream_s.pop())
            if self._upstream_s:
                self._upstream_s[-1] += total
        node.done = True
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
            "run the scenario study (python -m sphri.coverage +experiment=scenario_study)"
        )
    regions = list(cfg.data.regions)
    if len(regions) != 1:
        raise ConfigError(
            f"data.regions={regions} is invalid: the classification chain runs on one skin region "
            "at a time (e.g. data.regions=[arm]); compare regions with a multirun"
        )
    return regions[0]


def make_pipeline(cfg: DictConfig, cache: StageCache) -> Pipeline:
    """Wire the stages for ``cfg``; nothing is computed until :meth:`Pipeline.get`."""
    region = chain_region(cfg)
    groups = [g for g in STAGE_GROUPS if g != "tracking"]
    p = Pipeline(
        cfg, cache, components={g: build(cfg[g]) for g in groups if g != "model"}, versions=component_versions(cfg)
    )
    comp = p.components
    res = grid_res(cfg)
    seed = int(cfg.seed)
    fingerprints = input_fingerprints(cfg, memo_at(cache.root if cache.enabled else None))

    def files(*groups: str) -> dict[str, str]:
        """Fingerprints of the files the components of ``groups`` read."""
        return {path: fp for g in groups for path, fp in fingerprints.get(g, {}).items()}

    def link():
        return p.get("robot").link_for(region)

    p.add("hand", result_config(cfg.hand), lambda: comp["hand"].build(), files=files("hand"))
    p.add("robot", result_config(cfg.robot), lambda: comp["robot"].build(), files=files("robot"))

    def data():
        # a component that declares USES_ROBOT = False (a recorded dataset) gets no robot
        robot = p.get("robot") if "robot" in p.nodes["data"].reads else None
        return comp["data"].load(hand=p.get("hand"), robot=robot)

    p.add("data", result_config(cfg.data), data, files=files("data"))
    p.add(
        "contact",
        result_config(cfg.contact),
        lambda: comp["contact"].compute(p.get("data"), p.get("robot")),
        files=files("contact"),
    )
    p.add(
        "surface",
        result_config(cfg.surface),
        lambda: comp["surface"].fit(link()),
        extra={"region": region},
        files=files("surface"),
    )

    def layout():
        extra = {"contacts": p.get("contact")} if "contact" in p.nodes["layout"].reads else {}
        return comp["layout"].build(link(), p.get("surface"), res, **extra)

    p.add("layout", {"layout": result_config(cfg.layout), "res": res}, layout, files=files("layout"))
    p.add(
        "plan",
        result_config(cfg.window),
        lambda: comp["window"].plan(p.get("contact"), p.get("data")),
        files=files("window"),
    )

    def encode():
        return comp["encoder"].encode(
            p.get("contact"), link(), p.get("surface"), p.get("layout"), p.get("plan").selected_frames()
        )

    p.add("encode", result_config(cfg.encoder), encode, files=files("encoder"))

    def noise():
        # Noise on the windows as the model sees them (padded slots included), seeded per
        # (seed, trial, slot in the window): see sphri.noise.components.apply_to_windows.
        from sphri.noise.components import apply_to_windows

        dataset: GestureDataset = p.get("data")
        windows = comp["window"].assemble(p.get("encode"), p.get("plan"), dataset, p.get("layout"), p.get("surface"))
        return apply_to_windows(comp["noise"], windows, trial_keys(dataset)[windows.trial_row], seed)

    # assembling the windows is the window component's: its version enters the key
    p.add(
        "noise",
        {"noise": result_config(cfg.noise), "seed": seed},
        noise,
        extra={"window": p.versions["window"]},
        files=files("noise"),
    )
    p.add("filter", result_config(cfg.filter), lambda: comp["filter"].apply(p.get("noise")), files=files("filter"))

    def evaluate():
        dataset: GestureDataset = p.get("data")
        windows = p.get("filter")
        geometry: TaxelGeometry = windows.geometry

        # instantiate() would turn a dataclass argument into a dict: bind it after.
        model_factory = instantiate(cfg.model, _partial_=True, _convert_="all")

        def make_model():
            return model_factory(geometry=geometry)

        run_cv = comp["cv"].run
        # finished folds are kept in the cache as they come (a plugin CV without ``resume`` runs as before)
        kw = (
            {"resume": FoldCache(cache, p.nodes["evaluate"].key)}
            if cache.enabled and _accepts(run_cv, "resume")
            else {}
        )
        result = run_cv(make_model, windows, seed, **kw)
        return result, run_meta(cfg, dataset, p.get("robot"), region, p.get("surface"), p.get("layout"), windows)

    p.add(
        "evaluate",
        {"model": result_config(cfg.model), "cv": result_config(cfg.cv), "seed": seed},
        evaluate,
        files=files("model", "cv"),
    )
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
        link=robot.regions[region],
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
    for name, node in p.nodes.items():
        if name not in p.records:
            p.records[name] = StageRecord(name, node.key, "skipped")
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
        if group != "tracking" and isinstance(target, str):
            out[group] = str(getattr(get_class(target), "VERSION", "0"))
    return out


def config_hash(cfg: DictConfig) -> str:
    """Hash of what defines a job's result: its config (everything but tracking/cache/hydra and the
    runtime settings, :func:`sphri.config.runtime_setting`), the
    ``VERSION`` of every component and the content fingerprints of the files the components read
    (:mod:`sphri.inputs`), so that a sweep resumed after a component or an input file changed reruns its jobs."""

    c = OmegaConf.to_container(cfg, resolve=True)
    for k in ("tracking", "cache", "output_dir", "resume", "plugins", "hydra", "debug", "experiment"):
        c.pop(k, None)
    for group in STAGE_GROUPS:  # runtime settings (threads, workers, progress, chunks) are not the experiment
        if group in c and isinstance(cfg.get(group), DictConfig):
            c[group] = result_config(cfg[group])
    c["_component_versions"] = component_versions(cfg)
    fingerprints = input_fingerprints(cfg)
    if fingerprints:  # the contents of the files the components read (absent: no files, hash unchanged)
        c["_input_files"] = fingerprints
    return stable_hash(c)
