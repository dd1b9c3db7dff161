"""MLflow tracking: one run per job, one parent per sweep, failures recorded."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import forked_cli
import numpy as np
import pytest

from sphri.config import build, compose
from sphri.pipeline import RunResult, StageRecord
from sphri.testing.runs import toy_meta
from sphri.tracking.mlflow_tracker import MlflowTracker, default_uri, flatten_params, summary_text
from sphri.types import CVResult, FoldResult

REPO = Path(__file__).resolve().parent.parent


def fake_result() -> RunResult:
    rng = np.random.default_rng(0)
    folds = []
    for i in range(3):
        conf = rng.integers(0, 5, size=(8, 8))
        acc = float(np.trace(conf) / conf.sum())
        folds.append(
            FoldResult(f"participant_0{i + 1}", int(conf.sum()), acc, acc * 0.9, conf, np.diag(conf) / conf.sum(1))
        )
    return RunResult(
        CVResult("loso", "rf", folds), toy_meta(), {"contact": StageRecord("contact", "k", "cache", 0.1)}, "abc123"
    )


def test_default_store_is_absolute_sqlite(tmp_path: Path):
    uri = default_uri("outputs")
    assert uri.startswith("sqlite:////") and uri.endswith("outputs/mlflow.db")


def test_log_job_writes_params_tags_metrics_artifacts(tmp_path: Path):
    from mlflow.tracking import MlflowClient

    cfg = compose([f"output_dir={tmp_path}"])
    tracker = MlflowTracker()
    run_id = tracker.log_job(cfg, fake_result(), tmp_path / "job")
    client = MlflowClient(default_uri(tmp_path))
    run = client.get_run(run_id)
    assert run.info.status == "FINISHED"
    assert run.data.tags["sphri.synthetic"] == "true"
    assert run.data.tags["sphri.config_hash"] == "abc123"
    assert run.data.params["layout.res"] == "18"
    assert run.data.params["robot"] not in ("", "?")  # the class name when no Hydra choice is known
    assert "resolution.pitch_u_mm" in run.data.params
    assert len(run.data.params) < 120, "params are curated, not the whole config"
    assert 0 <= run.data.metrics["accuracy_mean"] <= 1
    history = client.get_metric_history(run_id, "fold_accuracy")
    assert sorted(m.step for m in history) == [0, 1, 2]
    names = {a.path for a in client.list_artifacts(run_id)}
    assert {"config.yaml", "per_participant.csv", "confusion.csv", "confusion.png", "summary.txt"} <= names
    assert "SYNTHETIC" in summary_text(fake_result())
    # tracking.confusion_png=false: the counts stay (the report redraws from them), the PNG is not drawn
    cfg_no_png = compose([f"output_dir={tmp_path}", "tracking.confusion_png=false"])
    quiet = build(cfg_no_png.tracking)  # the tracker a job builds from its config
    names = {a.path for a in client.list_artifacts(quiet.log_job(cfg_no_png, fake_result(), tmp_path / "job2"))}
    assert "confusion.csv" in names and "per_participant.csv" in names and "confusion.png" not in names


def test_failure_is_recorded(tmp_path: Path):
    from mlflow.tracking import MlflowClient

    cfg = compose([f"output_dir={tmp_path}"])
    run_id = MlflowTracker().log_failure(cfg, ValueError("bad thing"), tmp_path)
    run = MlflowClient(default_uri(tmp_path)).get_run(run_id)
    assert run.info.status == "FAILED"
    assert "bad thing" in run.data.tags["sphri.error"]
    assert run.info.run_name == "reachy-arm-res18-RandomForest (failed)"  # named after the job, not "failed"


def test_two_jobs_logging_the_same_dataset_at_once_both_finish(tmp_path: Path, monkeypatch):
    """Two parallel jobs of a sweep into a new store log the same dataset input: both look it up, find
    nothing, and insert it; the second insert fails on the datasets' unique key (seen in CI). Replayed
    here exactly: job 1 logs the dataset, then job 2's lookup is made to miss it once (as it did while
    job 1 had not committed yet), so its insert hits the real IntegrityError; the retry finds the row."""
    from mlflow.store.tracking.dbmodels.models import SqlDataset
    from mlflow.tracking import MlflowClient
    from sqlalchemy.orm import Query

    cfg = compose([f"output_dir={tmp_path}", "tracking.artifacts=false"])
    tracker = build(cfg.tracking)
    first = tracker.log_job(cfg, fake_result(), tmp_path / "job0")
    real_all, missed = Query.all, []

    def lookup_misses_once(query):
        if not missed and query.column_descriptions[0]["entity"] is SqlDataset:
            missed.append(True)
            return []
        return real_all(query)

    monkeypatch.setattr(Query, "all", lookup_misses_once)
    second = tracker.log_job(cfg, fake_result(), tmp_path / "job1")
    assert missed, "the replay did not reach MLflow's dataset lookup"
    client = MlflowClient(default_uri(tmp_path))
    for run_id in (first, second):
        run = client.get_run(run_id)
        assert run.info.status == "FINISHED"
        assert [d.dataset.name for d in run.inputs.dataset_inputs] == [fake_result().meta.dataset]


def test_params_are_flat_scalars():
    params = flatten_params(compose([]), {"robot": "reachy"})
    assert params["robot"] == "reachy"
    assert all(isinstance(v, str) for v in params.values())
    assert not any(k.endswith("_target_") for k in params)


def _sphri(args: list[str], cwd: Path, timeout: int = 600) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "HYDRA_FULL_ERROR": "1"}
    return forked_cli.run(["-m", "sphri", *args], cwd, env, timeout)


def test_parallel_multirun_makes_one_parent_with_four_children(tmp_path: Path):
    from mlflow.tracking import MlflowClient

    out = tmp_path / "outputs"
    proc = _sphri(
        [
            "-m",
            "+robot=reachy",
            "+debug=fast",
            "layout.res=1,2,3,4",
            f"output_dir={out}",
            "hydra/launcher=local",
            "hydra.launcher.n_jobs=2",
        ],
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    client = MlflowClient(default_uri(out))
    exp = client.get_experiment_by_name("sphri-debug")
    runs = client.search_runs([exp.experiment_id])
    parents = [r for r in runs if r.data.tags.get("sphri.kind") == "sweep"]
    children = [r for r in runs if r.data.tags.get("sphri.kind") == "job"]
    assert len(parents) == 1
    assert parents[0].info.status == "FINISHED"
    assert len(children) == 4
    assert all(c.data.tags["mlflow.parentRunId"] == parents[0].info.run_id for c in children)
    assert all(c.info.status == "FINISHED" for c in children)
    assert sorted(c.data.params["layout.res"] for c in children) == ["1", "2", "3", "4"]
    assert "4 of 4 jobs finished" in proc.stdout
    # the parent carries the sweep's params (swept values as given, shared settings) and source tags
    parent = parents[0].data
    assert parent.params["layout.res"] == "1,2,3,4" and parent.params["model"] and parent.params["seed"]
    assert parent.tags["mlflow.user"] and parent.tags["mlflow.source.git.commit"] and parent.tags["sphri.version"]


def test_failed_job_is_recorded_and_sweep_goes_on(tmp_path: Path, failing_mesh_sweep):
    """A job failing at run time (a mesh file that is not a mesh) is a FAILED run; the other job still runs."""
    from mlflow.tracking import MlflowClient

    out = tmp_path / "outputs"
    proc = _sphri([*failing_mesh_sweep, f"output_dir={out}"], cwd=tmp_path)
    assert proc.returncode == 1, "a sweep with a failed job exits non-zero: " + proc.stderr[-2000:]
    client = MlflowClient(default_uri(out))
    runs = client.search_runs([client.get_experiment_by_name("sphri-debug").experiment_id])
    jobs = sorted((r for r in runs if r.data.tags.get("sphri.kind") == "job"), key=lambda r: r.info.status)
    assert [r.info.status for r in jobs] == ["FAILED", "FINISHED"]
    assert "arm.obj" in jobs[0].data.tags["sphri.error"]
    assert "1 of 2 jobs finished" in proc.stdout and "FAILED: #1" in proc.stdout
    assert "job(s) failed: #1" in proc.stderr, "the exit names the failed job"
    parents = [r for r in runs if r.data.tags.get("sphri.kind") == "sweep"]
    assert len(parents) == 1 and parents[0].info.status == "FAILED", "a sweep with a failed job is never left RUNNING"


# A rerun of a sweep (same sweep dir, or a new timestamped one) skips its finished jobs into the same parent:
# tests/test_sweeps_store.py::test_rerun_of_a_sweep_skips_finished_jobs_into_its_parent


def test_ui_hint_names_the_store(tmp_path, monkeypatch):
    from sphri.tracking.mlflow_tracker import ui_hint

    monkeypatch.chdir(tmp_path)  # no Makefile here: `make ui` would not work
    uri = f"sqlite:///{tmp_path / 'outputs' / 'mlflow.db'}"
    assert ui_hint(uri) == f"mlflow ui --backend-store-uri {uri}"
    (tmp_path / "Makefile").write_text("ui:\n\tmlflow ui --backend-store-uri sqlite:///$(CURDIR)/outputs/mlflow.db\n")
    assert ui_hint(uri) == "make ui"
    assert ui_hint(f"sqlite:///{tmp_path / 'other' / 'mlflow.db'}").startswith("mlflow ui --backend-store-uri")


def test_job_run_has_standard_source_tags_debug_experiment_and_derived_metrics(tmp_path):
    """MLflow's own source fields are filled, debug runs go to their own experiment, pitch and area are metrics."""
    import subprocess
    import sys

    from mlflow.tracking import MlflowClient

    job = subprocess.run(
        [sys.executable, "-m", "sphri", "+debug=fast", f"output_dir={tmp_path}"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert job.returncode == 0, job.stderr[-2000:]
    client = MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}")
    assert client.get_experiment_by_name("sphri") is None
    exp = client.get_experiment_by_name("sphri-debug")
    (run,) = client.search_runs([exp.experiment_id])
    tags, metrics = run.data.tags, run.data.metrics
    # MLflow's tag providers ran (as in mlflow.start_run): user, source, commit of this checkout
    assert tags["mlflow.user"] and tags["mlflow.source.type"] == "LOCAL"
    assert tags["mlflow.source.name"].endswith("__main__.py") and tags["sphri.debug"] == "true"
    assert len(tags["mlflow.source.git.commit"]) == 40 and tags["sphri.git_commit"].startswith(
        tags["mlflow.source.git.commit"]
    )
    (data,) = run.inputs.dataset_inputs  # the dataset as an MLflow input, keyed by the data stage's content key
    assert data.dataset.name == "synthetic" and data.dataset.digest and data.dataset.source_type == "code"
    assert {t.key: t.value for t in data.tags}["mlflow.data.context"] == "training"
    assert metrics["resolution/pitch_u_mm"] > 0 and metrics["resolution/area_per_taxel_cm2"] > 0
    # the machine and libraries (issue 31), for the Random Forest too: CPU, no torch imported
    from sphri.tracking.machine import cpu

    assert tags["sphri.machine.cpu_model"] == cpu()["cpu_model"] and tags["sphri.lib.scikit-learn"][0].isdigit()
    assert run.data.params["run.device"] == "cpu" and tags["sphri.evaluated"] == "in this run"


def test_a_cnn_gru_job_records_device_precision_cpu_and_torch(tmp_path):
    """Issue 31: model.device=auto (the default) is recorded as the device it resolved to, with the
    precision, the CPU model and SIMD flags and the torch version."""
    from importlib import metadata

    import torch
    from mlflow.tracking import MlflowClient

    from sphri.models.cnn_gru import choose_precision
    from sphri.tracking.machine import cpu

    job = _sphri(
        [
            "+debug=fast",
            "model=cnn_gru",
            "layout.res=3",
            "model.max_epochs=1",
            "cv.max_folds=1",
            f"output_dir={tmp_path}",
        ],
        cwd=tmp_path,
    )
    assert job.returncode == 0, job.stderr[-2000:]
    client = MlflowClient(tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}")
    (run,) = client.search_runs([client.get_experiment_by_name("sphri-debug").experiment_id])
    params, tags = run.data.params, run.data.tags
    device = "cuda" if torch.cuda.is_available() else "cpu"
    assert params["model.device"] == "auto" and params["run.device"] == device
    # the precision the folds trained with, and why (auto on this grid: bf16 only where known safe)
    grid = tuple(int(v) for v in params["resolution.grid_shape"].strip("()").split(","))
    precision, why = choose_precision("auto", torch.device(device), grid, [2, 2, 1])
    assert (params["run.precision"], params["run.precision_reason"]) == (precision, why)
    here = cpu()
    assert tags["sphri.machine.cpu_model"] == here["cpu_model"] and tags["sphri.machine.cpu_flags"] == here["cpu_flags"]
    assert tags["sphri.lib.torch"] == metadata.version("torch") and tags["sphri.lib.python"]
    assert tags["sphri.machine.gpu"] == (torch.cuda.get_device_name(0) if device == "cuda" else "none")


@pytest.mark.slow  # `make test-all` (about 40 s, most of it the server starting): `make test` logs to SQLite stores
def test_a_job_logged_to_a_real_mlflow_server_reads_back_over_rest(tmp_path):
    """`mlflow server` on loopback, a job with tracking.uri=http://...: the run read back over MLflow's REST
    API has MLflow's own tags (user, commit), its dataset input and its logged model, and its artifacts
    live where the server keeps them (not in the job's output folder)."""
    import socket
    import time
    import urllib.request

    from mlflow.tracking import MlflowClient

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    uri = f"http://127.0.0.1:{port}"
    mlflow_bin = Path(sys.executable).with_name("mlflow")
    from sphri.tracking.store import ensure_store

    ensure_store(f"sqlite:///{tmp_path / 'server.db'}")  # a migrated store, as sphri makes its own: no migration wait
    server = subprocess.Popen(
        [
            str(mlflow_bin),
            "server",
            "--backend-store-uri",
            f"sqlite:///{tmp_path / 'server.db'}",
            "--artifacts-destination",
            str(tmp_path / "server-artifacts"),
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--workers",
            "1",
        ],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    try:
        for _ in range(180):
            try:
                if urllib.request.urlopen(f"{uri}/health", timeout=2).read() == b"OK":
                    break
            except OSError:
                time.sleep(1)
        else:
            raise AssertionError("mlflow server did not answer in 180 s")
        job = subprocess.run(
            [
                sys.executable,
                "-m",
                "sphri",
                "+debug=fast",
                "layout.res=4",
                f"tracking.uri={uri}",
                "tracking.log_model=true",
                f"output_dir={tmp_path / 'out'}",
            ],
            capture_output=True,
            text=True,
            cwd=tmp_path,
            timeout=600,
        )
        assert job.returncode == 0, (job.stdout + job.stderr)[-3000:]
        assert f"open {uri}" in job.stdout
        client = MlflowClient(uri)
        (run,) = client.search_runs([client.get_experiment_by_name("sphri-debug").experiment_id])
        tags = run.data.tags
        assert tags["mlflow.user"] and len(tags["mlflow.source.git.commit"]) == 40
        assert [d.dataset.name for d in run.inputs.dataset_inputs] == ["synthetic"]
        assert len(run.outputs.model_outputs) == 1
        assert not run.info.artifact_uri.startswith("file:"), run.info.artifact_uri
        assert not (tmp_path / "out" / "mlartifacts").exists()
    finally:
        import os
        import signal

        os.killpg(server.pid, signal.SIGTERM)
        try:  # gunicorn's workers may take longer than 30 s to stop on a loaded machine: then kill them
            server.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait(30)
