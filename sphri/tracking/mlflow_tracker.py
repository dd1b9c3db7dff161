"""MLflow tracking of jobs and sweeps.

One job = one MLflow run: a curated, flattened set of params (component
choices and their scalar settings, the resolution in physical units), tags
(config hash, git commit, sweep id, dataset and whether it is synthetic),
per-fold metrics (``fold_accuracy``/``fold_macro_f1`` with step = fold
index, and per participant), summary metrics, and artifacts (composed config,
per-participant CSV, confusion matrix PNG, summary text).

A multirun is one parent run (found or created by :mod:`sphri.tracking.parent`
after every job's config is validated and before any worker starts) with the
jobs as children.

The default store is SQLite at an absolute path (``<output_dir>/mlflow.db``),
artifacts beside it in ``<output_dir>/mlartifacts``; :mod:`sphri.tracking.store`
creates it, or refuses a broken one, the first time a tracker opens it.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import random
import subprocess
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from sphri import __version__
from sphri.config import Configured, build
from sphri.layout.schema import layout_res
from sphri.stages import PARAM_GROUPS  # groups whose component and scalar settings become params
from sphri.tracking import machine
from sphri.tracking.schema import MlflowTrackingSchema

if TYPE_CHECKING:
    from mlflow.tracking import MlflowClient
    from omegaconf import DictConfig

    from sphri.pipeline import RunResult
    from sphri.types import CVResult, RunMeta

log = logging.getLogger(__name__)
T = TypeVar("T")

PARENT_FILE = "mlflow_parent_run.json"
"""Written into a sweep directory: the parent run id and tracking URI."""
_CLIENTS: dict[str, MlflowClient] = {}
"""This process's MLflow client of each tracking URI (every tracker of a sweep's launching process shares it)."""

#: Settings of a group that are not MLflow params (paths, large nested definitions).
_SKIP_PARAM_KEYS = {"_target_", "root", "path", "definition_path", "density_path", "capsules", "links", "joints"}


def default_uri(output_dir: str | os.PathLike) -> str:
    """The MLflow tracking URI of ``output_dir``'s store: ``sqlite:///<output_dir, absolute>/mlflow.db``."""
    return f"sqlite:///{Path(output_dir).resolve() / 'mlflow.db'}"


def no_artifact_bars() -> None:
    """Turn MLflow's artifact progress bars off in this process, unless the user set
    ``MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR``: where sphri only reads back small artifacts it wrote (a
    report reading every job's files, a job whose model MLflow reads back to check its input example),
    a "Downloading artifacts" bar per read is noise on the console."""
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")


def git_commit() -> str:
    """The commit sphri runs from: the checkout's HEAD (``+dirty`` with uncommitted changes to tracked
    files), else the commit an installed wheel was built from (``sphri/_build_info.json``, written by
    setup.py), else ``"unknown"``."""
    here = Path(__file__).resolve().parent
    git = partial(subprocess.run, capture_output=True, text=True, timeout=5, cwd=here)
    try:
        out = git(["git", "rev-parse", "--show-toplevel", "HEAD"])
        top, commit = (out.stdout.split() + ["", ""])[:2]
        if out.returncode == 0 and commit and here.is_relative_to(Path(top).resolve()):
            dirty = git(["git", "status", "--porcelain", "--untracked-files=no"]).stdout.strip()
            return commit + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError, ValueError):
        pass
    try:
        data = json.loads((here.parent / "_build_info.json").read_text())
        return str(data["git_commit"]) + ("+dirty" if data.get("dirty") else "")
    except (OSError, ValueError, KeyError, TypeError):
        return "unknown"


def source_tags() -> dict[str, str]:
    """MLflow's own run-context tags, through its tag-provider registry as ``mlflow.start_run`` does
    (``mlflow.user``, ``mlflow.source.name``/``type``, and the git fields when the entry point is in a
    checkout), plus the commit of :func:`git_commit` (from a wheel too) and sphri's version."""
    from mlflow.tracking.context.registry import resolve_tags

    tags = dict(resolve_tags({}))
    commit = git_commit()
    tags["sphri.git_commit"] = commit
    tags["sphri.version"] = __version__
    if commit != "unknown":
        tags.setdefault("mlflow.source.git.commit", commit.removesuffix("+dirty"))
    return tags


