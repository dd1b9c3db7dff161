"""A model, an encoder, a layout and a noise model from a package outside sphri (tests/plugin_example/labext:
one module and one YAML each; the encoder carries no ``res``) run in a job; the model is exported to a model
file, loaded back and run live on the skin simulator streaming that chain's readings, with no edit to sphri;
the file names its class, which sphri imports only from a package the reader lists in ``plugins``."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import forked_cli
import numpy as np
import pytest

from sphri.export.model_file import ModelFileError, inspect_model, load_model
from sphri.types import GESTURES

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "tests" / "plugin_example"
SMALL = ["+debug=fast", "data.participants=2", "data.repetitions=1"]


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    """The example lab package and its config folder, copied outside the repository."""
    root = tmp_path_factory.mktemp("plugin_model")
    shutil.copytree(EXAMPLE, root / "lab")
    return root / "lab"


def _overrides(lab: Path, out: Path) -> list[str]:
    return [
        *SMALL,
        "plugins=[labext]",
        f"hydra.searchpath=[file://{lab / 'conf'}]",
        "model=prototype",
        "encoder=nearest",
        "layout=vertices",
        "noise=dropout",
        f"output_dir={out}",
    ]


def test_a_plugin_model_exports_loads_and_runs_live(lab, tmp_path, monkeypatch, capsys):
    from skin_sim import live_on_simulator

    from sphri.export.train import fit_bundle, training_windows
    from sphri.hardware.sim_skin import SkinSimSettings, pipeline_stream
    from sphri.hardware.skin import main as skin_main
    from sphri.hardware.source import open_pipeline

    overrides = _overrides(lab, tmp_path / "out")
    model_path = tmp_path / "proto.sphrimodel"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(lab), str(REPO)])}

    def python_m(*args: str) -> subprocess.CompletedProcess:  # forked: the lab's module imported in the child
        return forked_cli.run(["-m", *args], tmp_path, env, 600)

    job = python_m("sphri", *overrides, "tracking.enabled=false")  # a job cross-validates it like any model
    assert job.returncode == 0, (job.stdout + job.stderr)[-3000:]
    assert "model       lab_prototype, LOSO over 2 folds" in job.stdout and "accuracy    " in job.stdout
    export = python_m("sphri", "export", f"out={model_path}", *overrides)
    assert export.returncode == 0, (export.stdout + export.stderr)[-3000:]
    assert "saved NearestPrototype (16 windows" in export.stdout

    # the file names the class; without plugins=[labext] it is refused before anything is imported
    head = inspect_model(model_path)["estimator"]
    assert head["kind"] == "lab_prototype" and head["class"] == "labext.prototype:NearestPrototype"
    for name in [m for m in sys.modules if m == "labext" or m.startswith("labext.")]:
        monkeypatch.delitem(sys.modules, name)
    with pytest.raises(ModelFileError, match=r"proto\.sphrimodel: .*'labext'.*plugins=\[labext\]"):
        load_model(model_path)
    assert "labext" not in sys.modules
    assert skin_main(["live", "port=socket://127.0.0.1:9", f"model={model_path}"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "model file error" in err[0] and "plugins=[labext]" in err[0]
    with pytest.raises(ModelFileError, match="not listed in plugins"):  # listing one package trusts no other
        load_model(model_path, plugins=["other"])

    # loaded back: the same predictions as the model fitted here on the same windows
    monkeypatch.syspath_prepend(str(lab))
    bundle = load_model(model_path, plugins=["labext"])
    assert type(bundle.estimator).__module__ == "labext.prototype"
    p = open_pipeline(overrides)
    windows = training_windows(p)
    fresh = fit_bundle(p)
    np.testing.assert_array_equal(bundle.predict_proba(windows.x), fresh.predict_proba(windows.x))
    assert bundle.window_length == windows.x.shape[1] and bundle.n_taxels == windows.x.shape[2]

    # live on the skin simulator streaming the same trials: every trial is detected and named
    stream = pipeline_stream(overrides, 4, "participant_01", 0.5, 0)
    sim_settings = SkinSimSettings(port="socket://127.0.0.1:0", realtime=False, hold_s=30.0)
    pred = tmp_path / "pred.jsonl"
    lines: list[str] = []
    summary, sim = live_on_simulator(
        stream,
        sim_settings,
        model_path,
        lines.append,
        plugins=["labext"],
        out=str(pred),
        stride=10,
        show="off",
        persist=1,  # dropout noise only turns taxels off: one frame on is a touch (no false touch possible)
    )
    assert summary["error"] is None and summary["frames"] == sim.ledger.good == len(stream.values)
    assert lines[0].startswith("model NearestPrototype:")
    rows = [json.loads(r) for r in pred.read_text().splitlines()]
    assert rows and all(r["gesture"] in GESTURES for r in rows)
    touches = [r for r in rows if r["kind"] == "touch"]
    for trial in sim.ledger.trials:
        assert any(trial["good_start"] <= t["start"] < trial["good_end"] for t in touches), trial


@pytest.mark.slow
def test_a_plugin_model_is_served_as_an_mlflow_pyfunc_model(lab, tmp_path, monkeypatch):
    """The pyfunc model of a job that lists plugins=[labext] loads its plugin model (model_config)."""
    import io
    from contextlib import redirect_stdout

    import mlflow

    from sphri.export import train
    from sphri.hardware.source import open_pipeline

    monkeypatch.syspath_prepend(str(lab))
    overrides = _overrides(lab, tmp_path / "out")
    text = io.StringIO()
    with redirect_stdout(text):
        assert train.main([f"out={tmp_path / 'proto.sphrimodel'}", "mlflow=true", *overrides]) == 0
    uri = next(ln.split("model=")[1] for ln in text.getvalue().splitlines() if "model=runs:/" in ln)
    windows = train.training_windows(open_pipeline(overrides))
    bundle = load_model(tmp_path / "proto.sphrimodel", plugins=["labext"])
    before = mlflow.get_tracking_uri()
    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'out' / 'mlflow.db'}")
    try:
        served = mlflow.pyfunc.load_model(uri)
    finally:
        mlflow.set_tracking_uri(before)
    names = served.predict(windows.x.astype(np.float32))
    want = np.asarray(bundle.labels)[np.argmax(bundle.predict_proba(windows.x), axis=1)]
    np.testing.assert_array_equal(names, want)
