"""Fit the configured model on the configured pipeline's windows and save a model file.

::

    sphri export out=outputs/models/rf.sphrimodel +robot=reachy layout.res=18
    sphri export out=m.sphrimodel holdout=participant_03 +debug=fast mlflow=true

The windows are exactly those the cross-validation sees (data, contact,
layout, encoder, noise and window stages, all cached), but the model is fit
once on every kept trial (minus ``holdout``'s). The file
(:mod:`sphri.export.model_file`) carries the estimator, the skin's
geometry, the window length and frame rate, for ``skin live``.
"""

from __future__ import annotations

import datetime as _dt
import logging
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sphri.args import settings_main
from sphri.config import CONF_DIR, ConfigError, Schema, check_output_file, compose, require
from sphri.export.model_file import ModelBundle, save_model
from sphri.layout.schema import layout_res
from sphri.types import GESTURES, WindowedFrames

log = logging.getLogger(__name__)


@dataclass
class TrainExportSettings(Schema):
    """Fit the configured model on the configured pipeline's windows and save a model file (every
    ``key=value`` that is not a setting below is a config override, e.g. +debug=fast)."""

    out: str = "???"
    """Model file to write, e.g. outputs/models/rf.sphrimodel."""
    holdout: str | None = None
    """Participant left out of training (to try the model live on their trials)."""
    mlflow: bool = False
    """Also log the file as an artifact (model/<name>) of a new MLflow run."""
    overwrite: bool = False
    """Replace an existing file at out (refused otherwise); the file is replaced whole, atomically."""

    def check(self) -> None:
        require(self.out not in ("", "???"), "out", self.out, "an output path, e.g. out=model.sphrimodel")


def training_windows(pipeline) -> WindowedFrames:
    """The pipeline's windows as the CV sees them: plan, encode, assemble, noise, filter."""
    return pipeline.get("filter")


def fit_bundle(pipeline, holdout: str | None = None, overrides: Sequence[str] = ()) -> ModelBundle:
    """Fit ``cfg.model`` on all windows (except ``holdout``'s participant) -> :class:`ModelBundle`."""
    from sphri.pipeline import config_hash, model_factory

    cfg = pipeline.cfg
    windows = training_windows(pipeline)
    train = np.ones(len(windows.y), dtype=bool)
    if holdout is not None:
        train = windows.groups != holdout
        if train.all():
            raise ConfigError(
                f"holdout={holdout!r} is invalid: no such participant among {sorted(set(windows.groups))}"
            )
    if train.sum() < 2 or len(np.unique(windows.y[train])) < 2:
        raise ConfigError("the pipeline gives fewer than two gestures to train on; use more data (data.participants)")
    model = model_factory(cfg)(geometry=windows.geometry)  # the chain's model, as its evaluation makes it
    model.fit(windows.x[train], windows.y[train])
    acc = float(np.mean(model.predict(windows.x[train]) == windows.y[train]))
    dataset = pipeline.get("data")
    meta = {
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "model": str(cfg.model._target_).rsplit(".", 1)[-1],
        "overrides": list(overrides),
        "config_hash": config_hash(cfg),
        "n_train": int(train.sum()),
        "train_accuracy": acc,
        "holdout": holdout,
        "participants": sorted(set(windows.groups[train].tolist())),
        "dataset": dataset.name,
        "region": list(cfg.data.regions)[0],
        "encoder": str(cfg.encoder._target_).rsplit(".", 1)[-1],
        "encoder_res": layout_res(cfg),
    }
    log.info("trained %s on %d windows (train accuracy %.3f)", meta["model"], meta["n_train"], acc)
    return ModelBundle(model, windows.geometry, int(windows.x.shape[1]), float(dataset.frame_rate_hz), GESTURES, meta)


def log_pyfunc_model(
    tracking_uri: str, run_id: str, bundle: ModelBundle, pipeline, registered_name: str | None = None
) -> str:
    """Log ``bundle`` into run ``run_id`` as an MLflow pyfunc model (artifact ``model``) with a signature
    and ``pipeline``'s first window ((1, L, N) float32) as its input example; register it as
    ``registered_name`` if given. Returns its ``runs:/`` URI.

    The model is :mod:`sphri.export.pyfunc_model` (MLflow "models from code") with the ``.sphrimodel``
    file as its artifact: loading it unpickles nothing. The job's ``plugins``: packages whose model class
    the pyfunc model may import back when it loads the file (stored in its ``model_config``).
    """
    import tempfile

    import mlflow
    from mlflow.models import infer_signature

    from sphri.export import pyfunc_model
    from sphri.tracking.mlflow_tracker import no_artifact_bars

    example = np.asarray(training_windows(pipeline).x[:1], dtype=np.float32)
    plugins = pipeline.cfg.get("plugins") or ()
    labels = np.asarray(bundle.labels)[np.argmax(bundle.predict_proba(example), axis=1)]
    no_artifact_bars()  # MLflow reads the logged model back to check the input example
    mlflow.set_tracking_uri(tracking_uri)
    with tempfile.TemporaryDirectory(prefix="sphri-model-") as tmp:
        path = save_model(bundle, Path(tmp) / "model.sphrimodel")
        code = _sphri_code(Path(tmp) / "code")
        with mlflow.start_run(run_id=run_id):
            mlflow.pyfunc.log_model(
                name="model",
                python_model=pyfunc_model.__file__,
                artifacts={pyfunc_model.ARTIFACT: str(path)},
                code_paths=[str(code)],  # sphri itself travels with the model: no index serves it
                signature=infer_signature(example, labels),
                input_example=example,
                registered_model_name=registered_name,
                model_config={"plugins": [str(x) for x in plugins]},
                pip_requirements=requirements(bundle.estimator),  # stated, not inferred (see requirements)
            )
    return f"runs:/{run_id}/model"