def dataset_input(cfg: DictConfig, result: RunResult) -> Any:
    """The job's dataset as an MLflow dataset input (``mlflow.data``; context ``training``): named after
    the dataset, its digest the data stage's content key (the same data gives the same digest), its
    source the dataset folder (``data.root``) or, for generated data, the generator and its settings."""
    from mlflow.data.code_dataset_source import CodeDatasetSource
    from mlflow.data.dataset_source_registry import resolve_dataset_source
    from mlflow.data.meta_dataset import MetaDataset
    from mlflow.entities import DatasetInput, InputTag

    stage = result.stages.get("data")
    digest = (stage.key if stage is not None else result.config_hash)[:36]
    root = cfg.data.get("root") if hasattr(cfg.data, "get") else None
    if root:
        source = resolve_dataset_source(str(Path(str(root)).resolve()))
    else:
        settings = node_settings(cfg.data)
        source = CodeDatasetSource({k: str(v)[:200] for k, v in settings.items() if not isinstance(v, dict)})
    dataset = MetaDataset(source=source, name=result.meta.dataset, digest=digest)
    return DatasetInput(dataset._to_mlflow_entity(), tags=[InputTag("mlflow.data.context", "training")])


def sweep_params(overrides: list[str]) -> dict[str, str]:
    """A sweep's parent-run params: each override's key and value as given (``layout.res`` -> ``2,4``;
    a group choice ``+experiment=resolution_sweep`` -> ``experiment``), flags such as ``-m`` left out."""
    out = {}
    for item in overrides:
        key, sep, value = item.partition("=")
        key = key.lstrip("+~")
        if sep and not item.startswith("-") and not key.startswith("hydra."):
            out[key[:250]] = value[:500]
    return out


def model_runtime(cfg: DictConfig) -> dict[str, str]:
    """``run.<key>`` params from the model's ``runtime()`` (device, precision as resolved on this
    machine: ``model.device=auto`` -> ``cuda`` or ``cpu``); empty for a model without one."""
    from hydra.utils import get_class

    target = cfg.model.get("_target_") if hasattr(cfg.model, "get") else None
    try:
        if not isinstance(target, str) or not callable(getattr(get_class(target), "runtime", None)):
            return {}
        runtime = build(cfg.model).runtime()
    except Exception as exc:  # noqa: BLE001 - the job's record matters more than this detail
        log.warning("could not tell the model's device (%s: %s)", type(exc).__name__, exc)
        return {"run.device": f"unknown ({type(exc).__name__})"}
    return {f"run.{k}": str(v) for k, v in runtime.items()}


def fold_runtime(cv: CVResult) -> dict[str, str]:
    """``run.<key>`` params from what the folds' models recorded after ``fit`` (the CNN-GRU's device,
    precision and why): one value where every fold agrees, else each value with its folds."""
    out: dict[str, str] = {}
    for key in sorted({k for f in cv.folds for k in f.runtime}):
        by_value: dict[str, list[str]] = {}
        for f in cv.folds:
            if key in f.runtime:
                by_value.setdefault(f.runtime[key], []).append(f.fold)
        said = [f"{v} (folds {', '.join(folds)})" for v, folds in by_value.items()]
        out[f"run.{key}"] = (next(iter(by_value)) if len(by_value) == 1 else "; ".join(said))[:500]
    return out


def component_name(node: Any, choice: str | None = None) -> str:
    """The YAML choice if known, else the ``_target_`` class name."""
    if choice:
        return choice
    target = node.get("_target_", "") if hasattr(node, "get") else ""
    return str(target).rsplit(".", 1)[-1] or "?"


def node_settings(node: Any) -> dict[str, Any]:
    """A config group's settings as a plain dict (interpolations resolved), keys as str."""
    from omegaconf import OmegaConf

    values = OmegaConf.to_container(node, resolve=True)
    if not isinstance(values, dict):
        raise TypeError(f"a config group's settings must be a mapping, got {type(values).__name__}")
    return {str(k): v for k, v in values.items()}


