"""bench/cnn_gru_curve_device.py: the CNN-GRU evaluated outside a sweep, one JSON entry per resolution,
compared participant by participant with a CPU sweep's MLflow store."""

from __future__ import annotations

import json
import re
import sys
import time
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

from cnn_gru_curve_device import compare, main, readings_key, run, stages  # noqa: E402

TINY = ["+debug=fast", "cv.max_folds=1", "cv.progress=false"]


def test_run_writes_each_resolution_keeps_them_past_its_budget_and_keys_the_windows_by_content(tmp_path: Path):
    out = tmp_path / "curve.json"
    doc = run([2], TINY, out, budget_s=float("inf"), cache_dir=str(tmp_path / "cache"))
    saved = json.loads(out.read_text())
    assert saved == json.loads(json.dumps(doc))
    entry = saved["results"]["2"]
    assert len(entry["folds"]) == 1 and 0.0 <= entry["summary"]["accuracy_mean"] <= 1.0
    assert "layout.res=2" in entry["overrides"] and "tracking.enabled=false" in entry["overrides"]
    assert re.fullmatch(r"[0-9a-f]{20}", entry["windows_content_key"]), entry["windows_content_key"]
    assert saved["machine"]["cpu_count"] >= 1 and entry["machine"] == saved["machine"]
    assert not (tmp_path / "curve.json.partial").exists()
    # a budget already spent starts nothing and loses nothing already written
    run([3], TINY, out, budget_s=-1.0, cache_dir=str(tmp_path / "cache"))
    again = json.loads(out.read_text())
    assert set(again["results"]) == {"2"} and again["results"]["2"] == entry
    # the same config from another (empty) cache: the same windows, so the same key, and the same fold
    other = run([2], TINY, tmp_path / "other.json", float("inf"), str(tmp_path / "cache2"))["results"]["2"]
    assert other["windows_content_key"] == entry["windows_content_key"] and other["folds"] == entry["folds"]
    assert re.fullmatch(r"[0-9a-f]{20}", entry["readings_key"]) and other["readings_key"] == entry["readings_key"]
    # `stages` (from the run's cache) names every stage up to the windows, with the run's keys at its end
    keys = stages(2, TINY, str(tmp_path / "cache"))
    assert {"data", "contact", "surface", "layout", "encode", "noise", "readings"} <= set(keys)
    assert "evaluate" not in keys
    assert keys["noise"] == entry["windows_content_key"] and keys["readings"] == entry["readings_key"]


def test_readings_key_hashes_text_not_object_identity_and_sees_one_changed_reading():
    from types import SimpleNamespace

    import numpy as np

    x = np.zeros((3, 2, 4), np.float32)
    y = np.array([0, 1, 2])

    def groups() -> np.ndarray:  # the same names as new string objects (a loaded dataset's, another process's)
        return np.array(["".join(["participant_", str(i)]) for i in (1, 1, 2)], dtype=object)

    a, b = groups(), groups()
    assert a[0] is not b[0]
    key = readings_key(SimpleNamespace(x=x, y=y, groups=a))
    assert readings_key(SimpleNamespace(x=x.copy(), y=y.copy(), groups=b)) == key
    x2 = x.copy()
    x2[2, 1, 3] = 1.0
    assert readings_key(SimpleNamespace(x=x2, y=y, groups=a)) != key


def _store(out: Path, jobs: dict[tuple[str, int], dict[str, float]]) -> None:
    """FINISHED job runs with per-participant accuracies as sphri's tracker logs them."""
    from mlflow.entities import Metric, Param
    from mlflow.tracking import MlflowClient

    from sphri.tracking.mlflow_tracker import default_uri

    client = MlflowClient(default_uri(out))
    exp = client.create_experiment("sphri")
    now = int(time.time() * 1000)
    for (model, res), people in jobs.items():
        r = client.create_run(exp, tags={"sphri.kind": "job"})
        metrics = [Metric(f"participant/{p}/accuracy", a, now, 0) for p, a in people.items()]
        params = [Param("model", model), Param("layout.res", str(res))]
        client.log_batch(r.info.run_id, metrics=metrics, params=params)
        client.set_terminated(r.info.run_id, "FINISHED")
    parent = client.create_run(exp, tags={"sphri.kind": "sweep"})  # no model or res: left out
    client.set_terminated(parent.info.run_id, "FINISHED")


def _device(path: Path, results: dict[int, dict[str, float]]) -> Path:
    doc = {
        "machine": {"gpu": "test GPU"},
        "results": {
            str(r): {"folds": [{"fold": p, "n_test": 10, "accuracy": a, "macro_f1": a} for p, a in people.items()]}
            for r, people in results.items()
        },
    }
    path.write_text(json.dumps(doc))
    return path


def test_compare_pairs_participants_and_lists_the_accelerators_own_points(tmp_path: Path):
    _store(
        tmp_path,
        {
            ("cnn_gru", 8): {"p1": 0.5, "p2": 0.7, "p3": 0.6},
            ("rf", 8): {"p1": 0.4, "p2": 0.5, "p3": 0.45},
            ("rf", 40): {"p1": 0.6, "p2": 0.6, "p3": 0.6},
        },
    )
    dev = _device(
        tmp_path / "dev.json", {8: {"p1": 0.52, "p2": 0.72, "p3": 0.62}, 40: {"p1": 0.7, "p2": 0.8, "p3": 0.6}}
    )
    fig = tmp_path / "fig.png"
    c = compare(tmp_path, dev, fig)
    (row,) = c["shared_resolutions"]
    assert row["res"] == 8 and row["n"] == 3
    assert row["cpu"] == pytest.approx(0.6) and row["device"] == pytest.approx(0.62)
    assert row["diff"] == pytest.approx(0.02) and row["max_abs_paired_diff"] == pytest.approx(0.02)
    assert c["paired"]["n"] == 3 and c["paired"]["mean_diff"] == pytest.approx(0.02)
    assert c["paired"]["ci95"] == pytest.approx([0.02, 0.02])
    assert c["device_only"] == {"40": pytest.approx(0.7)}
    assert c["device_machine"] == {"gpu": "test GPU"}
    assert fig.is_file() and fig.stat().st_size > 1000


def test_missing_inputs_are_one_line(tmp_path: Path):
    with pytest.raises(SystemExit, match="no accelerator results at"):
        compare(tmp_path, tmp_path / "none.json", None)
    dev = _device(tmp_path / "dev.json", {8: {"p1": 0.5}})
    with pytest.raises(SystemExit, match=r"no MLflow store at .*mlflow\.db"):
        compare(tmp_path / "nowhere", dev, None)
    with pytest.raises(SystemExit):
        main(["run", "40,fifty"])
    broken = tmp_path / "broken.json"
    broken.write_text('{"results": {"8": ')  # a file cut short by hand: refused, and left as it was
    with pytest.raises(SystemExit, match=r"broken\.json is not this script's JSON"):
        run([2], TINY, broken, float("inf"), str(tmp_path / "cache"))
    assert broken.read_text() == '{"results": {"8": '
