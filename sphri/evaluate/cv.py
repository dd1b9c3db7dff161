"""Cross-validation of gesture models: leave-one-subject-out and within-subject k-fold.

``instantiate(cfg.cv).run(make_model, windows, seed) -> CVResult``, where
``make_model()`` returns a fresh, unfitted sklearn-like estimator for every
fold. Models see only the training side of a fold: ``fit(x[train],
y[train], groups=groups[train])`` (``groups`` when ``fit`` accepts it, so
that early stopping or tuning splits training participants), then
``predict(x[test])``. A model whose ``transform`` is a fixed per-trial
function (class attribute ``TRANSFORM_PER_TRIAL = True``, e.g. the Random
Forest's features) has it computed once for all trials; each fold then calls
``fit_features`` / ``predict_features`` on its rows of the result, which
cannot leak across folds since nothing in the transform is fitted.
Folds run one after another or in ``workers``
processes (loky), each limited to its share of the cores (BLAS/OpenMP via
threadpoolctl, torch threads, and the model's ``n_jobs``/``threads``).
With ``backend="ray"`` every fold is a Ray task instead (``ray.remote``,
reserving ``threads_per_worker`` CPUs, default 1), on the Ray instance this
process runs in (a job of ``hydra/launcher=ray``), else the running cluster
``ray.init(address="auto")`` finds (or ``$RAY_ADDRESS``), else a local
instance started for this run: the folds of every job of a sweep spread over
the cluster's nodes (docs/CLUSTER.md). The fold's code is the same
:func:`run_fold` either way.

Resume by fold: given a ``resume`` store (:class:`FoldStore`; the pipeline
passes one over the stage cache, :class:`sphri.pipeline.FoldCache`), each
fold's :class:`~sphri.types.FoldRecord` is saved by the process that
computed it as soon as it finishes (also in a worker, whatever the order),
and a rerun loads the folds found there and computes only the others. The
result is the same as an uninterrupted run's: every fold is a fresh model
seeded by its own settings, independent of which folds ran before it.
"""

from __future__ import annotations

import inspect
import logging
import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm.auto import tqdm

from sphri.config import Configured
from sphri.evaluate.metrics import fold_metrics
from sphri.evaluate.schema import FoldsSchema, KFoldSchema, LosoSchema
from sphri.finite import require_finite
from sphri.types import GESTURES, CVResult, FoldRecord, FoldResult, WindowedFrames

log = logging.getLogger(__name__)


class CVError(ValueError):
    """The windows cannot be cross-validated as configured (too few participants); names the cause."""


@dataclass(frozen=True)
class Fold:
    """One split: held-out name and (train, test) trial indices into the windows."""

    name: str
    train: np.ndarray
    """(n_train,) int64 row indices of ``WindowedFrames``."""
    test: np.ndarray
    """(n_test,) int64 row indices of ``WindowedFrames``."""


#: Environment variable holding this process's thread budget (set by parallel sweep jobs).
THREADS_ENV = "SPHRI_THREADS"


def available_cores() -> int:
    """CPU cores this process may use: its affinity, capped by ``$SPHRI_THREADS`` when set.

    A parallel sweep job sets ``SPHRI_THREADS`` to its share of the cores
    (``sphri.__main__.limit_threads``), so the folds and forests of two jobs
    on two cores use one thread each instead of two.
    """
    try:
        cores = max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        cores = max(1, os.cpu_count() or 1)
    budget = os.environ.get(THREADS_ENV, "")
    if budget:
        try:
            cores = min(cores, max(1, int(budget)))
        except ValueError:
            raise ValueError(f"${THREADS_ENV}={budget!r} is invalid: must be a positive integer") from None
    return cores


def model_name(est: Any) -> str:
    """Short name of an estimator: its class's ``NAME`` or the class name."""
    return str(getattr(type(est), "NAME", type(est).__name__))