def flatten_params(cfg: DictConfig, choices: dict[str, str] | None = None) -> dict[str, str]:
    """Curated params: ``<group>`` = component, ``<group>.<key>`` = scalar settings."""
    choices = choices or {}
    params: dict[str, str] = {"seed": str(cfg.seed)}
    if cfg.get("variant") is not None:  # the assumption variant of a sensitivity sweep (conf/sensitivity/)
        params["variant"] = str(cfg.variant)
    for group in PARAM_GROUPS:
        node = cfg[group]
        params[group] = component_name(node, choices.get(group))
        for key, value in node_settings(node).items():
            too_big = isinstance(value, dict) or (isinstance(value, list) and len(value) > 12)
            if key not in _SKIP_PARAM_KEYS and not too_big:
                params[f"{group}.{key}"] = str(value)[:500]
    return params


def log_analysis_run(
    cfg: DictConfig,
    kind: str,
    run_name: str,
    tags: dict[str, str],
    numbers: Callable[[], tuple[list, list]],
    out_dir: str | os.PathLike,
) -> str | None:
    """One MLflow run of an analysis of ``cfg`` (coverage, scenario study), tagged ``sphri.kind=<kind>``,
    ``tags`` and the git commit, holding ``numbers()`` (metrics, params) and every file of ``out_dir``,
    ended FINISHED (FAILED on error); its id, or None where ``cfg.tracking`` turns tracking off."""
    tracker = build(cfg.tracking)
    if not getattr(tracker, "enabled", True):
        return None
    client = tracker.client(cfg.output_dir)
    exp = tracker.experiment_id(cfg.output_dir)
    tags = {"sphri.kind": kind, **tags, "sphri.git_commit": git_commit()}
    run_id = tracker._retry(client.create_run, exp, tags=tags, run_name=run_name).info.run_id
    try:
        metrics, params = numbers()
        tracker.log_batches(client, run_id, metrics, params)
        tracker._retry(client.log_artifacts, run_id, str(out_dir))
        tracker._retry(client.set_terminated, run_id, "FINISHED")
    except Exception:
        tracker._retry(client.set_terminated, run_id, "FAILED")
        raise
    return run_id


def _lost_race(exc: Exception) -> bool:
    """Whether a store write failed only because a parallel job wrote first (worth a retry)."""
    text = str(exc).lower()
    return "locked" in text or "unique constraint failed: datasets." in text


