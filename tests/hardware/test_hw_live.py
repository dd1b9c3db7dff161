"""Live classification: the sliding/touch logic, model files, and `skin live` against the simulator."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sphri.export.model_file import ModelBundle, ModelFileError, inspect_model, load_model, save_model
from sphri.hardware.live import LiveClassifier, auto_stride
from sphri.hardware.sim_skin import SkinSimSettings, pattern_stream
from tests.hardware.skin_sim import live_on_simulator  # importable from tests/fuzz too


class Recorder:
    """Stub estimator: remembers the windows it saw; class = window's first-frame activity > 0."""

    classes_ = np.arange(8)

    def __init__(self):
        self.seen: list[np.ndarray] = []

    def predict_proba(self, x):
        self.seen.append(np.array(x))
        p = np.full((len(x), 8), 0.01)
        p[:, 1] = 0.5
        return p


def stub_bundle(geometry, length=10) -> ModelBundle:
    return ModelBundle(Recorder(), geometry, length, 90.0)


def test_sliding_windows_every_stride(make_geometry):
    b = stub_bundle(make_geometry(3, 2), length=10)
    clf = LiveClassifier(b, stride=4, onset_activity=100.0, cluster_taxels=0)  # no touches
    frames = np.random.default_rng(0).random((30, 6)).astype(np.float32)
    preds = [p for f in frames for p in clf.push(f)]
    assert [p.frame for p in preds] == [9, 13, 17, 21, 25, 29]
    assert all(p.kind == "window" and p.gesture == "pat" for p in preds)
    for p, x in zip(preds, b.estimator.seen):
        np.testing.assert_array_equal(x[0], frames[p.frame - 9 : p.frame + 1])
    assert all(p.latency_ms >= p.compute_ms >= 0 for p in preds)


def test_touch_window_starts_at_the_onset_despite_noise(make_geometry):
    rng = np.random.default_rng(1)
    n, length = 200, 20
    frames = (rng.random((n, 24)) < 0.02).astype(np.float32)  # flickering noise
    frames[60:110, 5:8] = 1.0  # a touch held for 50 frames
    frames[150:158, 20] = 1.0  # a short one-taxel poke
    b = stub_bundle(make_geometry(6, 4), length=length)
    clf = LiveClassifier(b, stride=1000, calibrate_frames=40, release_frames=5)
    preds = [p for f in frames for p in clf.push(f)]
    touches = [p for p in preds if p.kind == "touch"]
    assert [p.start for p in touches] == [60, 150]
    assert [p.frame for p in touches] == [60 + length - 1, 150 + length - 1]
    np.testing.assert_array_equal(b.estimator.seen[preds.index(touches[0])][0], frames[60:80])
    assert clf.threshold is not None and clf.threshold < 1.0


def test_a_long_touch_is_classified_once_and_rearms_after_release(make_geometry):
    frames = np.zeros((120, 6), dtype=np.float32)
    frames[10:70, 0] = 1.0
    frames[90:100, 1] = 1.0
    clf = LiveClassifier(stub_bundle(make_geometry(3, 2), 10), stride=1000, onset_activity=0.5, release_frames=5)
    touches = [p for f in frames for p in clf.push(f) if p.kind == "touch"]
    assert [p.start for p in touches] == [10, 90]


def test_wrong_frame_shape_is_refused(make_geometry):
    clf = LiveClassifier(stub_bundle(make_geometry(3, 2)), stride=2)
    with pytest.raises(ValueError, match=r"\(6,\)"):
        clf.push(np.zeros(7))


def test_auto_stride_gives_at_least_ten_per_second():
    for rate in (30.0, 60.0, 90.0, 120.0):
        assert rate / auto_stride(rate) >= 10.0


# ------------------------------------------------------------------ model files
def small_rf(geometry, length=20, seed=0):
    from sphri.models.rf import RandomForest

    rng = np.random.default_rng(seed)
    x = (rng.random((40, length, geometry.n_taxels)) < 0.1).astype(np.float32)
    y = np.arange(40) % 8
    return RandomForest(n_estimators=10, n_jobs=1, seed=seed, geometry=geometry).fit(x, y)


def test_model_file_round_trip(tmp_path, make_geometry):
    geo = make_geometry(18, 6)
    model = small_rf(geo)
    bundle = ModelBundle(model, geo, 20, 90.0, meta={"model": "rf", "n_train": 40})
    path = save_model(bundle, tmp_path / "m" / "rf.sphrimodel")
    head = inspect_model(path)
    assert head["window_length"] == 20 and head["n_taxels"] == 108 and head["grid_shape"] == [18, 6]
    back = load_model(path)
    x = (np.random.default_rng(3).random((3, 20, 108)) < 0.1).astype(np.float32)
    np.testing.assert_allclose(back.predict_proba(x), model.predict_proba(x))
    assert back.meta["n_train"] == 40 and back.labels[0] == "hit"