def _cap_threads(est: Any, threads: int) -> None:
    """Limit an estimator's own parallelism (``n_jobs``, ``threads``) to ``threads``."""
    if not hasattr(est, "get_params") or not hasattr(est, "set_params"):
        return
    params = est.get_params(deep=False)
    updates = {  # None, -1 (all cores) or more than ``threads``: capped
        key: threads
        for key in ("n_jobs", "threads")
        if key in params and not (isinstance(params[key], (int, np.integer)) and 0 < params[key] <= threads)
    }
    if updates:
        est.set_params(**updates)


def _accepts_groups(est: Any) -> bool:
    try:
        sig = inspect.signature(est.fit)
    except (TypeError, ValueError):
        return False
    return "groups" in sig.parameters or any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())


class FoldStore(Protocol):
    """Where finished folds are kept for a rerun (see the module doc). Must be picklable: the
    workers of ``cv.workers > 1`` save their own folds."""

    def load(self, fold: str) -> FoldRecord | None:
        """The record of fold ``fold`` if one was kept (None: compute it)."""

    def save(self, record: FoldRecord) -> None:
        """Keep a finished fold (never raises for a store that cannot be written: logs it)."""


def run_fold(
    make_model: Callable[[], Any],
    x: np.ndarray,
    y: np.ndarray,
    groups: np.ndarray,
    fold: Fold,
    threads: int,
    featurized: bool = False,
    resume: FoldStore | None = None,
) -> tuple[FoldResult, dict[str, float]]:
    """Fit a fresh model on ``fold.train``, score it on ``fold.test``; with ``resume``, keep the finished
    fold there (in the process that computed it).

    With ``featurized``, ``x`` holds the model's per-trial features
    (:func:`transform_once`) and the fold calls ``fit_features`` /
    ``predict_features`` instead of ``fit`` / ``predict``.

    Returns the fold's metrics and its timing: ``wall_s`` and ``cpu_s`` (CPU
    seconds of this process, all its threads; less sensitive than wall time
    to other processes competing for the cores). Runs with BLAS, OpenMP and
    torch limited to ``threads``.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    with threadpool_limits(limits=threads):
        est = make_model()
        _cap_threads(est, threads)
        torch = sys.modules.get("torch")
        prev = torch.get_num_threads() if torch is not None else None
        if torch is not None:
            torch.set_num_threads(threads)
        try:
            fit = est.fit_features if featurized else est.fit
            predict = est.predict_features if featurized else est.predict
            kw = {"groups": groups[fold.train]} if _accepts_groups(est) else {}
            fit(x[fold.train], y[fold.train], **kw)
            pred = np.asarray(predict(x[fold.test]))
        finally:
            if torch is not None and prev is not None:
                torch.set_num_threads(prev)
    timing = {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}
    # a NaN label would be cast to an arbitrary class: no fold is recorded from non-finite predictions
    require_finite(pred, f"{model_name(est)} predictions of fold {fold.name}")
    runtime = getattr(est, "runtime_", None)
    res = fold_metrics(fold.name, y[fold.test], pred)
    if isinstance(runtime, dict):
        res.runtime = {str(k): str(v) for k, v in runtime.items()}
    if resume is not None:
        resume.save(FoldRecord(result=res, wall_s=float(timing["wall_s"]), cpu_s=float(timing["cpu_s"])))
    return res, timing


def _usable(record: FoldRecord, fold: Fold, y: np.ndarray) -> bool:
    """A kept record belongs to this fold: same name, as many test trials, the same true labels."""
    r = record.result
    cm = np.asarray(r.confusion)
    ok = (
        r.fold == fold.name
        and r.n_test == fold.test.size
        and np.array_equal(cm.sum(axis=1), np.bincount(y[fold.test], minlength=cm.shape[0]))
    )
    if not ok:
        log.warning(
            "fold %s: the kept result does not match this fold (%s, %d test trials); recomputing it",
            fold.name,
            r.fold,
            r.n_test,
        )
    return ok


def transforms_per_trial(est: Any) -> bool:
    """Whether ``est`` declares a fold-independent per-trial ``transform`` (see the module doc)."""
    return bool(getattr(est, "TRANSFORM_PER_TRIAL", False)) and all(
        callable(getattr(est, m, None)) for m in ("transform", "fit_features", "predict_features")
    )


def transform_once(est: Any, x: np.ndarray, threads: int) -> tuple[np.ndarray, dict[str, float]]:
    """``est.transform(x)`` for all trials at once, with ``threads`` threads -> (features, timing)."""
    t0, c0 = time.perf_counter(), time.process_time()
    with threadpool_limits(limits=threads):
        feats = np.asarray(est.transform(x))
    if feats.shape[0] != x.shape[0]:
        raise RuntimeError(
            f"{type(est).__name__}.transform returned {feats.shape[0]} rows for {x.shape[0]} trials; "
            "a per-trial transform must keep one row per trial"
        )
    return feats, {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}


def _check_windows(windows: WindowedFrames) -> None:
    x, y, g = windows.x, windows.y, windows.groups
    if x.ndim != 3:
        raise ValueError(f"windows.x must be (n_trials, L, N_taxels), got shape {x.shape}")
    n = x.shape[0]
    if np.shape(y) != (n,) or np.shape(g) != (n,):
        raise ValueError(f"windows.y {np.shape(y)} and windows.groups {np.shape(g)} must both be ({n},)")
    if n == 0:
        raise ValueError("windows hold no trials (every trial dropped?); nothing to cross-validate")
    y = np.asarray(y)
    if y.min() < 0 or y.max() >= len(GESTURES):
        raise ValueError(f"windows.y holds labels outside 0..{len(GESTURES) - 1}: {np.unique(y)}")


#: How to install Ray (the ``cluster`` extra pins a version hydra-ray-launcher accepts).
RAY_HINT = 'pip install -e ".[cluster]" (docs/CLUSTER.md)'


class RayFolds:
    """The folds of one :meth:`CrossValidation.run` as Ray tasks (``backend="ray"``).

    Joins the Ray instance this process is connected to (a Ray launcher job), else ``$RAY_ADDRESS``,
    else a running cluster (``ray.init(address="auto")``), else starts a local instance with this
    process's cores; disconnects (and stops a local instance) in :meth:`close` only if it connected.
    The windows go to the object store once; each fold is ``run_fold`` as a task with ``num_cpus``
    equal to its thread count, so Ray's scheduler spreads the folds of every job over the nodes.
    """

    def __init__(self, data_bytes: int = 0) -> None:
        """``data_bytes``: size of the windows, to size the object store of a local instance."""
        try:
            import ray
        except ModuleNotFoundError:
            from sphri.config import ConfigError

            raise ConfigError(f"cv.backend='ray' is invalid: needs Ray: {RAY_HINT}") from None

        self.ray = ray
        self.connected = False
        self.pending: list[Any] = []
        if ray.is_initialized():
            return
        if os.environ.get("RAY_ADDRESS"):
            ray.init()
        else:
            try:
                ray.init(address="auto")
            except ConnectionError:  # no running cluster: a local instance for this run
                store = max(100 * 2**20, 3 * int(data_bytes))  # the windows, with room for the results
                ray.init(num_cpus=available_cores(), include_dashboard=False, object_store_memory=store)
        self.connected = True

    def submit(
        self,
        make_model: Callable[[], Any],
        x: np.ndarray,
        y: np.ndarray,
        groups: np.ndarray,
        folds: list[Fold],
        threads: int,
        featurized: bool,
        resume: FoldStore | None,
    ) -> Iterator[tuple[FoldResult, dict[str, float]]]:
        """Start a task per fold now; yields their results in fold order."""
        ray = self.ray
        task = ray.remote(run_fold).options(num_cpus=threads)
        shared = [ray.put(v) for v in (make_model, x, y, groups)]  # top-level refs: resolved in the task
        self.pending = [task.remote(*shared, f, threads, featurized, resume) for f in folds]
        log.info("%d folds submitted as Ray tasks (%d CPU each)", len(folds), threads)
        return self._results()

    def _results(self) -> Iterator[tuple[FoldResult, dict[str, float]]]:
        while self.pending:
            out = self.ray.get(self.pending[0])
            self.pending.pop(0)
            yield out

    def close(self) -> None:
        """Cancel the folds not collected (after an error), disconnect if this object connected."""
        for ref in self.pending:
            try:
                self.ray.cancel(ref)
            except Exception as exc:  # a finished or lost task: nothing to cancel
                log.debug("ray.cancel: %s", exc)
        self.pending = []
        if self.connected:
            self.ray.shutdown()
            self.connected = False


def _kept_folds(resume: FoldStore | None, folds: list[Fold], y: np.ndarray) -> dict[str, FoldRecord]:
    """Fold name -> the record ``resume`` keeps of it, for the folds whose record still fits labels ``y``."""
    kept: dict[str, FoldRecord] = {}
    if resume is not None:
        for f in folds:
            record = resume.load(f.name)
            if record is not None and _usable(record, f, y):
                kept[f.name] = record
    return kept


@dataclass
class _Jobs:
    """The folds to compute (``todo``) and what each needs: the model factory, windows x (n, L, N) or their
    per-trial features, labels y (n,), groups (n,), threads per fold, whether x holds features, and the store
    each computed fold is saved in (or None)."""

    make_model: Callable[[], Any]
    x: np.ndarray
    y: np.ndarray
    groups: np.ndarray
    todo: list[Fold]
    threads: int
    featurized: bool
    resume: FoldStore | None

    def computed(self, workers: int, ray_run: RayFolds | None) -> Iterator[tuple[FoldResult, dict[str, float]]]:
        """(result, timing) of each fold of ``todo`` in order: Ray tasks, this process, or ``workers`` processes."""
        make_model, x, y, groups, todo = self.make_model, self.x, self.y, self.groups, self.todo
        threads, featurized, resume = self.threads, self.featurized, self.resume
        if ray_run is not None:
            return ray_run.submit(make_model, x, y, groups, todo, threads, featurized, resume)
        if workers == 1:
            return (run_fold(make_model, x, y, groups, f, threads, featurized, resume) for f in todo)
        from joblib import Parallel, delayed

        return Parallel(n_jobs=workers, backend="loky", return_as="generator")(
            delayed(run_fold)(make_model, x, y, groups, f, threads, featurized, resume) for f in todo
        )


class CrossValidation(Configured):
    """Runs a model over folds; subclasses define :meth:`splits`, ``SCHEME`` and ``SCHEMA``.

    Settings, defaults and range checks are the schema's (:class:`sphri.evaluate.schema.FoldsSchema`:
    ``workers``, ``threads_per_worker``, ``max_folds``, ``progress``, ``backend``); a bad value raises
    :class:`sphri.config.ConfigError` naming ``cv.<field>``.
    """

    SCHEME = ""
    VERSION = "1"
    SCHEMA: Any = FoldsSchema
    workers: int
    threads_per_worker: int | None
    max_folds: int | None
    progress: bool
    backend: str

    def splits(self, windows: WindowedFrames, seed: int = 0) -> list[Fold]:
        raise NotImplementedError

    def _check_fold(self, fold: Fold, groups: np.ndarray) -> None:
        """Refuse a fold whose train and test sides share trials."""
        if np.intersect1d(fold.train, fold.test).size:
            raise RuntimeError(f"fold {fold.name!r}: a trial is on both the train and the test side")

    def run(
        self,
        make_model: Callable[[], Any],
        windows: WindowedFrames,
        seed: int = 0,
        on_fold: Callable[[FoldResult, dict[str, float]], None] | None = None,
        resume: FoldStore | None = None,
    ) -> CVResult:
        """Evaluate ``make_model()`` on every fold (the first ``max_folds``) -> :class:`CVResult`.

        ``on_fold(result, timing)`` is called as each fold finishes (in fold
        order), with ``timing = {"wall_s": ..., "cpu_s": ...}`` of that fold
        (for a fold loaded from ``resume``: the times it took when computed).
        ``resume``: a :class:`FoldStore`; its folds are not recomputed and
        every fold computed here is saved in it.
        """
        folds, groups = self._checked_folds(windows, seed)
        x, y = windows.x, np.asarray(windows.y, dtype=np.int64)
        kept = _kept_folds(resume, folds, y)
        todo = [f for f in folds if f.name not in kept]
        probe = make_model()
        name = model_name(probe)
        if kept:
            log.info(
                "%s %s: %d of %d folds loaded from the cache (kept by an interrupted run), computing %d",
                self.SCHEME,
                name,
                len(kept),
                len(folds),
                len(todo),
            )
        workers = max(1, min(self.workers, len(todo)))
        threads = self.threads_per_worker or max(1, available_cores() // workers)
        if self.backend == "ray":  # a task per fold, each reserving (and using) threads_per_worker CPUs
            threads = self.threads_per_worker or 1
        featurized = transforms_per_trial(probe)
        if featurized and todo:
            x = self._features_once(probe, x, name)
        del probe
        jobs = _Jobs(make_model, x, y, groups, todo, threads, featurized, resume)
        results = self._collect(jobs, folds, kept, workers, name, on_fold)
        return CVResult(scheme=self.SCHEME, model=name, folds=results)

    def _checked_folds(self, windows: WindowedFrames, seed: int) -> tuple[list[Fold], np.ndarray]:
        """(the folds to run: the first ``max_folds`` of :meth:`splits`, each checked; the windows' groups)."""
        _check_windows(windows)
        folds = self.splits(windows, seed)
        if self.max_folds is not None:
            folds = folds[: self.max_folds]
        groups = np.asarray(windows.groups)
        for f in folds:
            self._check_fold(f, groups)
        return folds, groups

    def _features_once(self, probe: Any, x: np.ndarray, name: str) -> np.ndarray:
        """The per-trial features of windows ``x`` by the model ``probe`` (computed once for all folds)."""
        x, timing = transform_once(probe, x, threads=self.threads_per_worker or available_cores())
        log.info(
            "%s %s: per-trial features %s computed once in %.1f s (%.1f CPU s)",
            self.SCHEME,
            name,
            x.shape,
            timing["wall_s"],
            timing["cpu_s"],
        )
        return x

    def _collect(
        self,
        jobs: _Jobs,
        folds: list[Fold],
        kept: dict[str, FoldRecord],
        workers: int,
        name: str,
        on_fold: Callable[[FoldResult, dict[str, float]], None] | None,
    ) -> list[FoldResult]:
        """Every fold's result in fold order: kept folds in place, computed ones (by ``workers`` processes or
        Ray) as they come; ``on_fold`` and the progress bar see each."""
        bar = tqdm(
            total=len(folds),
            desc=f"{self.SCHEME} {name}",
            unit="fold",
            disable=not (self.progress and sys.stderr.isatty()),
        )
        results: list[FoldResult] = []
        ray_run = RayFolds(jobs.x.nbytes) if self.backend == "ray" and jobs.todo else None
        try:
            computed = jobs.computed(workers, ray_run)
            for f in folds:  # in fold order: kept folds in place, computed ones as they come
                record = kept.get(f.name)
                if record is not None:
                    res, timing = record.result, {"wall_s": record.wall_s, "cpu_s": record.cpu_s}
                else:
                    res, timing = next(computed)
                    log.debug(
                        "%s %s fold %s: accuracy %.3f in %.1f s (%.1f CPU s)",
                        self.SCHEME,
                        name,
                        res.fold,
                        res.accuracy,
                        timing["wall_s"],
                        timing["cpu_s"],
                    )
                results.append(res)
                if on_fold is not None:
                    on_fold(res, timing)
                bar.update(1)
                bar.set_postfix(acc=f"{np.mean([r.accuracy for r in results]):.3f}")
        finally:
            bar.close()
            if ray_run is not None:
                ray_run.close()
        return results


class LeaveOneSubjectOut(CrossValidation):
    """``cv=loso``: each participant is the test set once; the others train.

    Folds are in sorted participant order, named by participant. ``seed`` is
    unused (the split is deterministic; models carry their own seed).
    """

    SCHEME = "loso"
    SCHEMA = LosoSchema
    min_participants: int | None

    def splits(self, windows: WindowedFrames, seed: int = 0) -> list[Fold]:
        groups = np.asarray(windows.groups)
        uniq = np.unique(groups)
        if uniq.size < 2:
            raise CVError(
                f"leave-one-subject-out needs at least 2 participants, windows have {uniq.size}: {list(uniq)}"
            )
        if self.min_participants is not None and uniq.size < self.min_participants:
            raise CVError(
                f"cv.min_participants={self.min_participants}: only {uniq.size} participants have windows "
                f"({[str(g) for g in uniq]}); the others lost every trial (no contact, or dropped by the data stage)"
            )
        idx = np.arange(groups.shape[0], dtype=np.int64)
        return [Fold(name=str(g), train=idx[groups != g], test=idx[groups == g]) for g in uniq]

    def _check_fold(self, fold: Fold, groups: np.ndarray) -> None:
        super()._check_fold(fold, groups)
        shared = np.intersect1d(groups[fold.train], groups[fold.test])
        if shared.size:
            raise RuntimeError(f"fold {fold.name!r}: participants {list(shared)} on both train and test side")


class WithinSubjectKFold(CrossValidation):
    """``cv=kfold``: stratified k folds inside each participant, pooled.

    Fold i tests every participant's i-th share of trials (stratified by
    gesture) and trains on all the rest, so the same people are on both
    sides: within-subject accuracy, NOT comparable to leave-one-subject-out
    (the result's ``scheme`` is ``"kfold"``). Shuffled with ``seed``.
    """

    SCHEME = "kfold"
    SCHEMA = KFoldSchema
    k: int

    def assign(self, y: np.ndarray, groups: np.ndarray, seed: int = 0) -> np.ndarray:
        """(n,) int64 fold of each trial: per participant, gestures dealt round-robin."""
        rng = np.random.default_rng(seed)
        fold = np.empty(y.shape[0], dtype=np.int64)
        idx = np.arange(y.shape[0])
        for g in np.unique(groups):
            members = idx[groups == g]
            # class by class, shuffled within class, dealt 0, 1, ..., k-1, 0, ...
            order = np.concatenate([rng.permutation(members[y[members] == c]) for c in np.unique(y[members])])
            fold[order] = (int(rng.integers(self.k)) + np.arange(order.size)) % self.k
        return fold

    def splits(self, windows: WindowedFrames, seed: int = 0) -> list[Fold]:
        y = np.asarray(windows.y)
        groups = np.asarray(windows.groups)
        names, sizes = np.unique(groups, return_counts=True)
        if sizes.size and self.k > int(sizes.min()):
            least = str(names[int(np.argmin(sizes))])
            raise CVError(
                f"cv.k={self.k} is more than the {int(sizes.min())} windows of {least} (the participant with the "
                f"fewest of {len(names)}): each of the k folds needs a share of every participant's trials; "
                f"set cv.k<={int(sizes.min())}"
            )
        fold = self.assign(y, groups, seed)
        idx = np.arange(y.shape[0], dtype=np.int64)
        out = []
        for i in range(self.k):
            test, train = idx[fold == i], idx[fold != i]
            if test.size and train.size:
                out.append(Fold(name=f"fold_{i + 1}", train=train, test=test))
        if not out:
            raise ValueError(f"within-subject {self.k}-fold: too few trials ({y.shape[0]}) for any fold")
        return out
