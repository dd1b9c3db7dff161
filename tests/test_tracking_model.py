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
DATA = ["+debug=fast", "layout.res=4"]


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
    from sphri.export.train import training_windows
    from sphri.hardware.source import open_pipeline
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
    from sphri.export.model_file import load_model, resolve_model_path

    bundle = load_model(resolve_model_path(f"runs:/{run_id}/model", default_uri(out), allow_remote=True))
    mine = np.asarray(bundle.labels)[bundle.predict_proba(windows.x[:6]).argmax(1)]
    assert got["labels"] == mine.tolist()


def test_registered_model_resolves_for_skin_live_only_when_remote_is_allowed(logged):
    from sphri.export.model_file import ModelFileError, load_model, resolve_model_path
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
    model = next(out.glob("mlartifacts/**/requirements.txt")).parent
    reqs = (model / "requirements.txt").read_text().split()
    assert not any(r.startswith("sphri") for r in reqs)  # no index serves sphri: its code travels with the model
    code = model / "code" / "sphri"
    assert (code / "__init__.py").read_text().count(f'__version__ = "{__version__}"') == 1
    assert (code / "conf" / "config.yaml").is_file()  # the config tree sphri.config reads on import
    assert not list(code.rglob("__pycache__"))
    assert "scikit-learn==" in " ".join(reqs) and not any("+" in r for r in reqs)  # no local labels
    assert not any("torch" in r for r in reqs)  # a Random Forest's model needs no torch


def test_a_torch_model_names_torch_from_its_cpu_index_and_a_forest_does_not():
    from sphri.export.train import TORCH_CPU_INDEX, requirements
    from sphri.models.cnn_gru import CnnGru
    from sphri.models.rf import RandomForest

    forest = requirements(RandomForest.__new__(RandomForest))
    net = requirements(CnnGru.__new__(CnnGru))
    assert not any("torch" in r for r in forest)
    assert net[0] == f"--extra-index-url {TORCH_CPU_INDEX}"  # PyPI's Linux torch pulls the CUDA libraries
    assert any(r.startswith("torch==") and "+" not in r for r in net)
    assert [r for r in net if "torch" not in r] == forest


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.slow
def test_the_forest_model_serves_from_a_fresh_environment_built_from_its_requirements(logged, tmp_path):
    """The steps docs/how-to/mlflow.md gives: a new venv (no system site-packages, no sphri), `pip install -r`
    the model's requirements.txt from the package index, `mlflow.pyfunc.load_model` and `mlflow models serve
    --env-manager local` answer with gesture names. About 80 s of the test is pip (2 shared AMD EPYC cores,
    2026-12-01)."""
    import time
    import urllib.request

    out = logged[0]
    model = next(out.glob("mlartifacts/**/requirements.txt")).parent
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = os.pathsep.join([str(venv / "bin"), env.get("PATH", "")])
    py = str(venv / "bin" / "python")
    assert subprocess.run([py, "-c", "import sphri"], env=env, cwd=tmp_path, capture_output=True).returncode == 1
    pip = subprocess.run(
        [py, "-m", "pip", "install", "-q", "-r", str(model / "requirements.txt")],
        env=env, cwd=tmp_path, capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert pip.returncode == 0, pip.stderr[-3000:]
    code = (
        "import json, sys, mlflow, numpy as np\n"
        f"model = mlflow.pyfunc.load_model({str(model)!r})\n"
        f"x = np.asarray(json.load(open({str(model / 'input_example.json')!r})), dtype=np.float32)\n"
        "assert x.ndim == 3, x.shape\n"
        "print(json.dumps({'labels': model.predict(np.concatenate([x, x])).tolist(),"
        " 'torch': 'torch' in sys.modules}))\n"
    )
    proc = subprocess.run([py, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert len(got["labels"]) == 2 and set(got["labels"]) <= set(GESTURES) and got["torch"] is False

    port = _free_port()
    server = subprocess.Popen(
        ["mlflow", "models", "serve", "-m", str(model), "--env-manager", "local", "-h", "127.0.0.1", "-p", str(port)],
        env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        body = (model / "serving_input_example.json").read_bytes()
        request = urllib.request.Request(
            f"http://127.0.0.1:{port}/invocations", data=body, headers={"Content-Type": "application/json"}
        )
        deadline, answer = time.monotonic() + 120, None
        while answer is None and time.monotonic() < deadline and server.poll() is None:
            try:
                with urllib.request.urlopen(request, timeout=10) as r:
                    answer = json.loads(r.read())
            except OSError:
                time.sleep(1)
    finally:
        server.terminate()
        log = server.communicate(timeout=60)[0]
    assert answer is not None, log[-3000:]
    (label,) = answer["predictions"]
    assert label in GESTURES


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