class MlflowTracker(Configured):
    """Logs jobs to MLflow; built from the ``tracking`` config group."""

    VERSION = "1"
    SCHEMA = MlflowTrackingSchema
    enabled: bool  # these eight set from SCHEMA by Configured
    uri: str | None
    experiment: str
    artifacts: bool
    confusion_png: bool
    retries: int
    log_model: bool | None
    register_model: str | None

    def configured(self) -> None:
        self._client: MlflowClient | None = None

    # -- setup -------------------------------------------------------------
    def resolve_uri(self, output_dir: str | os.PathLike) -> str:
        return self.uri or default_uri(output_dir)

    def client(self, output_dir: str | os.PathLike) -> MlflowClient:
        """The MLflow client; opening it creates (or checks) the store, so call it before computing."""
        if self._client is None:
            uri = self.resolve_uri(output_dir)
            if uri not in _CLIENTS:  # one per store and process: opening a SQL store costs about 0.6 s
                from mlflow.tracking import MlflowClient

                from sphri.tracking.store import ensure_store

                ensure_store(uri)  # a new SQLite store is created once, under a lock; a broken one raises BrokenStore
                _CLIENTS[uri] = MlflowClient(tracking_uri=uri)
            self._client = _CLIENTS[uri]
        return self._client

    def experiment_id(self, output_dir: str | os.PathLike) -> str:
        """Get or create the experiment (artifacts under ``<output_dir>/mlartifacts``)."""
        client = self.client(output_dir)

        def get_or_create() -> str:
            exp = client.get_experiment_by_name(self.experiment)
            if exp is not None:
                return exp.experiment_id
            # a local store keeps artifacts beside it; a server (http) chooses where its artifacts go
            local = not self.resolve_uri(output_dir).startswith(("http://", "https://"))
            location = (Path(output_dir).resolve() / "mlartifacts").as_uri() if local else None
            try:
                return client.create_experiment(self.experiment, artifact_location=location)
            except Exception:  # created concurrently by another process
                exp = client.get_experiment_by_name(self.experiment)
                if exp is None:
                    raise
                return exp.experiment_id

        return self._retry(get_or_create)

    def log_batches(self, client: MlflowClient, run_id: str, metrics: list, params: list) -> None:
        """Log metrics and params in MLflow's batches of 100, retrying a locked store."""
        for i in range(0, max(len(metrics), len(params)), 100):
            self._retry(client.log_batch, run_id, metrics=metrics[i : i + 100], params=params[i : i + 100])

    def _retry(self, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        """``fn(*args, **kwargs)``, retried when it lost a race with another job writing the same store: a
        locked SQLite database, or a dataset row another job inserted between MLflow's lookup and its insert
        (two parallel jobs logging the same dataset input into a new store: the retry finds the row)."""
        for attempt in range(self.retries + 1):
            try:
                return fn(*args, **kwargs)
            except Exception as exc:  # sqlalchemy's OperationalError/IntegrityError, wrapped by MLflow
                if not _lost_race(exc) or attempt == self.retries:
                    raise
                time.sleep(0.2 * (2**attempt) * (0.5 + random.random()))
        raise AssertionError("unreachable")

    def _search(self, output_dir: str, query: str, **kwargs: Any) -> list:
        """The experiment's runs matching ``query`` (none while the experiment does not exist)."""
        client = self.client(output_dir)
        exp = self._retry(client.get_experiment_by_name, self.experiment)
        return [] if exp is None else self._retry(client.search_runs, [exp.experiment_id], query, **kwargs)

    # -- sweeps --------------------------------------------------------------
    def start_parent(
        self,
        output_dir: str,
        sweep_dir: str,
        sweep_id: str,
        overrides: list[str],
        sweep_hash: str | None = None,
        base: DictConfig | None = None,
        swept: dict[str, str] | None = None,
    ) -> str:
        """Create a sweep's parent run with MLflow's source tags and the sweep's params: the settings
        every job shares (``base``, the composed sweep config), then each swept key with its values as
        given (the command line's overrides and an experiment's ``hydra.sweeper.params``)."""
        from mlflow.entities import Param

        client = self.client(output_dir)
        exp_id = self.experiment_id(output_dir)
        tags = {
            "sphri.kind": "sweep",
            "sphri.sweep_id": sweep_id,
            **({"sphri.sweep_hash": sweep_hash} if sweep_hash else {}),
            "sphri.sweep_dir": str(Path(sweep_dir).resolve()),
            **source_tags(),
            "mlflow.note.content": "sweep: " + " ".join(overrides),
        }
        run_id = self._retry(client.create_run, exp_id, tags=tags, run_name=f"sweep-{sweep_id}").info.run_id
        values = flatten_params(base) if base is not None else {}
        values.update(sweep_params(overrides))
        values.update({k: v[:500] for k, v in (swept or {}).items()})
        self.log_batches(client, run_id, [], [Param(k, v) for k, v in values.items()])
        return run_id

    def end_parent(
        self,
        output_dir: str,
        run_id: str,
        n_jobs: int,
        n_failed: int,
        status: str | None = None,
        skipped: dict[int, str] | None = None,
    ) -> None:
        """End a sweep's parent run: ``status`` FINISHED, FAILED or KILLED (None: FAILED if a job failed).

        ``skipped``: job number -> the run that had already finished it; those of other sweeps are named
        on the parent (tag ``sphri.skipped_jobs``), so the parent accounts for every job."""
        client = self.client(output_dir)
        status = status or ("FAILED" if n_failed else "FINISHED")
        self._retry(client.set_tag, run_id, "sphri.jobs", f"{n_jobs - n_failed}/{n_jobs} finished")
        elsewhere = [
            f"job {job}: run {done}"
            for job, done in sorted((skipped or {}).items())
            if self._retry(client.get_run, done).data.tags.get("mlflow.parentRunId") != run_id
        ]
        if elsewhere:
            self._retry(client.set_tag, run_id, "sphri.skipped_jobs", ", ".join(elsewhere)[:5000])
        if status == "KILLED":  # jobs interrupted while logging end with their sweep
            exp_id = self._retry(client.get_run, run_id).info.experiment_id
            query = f"tags.`mlflow.parentRunId` = '{run_id}' and attributes.status = 'RUNNING'"
            for child in self._retry(client.search_runs, [exp_id], query):
                self._retry(client.set_terminated, child.info.run_id, "KILLED")
        self._retry(client.set_terminated, run_id, status)

    def find_parent(self, output_dir: str, sweep_hash: str) -> dict[str, str] | None:
        """``{run_id, sweep_id}`` of the latest parent run of a sweep with these overrides, if any."""
        query = f"tags.`sphri.sweep_hash` = '{sweep_hash}' and tags.`sphri.kind` = 'sweep'"
        runs = self._search(output_dir, query, max_results=1, order_by=["attributes.start_time DESC"])
        if not runs:
            return None
        run = runs[0]
        return {"run_id": run.info.run_id, "sweep_id": run.data.tags.get("sphri.sweep_id", run.info.run_id[:8])}

    def reopen_parent(self, output_dir: str, run_id: str) -> bool:
        """Mark an existing parent run RUNNING again (a resumed sweep); False if gone."""
        client = self.client(output_dir)
        try:
            self._retry(client.get_run, run_id)
        except Exception:
            return False
        self._retry(client.update_run, run_id, status="RUNNING")
        return True

    def find_finished(self, output_dir: str, config_hash: str) -> str | None:
        """Run id of a FINISHED job with this config hash, if any (sweep resume)."""
        query = (
            f"tags.`sphri.config_hash` = '{config_hash}' and tags.`sphri.kind` = 'job' "
            "and attributes.status = 'FINISHED'"
        )
        runs = self._search(output_dir, query, max_results=1)
        return runs[0].info.run_id if runs else None

    def mark_rerun(self, output_dir: str, run_id: str, job_dir: Path) -> int:
        """Record on the FINISHED run ``run_id`` that the same experiment ran again (a single run whose
        config hash it already holds: no new run is made). Returns how many reruns it has seen."""
        client = self.client(output_dir)
        n = int(self._retry(client.get_run, run_id).data.tags.get("sphri.reruns", "0") or 0) + 1
        stamp = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        for key, value in (("sphri.reruns", str(n)), ("sphri.last_rerun", stamp), ("sphri.last_rerun_dir", job_dir)):
            self._retry(client.set_tag, run_id, key, str(value))
        return n

    def logged_models(self, output_dir: str, run_id: str) -> list[str]:
        """``models:/<model_id>`` of every model logged from run ``run_id`` (MLflow's logged models)."""
        client = self.client(output_dir)
        exp_id = self._retry(client.get_run, run_id).info.experiment_id
        found = self._retry(
            client.search_logged_models, experiment_ids=[exp_id], filter_string=f"source_run_id = '{run_id}'"
        )
        return [f"models:/{m.model_id}" for m in found]

    # -- jobs ----------------------------------------------------------------
    def _start_job(
        self, cfg: DictConfig, job_dir: Path, parent: dict | None, run_name: str, tags: dict[str, str]
    ) -> str:
        client = self.client(cfg.output_dir)
        exp_id = self.experiment_id(cfg.output_dir)
        # MLflow's own fields (user, source, commit) first: the UI shows them
        tags = {"sphri.kind": "job", **source_tags(), "sphri.job_dir": str(job_dir), **tags}
        if parent:
            tags["mlflow.parentRunId"] = parent["run_id"]
            tags["sphri.sweep_id"] = parent["sweep_id"]
        return self._retry(client.create_run, exp_id, tags=tags, run_name=run_name).info.run_id

    def log_job(
        self,
        cfg: DictConfig,
        result: RunResult,
        job_dir: Path,
        parent: dict | None = None,
        run_name: str | None = None,
        choices: dict[str, str] | None = None,
    ) -> str:
        """Log a finished job; returns the MLflow run id."""
        from mlflow.entities import Param

        meta, stages = result.meta, result.stages
        evaluated_here = "evaluate" not in stages or stages["evaluate"].source == "computed"
        tags = {
            "sphri.config_hash": result.config_hash,
            "sphri.dataset": meta.dataset,
            "sphri.synthetic": str(meta.synthetic).lower(),
            "sphri.cv_scheme": result.cv.scheme,
            "sphri.from_cache": ",".join(n for n, r in stages.items() if r.source == "cache") or "none",
            "sphri.debug": str(bool((choices or {}).get("debug"))).lower(),
            **machine.tags(),  # CPU model and SIMD flags, GPU, library versions of this process
            "sphri.evaluated": "in this run"
            if evaluated_here
            else "earlier (the evaluation came from the cache: sphri.machine.* is this run's machine)",
        }
        run_id = self._start_job(cfg, job_dir, parent, run_name or self._run_name(cfg, meta, choices), tags)
        client = self.client(cfg.output_dir)
        params = flatten_params(cfg, choices)
        # what each fold's model trained with, kept with the folds; a model whose folds say nothing is asked
        # where it would run (only when evaluated here: a cached evaluation's device is not known here)
        runtime = fold_runtime(result.cv)
        params.update(runtime if runtime or not evaluated_here else model_runtime(cfg))
        for k, v in meta.resolution.items():
            params[f"resolution.{k}"] = f"{v:.6g}" if isinstance(v, float) else str(v)
        meta_keys = "robot region link n_participants n_trials n_windows n_dropped_no_contact frame_rate_hz"
        params.update({f"meta.{k}": str(getattr(meta, k)) for k in meta_keys.split()})
        plist = [Param(k, v) for k, v in params.items()]
        self.log_batches(client, run_id, _job_metrics(result), plist)
        self._retry(client.log_inputs, run_id, datasets=[dataset_input(cfg, result)])
        self._retry(client.set_tag, run_id, "mlflow.note.content", summary_text(result))
        if self.artifacts:
            self._log_artifacts(client, run_id, cfg, result)
        self._retry(client.set_terminated, run_id, "FINISHED")
        return run_id

    def log_failure(
        self,
        cfg: DictConfig,
        exc: BaseException,
        job_dir: Path,
        parent: dict | None = None,
        choices: dict[str, str] | None = None,
    ) -> str | None:
        """Record a failed job as a FAILED run carrying its error."""
        try:
            from mlflow.entities import Param

            tags = {"sphri.error": f"{type(exc).__name__}: {exc}"[:5000]}
            run_id = self._start_job(cfg, job_dir, parent, self._failed_name(cfg, choices), tags)
            client = self.client(cfg.output_dir)
            params = [Param(k, v) for k, v in flatten_params(cfg, choices).items()]
            self._retry(client.log_batch, run_id, params=params[:100])
            self._retry(client.set_terminated, run_id, "FAILED")
            return run_id
        except Exception as log_exc:  # never mask the job's own error
            log.error("could not record the failure in MLflow: %s", log_exc)
            return None

    @staticmethod
    def _failed_name(cfg: DictConfig, choices: dict[str, str] | None) -> str:
        """A failed job's run name: what its finished run would be called (from the config alone:
        the job never got as far as its metadata), then ``(failed)``."""
        try:
            robot = str(cfg.robot.get("name") or component_name(cfg.robot, (choices or {}).get("robot")))
            regions = list(cfg.data.get("regions") or [])
            model = component_name(cfg.model, (choices or {}).get("model"))
            return f"{robot}-{regions[0] if regions else 'all'}-res{layout_res(cfg, check=False)}-{model} (failed)"
        except Exception:  # a config too broken to name: still a recognisable failed run
            return "job (failed)"

    @staticmethod
    def _run_name(cfg: DictConfig, meta: RunMeta, choices: dict[str, str] | None) -> str:
        model = component_name(cfg.model, (choices or {}).get("model"))
        return f"{meta.robot}-{meta.region}-res{layout_res(cfg)}-{model}"

    def _log_artifacts(self, client: MlflowClient, run_id: str, cfg: DictConfig, result: RunResult) -> None:
        from omegaconf import OmegaConf

        from sphri.figures import Provenance
        from sphri.tracking.artifacts import write_confusion_csv, write_confusion_png, write_fold_csv

        cv = result.cv
        with tempfile.TemporaryDirectory(prefix="sphri-artifacts-") as tmp:
            tmp_path = Path(tmp)
            (tmp_path / "config.yaml").write_text(OmegaConf.to_yaml(cfg, resolve=True))
            write_fold_csv(cv, tmp_path / "per_participant.csv")
            # The report redraws the matrix from the counts (PNG, PDF, SVG, layout-checked); the job's own
            # PNG is for browsing runs in the MLflow UI, so it skips the vector files and the check.
            write_confusion_csv(cv, tmp_path / "confusion.csv")
            if self.confusion_png:
                title = f"{cv.model}, {cv.scheme.upper()} over {len(cv.folds)} folds"
                provenance = Provenance(synthetic=result.meta.synthetic, ids=f"res {layout_res(cfg)}")
                write_confusion_png(cv, tmp_path / "confusion.png", title, provenance, ("png",), check=False)
            (tmp_path / "summary.txt").write_text(summary_text(result) + "\n")
            (tmp_path / "meta.json").write_text(json.dumps(dataclasses.asdict(result.meta), indent=2, default=str))
            self._retry(client.log_artifacts, run_id, str(tmp_path))


def _job_metrics(result: RunResult) -> list:
    """A job's MLflow metrics: the resolution (``resolution/<key>``: the UI plots and sorts these), each fold's
    accuracy and macro-F1 (step = fold index) and accuracy per participant, the summary and each stage's time."""
    from mlflow.entities import Metric

    from sphri.evaluate.metrics import summarize

    now = int(time.time() * 1000)
    metrics = [
        Metric(f"resolution/{k}", float(v), now, 0)
        for k, v in result.meta.resolution.items()
        if isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
    ]
    for i, fold in enumerate(result.cv.folds):
        metrics += [
            Metric("fold_accuracy", float(fold.accuracy), now, i),
            Metric("fold_macro_f1", float(fold.macro_f1), now, i),
            Metric(f"participant/{fold.fold}/accuracy", float(fold.accuracy), now, 0),
        ]
    metrics += [
        Metric(k, float(v), now, 0)
        for k, v in summarize(result.cv).items()
        if isinstance(v, (int, float)) and np.isfinite(v)
    ]
    return metrics + [Metric(f"time/{name}_s", float(rec.seconds), now, 0) for name, rec in result.stages.items()]


def ui_hint(uri: str) -> str:
    """The command that shows ``uri`` in the MLflow UI (``make ui`` only for the repository's default store)."""
    if uri.startswith(("http://", "https://")):
        return f"open {uri}"  # a tracking server serves its own UI
    default = f"sqlite:///{(Path.cwd() / 'outputs' / 'mlflow.db').resolve()}"
    makefile = Path.cwd() / "Makefile"
    in_checkout = makefile.is_file() and "mlflow ui" in makefile.read_text(errors="replace")
    return "make ui" if uri == default and in_checkout else f"mlflow ui --backend-store-uri {uri}"


def summary_text(result: RunResult) -> str:
    """The one-screen summary printed at the end of a run."""
    from sphri.evaluate.metrics import chance_level, summarize

    m = result.meta
    s = summarize(result.cv)
    dropped = f"{m.n_dropped_no_contact} trial{'' if m.n_dropped_no_contact == 1 else 's'}"
    lines = [
        f"dataset     {m.dataset} ({'SYNTHETIC' if m.synthetic else 'real'}): {m.n_participants} participants, "
        f"{m.n_trials} trials, {m.n_windows} windows of {m.window_frames} frames ({dropped} without contact dropped)",
        f"robot       {m.robot}, region {m.region} (link {m.link}), surface {m.surface} "
        f"(fit residual {m.surface_fit_residual_mm:.1f} mm)",
        "resolution  " + ", ".join(_fmt_resolution(m.resolution)),
        f"model       {result.cv.model}, {result.cv.scheme.upper()} over {len(result.cv.folds)} folds",
        f"accuracy    {s['accuracy_mean']:.3f} +/- {s['accuracy_std']:.3f}   "
        f"(95% CI {s.get('accuracy_ci_low', float('nan')):.3f}-{s.get('accuracy_ci_high', float('nan')):.3f})",
        f"macro-F1    {s['macro_f1_mean']:.3f} +/- {s['macro_f1_std']:.3f}   (mean +/- std over participants; "
        f"chance {chance_level(result.cv):.3f})",
    ]
    return "\n".join(lines + [f"warning     {w}" for w in m.warnings])


def _fmt_resolution(r: dict[str, Any]) -> list[str]:
    out = []
    if "n_taxels" in r:
        shape = r.get("grid_shape")
        out.append(f"{r['n_taxels']} taxels" + (f" ({shape[0]} x {shape[1]})" if shape else ""))
    if r.get("pitch_u_mm"):
        out.append(f"pitch {r['pitch_u_mm']:.1f} mm along / {r.get('pitch_v_mm', float('nan')):.1f} mm around")
    if r.get("area_per_taxel_cm2"):
        out.append(f"{r['area_per_taxel_cm2']:.2f} cm^2/taxel")
    if r.get("taxels_per_24cm"):
        out.append(f"{r['taxels_per_24cm']:.1f} taxels per 24 cm")
    return out
