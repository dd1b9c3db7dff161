"""A job logs its model as an MLflow pyfunc model: `mlflow.pyfunc.load_model("runs:/<id>/model")`
predicts gesture names on windows, the registry serves it as `models:/<name>/<version>`, and
`skin live` resolves both URIs to the same model file (no pickle on the way)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import forked_cli
import numpy as np
import pytest

from sphri.types import GESTURES

REPO = Path(__file__).resolve().parents[1]
DATA = ["+debug=fast", "encoder.res=4"]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}


@pytest.fixture(scope="module")
def logged(tmp_path_factory) -> tuple[Path, str, list[str], list[str]]:
    """(output_dir, run id, the three runs' stdout, their stderr) of a debug job recorded first without its model, then
    run again with ``tracking.log_model=true tracking.register_model=gestures`` (the model is logged into
    the recorded run and registered as `gestures`), then a third time with ``tracking.log_model=true``."""
    tmp = tmp_path_factory.mktemp("model_run")
    out = tmp / "out"
    args = ["-m", "sphri", *DATA, f"output_dir={out}"]
    runs, errs = [], []
    for flags in (
        ["tracking.log_model=false"],
        ["tracking.log_model=true", "tracking.register_model=gestures"],
        ["tracking.log_model=true"],
    ):
        job = forked_cli.run([*args, *flags], tmp, _env(), 600)
        assert job.returncode == 0, (job.stdout + job.stderr)[-3000:]
        runs.append(job.stdout)
        errs.append(job.stderr)
    status = json.loads(min(out.glob("runs/*/*/sphri_status.json")).read_text())  # the first run's
    return out, status["mlflow_run_id"], runs, errs


def test_logged_model_loads_with_pyfunc_in_a_fresh_process_and_predicts_on_windows(logged, tmp_path):
    from sphri.hardware.source import open_pipeline
    from sphri.hardware.train_export import training_windows
    from sphri.tracking.mlflow_tracker import default_uri

    out, run_id, _, _ = logged
    windows = training_windows(open_pipeline([*DATA, f"output_dir={out}"]))
    np.save(tmp_path / "x.npy", windows.x[:6].astype(np.float32))
    code = (
        "import json, sys, mlflow, numpy as np\n"
        f"mlflow.set_tracking_uri({default_uri(out)!r})\n"
        f"model = mlflow.pyfunc.load_model('runs:/{run_id}/model')\n"
        f"x = np.load({str(tmp_path / 'x.npy')!r})\n"
        "print(json.dumps({'labels': model.predict(x).tolist(),"
        " 'shape': list(model.metadata.get_input_schema().inputs[0].shape)}))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=300, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["shape"] == [-1, windows.x.shape[1], windows.x.shape[2]]  # the signature: (n, L, N) windows
    assert len(got["labels"]) == 6 and set(got["labels"]) <= set(GESTURES)

    # the same labels as sphri's own loader gives for the model file inside that MLflow model
    from sphri.hardware.model_file import load_model, resolve_model_path

    bundle = load_model(resolve_model_path(f"runs:/{run_id}/model", default_uri(out), allow_remote=True))
    mine = np.asarray(bundle.labels)[bundle.predict_proba(windows.x[:6]).argmax(1)]
    assert got["labels"] == mine.tolist()


def test_registered_model_resolves_for_skin_live_only_when_remote_is_allowed(logged):
    from sphri.hardware.model_file import ModelFileError, load_model, resolve_model_path
    from sphri.tracking.mlflow_tracker import default_uri

    out, _, _, _ = logged
    uri = default_uri(out)
    path = resolve_model_path("models:/gestures/1", uri, allow_remote=True)
    assert path.suffix == ".sphrimodel" and load_model(path).window_length == 50
    with pytest.raises(ModelFileError, match="allow_remote=true"):
        resolve_model_path("models:/gestures/1", uri)
    with pytest.raises(ModelFileError, match="models:/nope/1"):
        resolve_model_path("models:/nope/1", uri, allow_remote=True)


def test_register_model_needs_log_model():
    from sphri.config import ConfigError, compose

    with pytest.raises(ConfigError, match="tracking.register_model"):
        compose(["+debug=fast", "tracking.log_model=false", "tracking.register_model=x"])


def test_the_run_lists_its_model_and_the_model_names_installable_requirements(logged):
    from mlflow import MlflowClient

    from sphri import __version__
    from sphri.tracking.mlflow_tracker import MlflowTracker, default_uri

    out, run_id, _, _ = logged
    client = MlflowClient(default_uri(out))
    run = client.get_run(run_id)
    (output,) = run.outputs.model_outputs  # MLflow's logged model, linked to the run
    assert MlflowTracker().logged_models(str(out), run_id) == [f"models:/{output.model_id}"]
    reqs = next(out.glob("mlartifacts/**/requirements.txt")).read_text().split()
    assert f"sphri=={__version__}" in reqs  # the model's code imports sphri
    assert any(r.startswith("torch==") for r in reqs) and not any("+" in r for r in reqs)  # no local labels


def test_log_model_on_an_already_recorded_config_logs_it_or_says_where_it_is(logged):
    """A config first recorded without its model, run again with tracking.log_model=true, gets its model
    logged into the recorded run; a third run says the model is already there (never silently nothing)."""
    runs = logged[2]
    assert "model " not in runs[0].split("model       rf")[-1]
    assert "already recorded" in runs[1] and "model       logged runs:/" in runs[1]
    assert "model       model already logged in that run: models:/" in runs[2]


def test_logging_a_model_shows_no_download_bar(logged):
    """MLflow reads the logged model back to check its input example and drew a "Downloading artifacts"
    progress bar on the job's console for that (nothing is downloaded); the job turns MLflow's artifact
    bars off, unless MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR is set."""
    runs, errs = logged[2], logged[3]
    assert "model       logged runs:/" in runs[1]  # the second run logged its model
    assert "Downloading artifacts" not in runs[1] + errs[1], errs[1][-2000:]