def test_model_file_errors(tmp_path, make_geometry):
    geo = make_geometry(18, 6)
    path = save_model(ModelBundle(small_rf(geo), geo, 20, 90.0), tmp_path / "rf.sphrimodel")
    blob = bytearray(path.read_bytes())
    blob[-10] ^= 0xFF
    bad = tmp_path / "bad.sphrimodel"
    bad.write_bytes(bytes(blob))
    with pytest.raises(ModelFileError, match="checksum"):
        load_model(bad)
    other = tmp_path / "other.pkl"
    other.write_bytes(b"\x80\x05junk")
    with pytest.raises(ModelFileError, match="not a sphri model"):
        load_model(other)
    with pytest.raises(ModelFileError, match="not found"):
        load_model(tmp_path / "nope.sphrimodel")
    with pytest.raises(ModelFileError, match="predict_proba"):
        save_model(ModelBundle(object(), geo, 20, 90.0), tmp_path / "x.sphrimodel")


def test_predict_proba_maps_a_subset_of_classes(make_geometry):
    class Two:
        classes_ = np.array([2, 5])

        def predict_proba(self, x):
            return np.tile([0.3, 0.7], (len(x), 1))

    p = ModelBundle(Two(), make_geometry(2, 2), 5, 90.0).predict_proba(np.zeros((1, 5, 4)))
    assert p.shape == (1, 8) and p[0, 5] == pytest.approx(0.7) and p[0, 2] == pytest.approx(0.3)


# ------------------------------------------------------------------ live against the simulator
def test_live_against_the_simulator_rate_and_touches(tmp_path, make_geometry):
    """Every streamed touch is detected once; predictions keep up (>= 10 per second) at 90 Hz."""
    geo = make_geometry(18, 6)
    model_path = save_model(ModelBundle(small_rf(geo, length=30), geo, 30, 90.0), tmp_path / "rf.sphrimodel")
    frames = 500
    sim_settings = SkinSimSettings(
        port="socket://127.0.0.1:0", source="pattern", frames=frames, seed=2, realtime=True, rate_hz=90.0, hold_s=2.0
    )
    stream = pattern_stream((18, 6), frames, 2)
    out = tmp_path / "pred.jsonl"
    lines: list[str] = []
    summary, sim = live_on_simulator(stream, sim_settings, model_path, lines.append, out=str(out))
    assert summary["error"] is None and summary["frames"] == frames
    records = [json.loads(ln) for ln in out.read_text().splitlines()]
    touches = [r for r in records if r["kind"] == "touch"]
    blobs = sim.ledger.trials
    assert len(touches) == len(blobs)
    for t, b in zip(touches, blobs):
        assert abs(t["start"] - b["good_start"]) <= 1, (t, b)
    windows = [r for r in records if r["kind"] == "window"]
    assert len(windows) >= (frames - 30) // auto_stride(90.0)
    # the rates and latencies are measured against their goals by bench/bench_hardware.py, not asserted here
    assert np.isfinite(summary["latency_ms_median"]) and summary["capacity_predictions_per_s"] > 0
    assert any(ln.startswith("TOUCH") for ln in lines)


def test_live_fills_lost_frames_to_keep_the_timing(tmp_path, make_geometry):
    """With 8 % of the frames lost, touches still start where they do in the stream's own timeline."""
    geo = make_geometry(18, 6)
    model_path = save_model(ModelBundle(small_rf(geo, length=30), geo, 30, 90.0), tmp_path / "rf.sphrimodel")
    frames = 420
    sim_settings = SkinSimSettings(
        port="socket://127.0.0.1:0",
        source="pattern",
        frames=frames,
        seed=3,
        realtime=False,
        hold_s=30.0,
        drop_rate=0.05,
        corrupt_rate=0.03,
    )
    stream = pattern_stream((18, 6), frames, 3)
    out = tmp_path / "pred.jsonl"
    summary, sim = live_on_simulator(stream, sim_settings, model_path, out=str(out), stride=50, show="off")
    led = sim.ledger
    assert summary["frames"] == led.good and led.dropped + led.corrupt > 10
    assert summary["filled_frames"] == summary["decoder"]["seq_missing"] > 10
    touches = [r for r in map(json.loads, out.read_text().splitlines()) if r["kind"] == "touch"]
    starts = [int(np.flatnonzero(stream.trial == k)[0]) for k in range(len(led.trials))]
    assert len(touches) == len(starts)
    for t, s in zip(touches, starts):
        assert 0 <= t["start"] - s <= 1, (t["start"], s)