#: The libraries loading a sphri model file imports (sphri's config reads hydra's; the Random Forest's
#: file is read with skops), besides torch for a model built on it.
LOAD_LIBRARIES = ("mlflow", "numpy", "scipy", "scikit-learn", "skops", "hydra-core", "omegaconf")
#: The index of torch's CPU-only builds: PyPI's Linux torch wheels pull the CUDA libraries.
TORCH_CPU_INDEX = "https://download.pytorch.org/whl/cpu"


def _sphri_code(dest: Path) -> Path:
    """A copy of the installed ``sphri`` package (no byte code) under ``dest``, for MLflow's ``code_paths``:
    the logged model carries the code that reads it, so serving it needs no sphri install."""
    import shutil

    import sphri

    src = Path(sphri.__file__).resolve().parent
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(src, dest / "sphri", ignore=skip)
    if not (dest / "sphri" / "conf").is_dir():  # a checkout's config tree, where a wheel keeps it
        shutil.copytree(CONF_DIR, dest / "sphri" / "conf", ignore=skip)
    return dest / "sphri"


def uses_torch(estimator: Any) -> bool:
    """Whether ``estimator``'s class (or a base class) is defined in a module that imports torch."""
    for cls in type(estimator).__mro__:
        mod = sys.modules.get(cls.__module__)
        for value in vars(mod).values() if mod is not None else ():
            if getattr(value, "__name__", "").split(".")[0] == "torch" and type(value).__name__ == "module":
                return True
    return False


def requirements(estimator: Any) -> list[str]:
    """What loading the pyfunc model of ``estimator`` needs from an index, pinned to the releases that
    wrote it: :data:`LOAD_LIBRARIES`, and torch only for a model built on torch, from its CPU index
    (``--extra-index-url``; PyPI's own Linux torch pulls CUDA). sphri is not among them: it travels with
    the model (``code_paths``). Local version labels (``torch==2.13.0+cpu``) are dropped: the CPU index
    serves ``2.13.0+cpu`` for ``torch==2.13.0`` on Linux and the plain release elsewhere."""
    from importlib.metadata import PackageNotFoundError, version

    libs = [*LOAD_LIBRARIES, "torch"] if uses_torch(estimator) else list(LOAD_LIBRARIES)
    out = [f"--extra-index-url {TORCH_CPU_INDEX}"] if "torch" in libs else []
    for dist in libs:
        try:
            out.append(f"{dist}=={version(dist).split('+', 1)[0]}")
        except PackageNotFoundError:
            out.append(dist)
    return out


def log_to_mlflow(pipeline, bundle: ModelBundle) -> str:
    """Log ``bundle`` as the pyfunc model ``model`` of a new run; returns its ``runs:/`` URI."""
    from mlflow import MlflowClient

    from sphri import build

    tracker = build(pipeline.cfg.tracking)
    uri = tracker.resolve_uri(pipeline.cfg.output_dir)
    client = MlflowClient(tracking_uri=uri)
    exp = tracker.experiment_id(pipeline.cfg.output_dir)
    run = client.create_run(
        exp, run_name=f"train_export {bundle.meta.get('model', 'model')}", tags={"sphri.kind": "model_export"}
    )
    model_uri = log_pyfunc_model(uri, run.info.run_id, bundle, pipeline)
    client.set_terminated(run.info.run_id)
    return model_uri


def log_job_model(cfg, run_id: str, registered_name: str | None = None) -> str:
    """Fit the job's model on every participant's windows (from the stage cache the job just filled)
    and log it into the job's run ``run_id`` as a pyfunc model; returns its ``runs:/`` URI."""
    from sphri import build, make_pipeline, open_cache

    p = make_pipeline(cfg, open_cache(cfg))
    bundle = fit_bundle(p, None)
    return log_pyfunc_model(build(cfg.tracking).resolve_uri(cfg.output_dir), run_id, bundle, p, registered_name)


#: The settings of ``sphri export`` (no command word; other ``key=value`` are config overrides).
COMMANDS = {"": (TrainExportSettings, True)}


@settings_main("sphri export", COMMANDS)
def main(_cmd: str, settings: TrainExportSettings, overrides: list[str]) -> int:
    """``sphri export out=FILE ... [overrides ...]``."""
    from sphri.pipeline import make_pipeline, open_cache

    cfg = compose(overrides)  # an invalid override: one line from @clean_errors, exit 2
    # before training: a folder or a file in the way is one line, not lost work (or a replaced model)
    check_output_file(settings.out, overwrite=settings.overwrite)
    p = make_pipeline(cfg, open_cache(cfg))
    bundle = fit_bundle(p, settings.holdout, overrides)
    check_output_file(settings.out, overwrite=settings.overwrite)  # a file that appeared while training
    path = save_model(bundle, settings.out)  # through a temporary file beside it and a rename: whole
    print(
        f"saved {bundle.meta['model']} ({bundle.meta['n_train']} windows, train accuracy "
        f"{bundle.meta['train_accuracy']:.3f}; {bundle.n_taxels} taxels, L={bundle.window_length}) to {path}"
    )
    if settings.mlflow:
        print(f"logged to MLflow: model={log_to_mlflow(p, bundle)}")
    return 0
