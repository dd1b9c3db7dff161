"""Acceptance: `skin live` names streamed synthetic gestures like the model does offline (slow)."""

from __future__ import annotations

import json

import numpy as np
import pytest

#: 6 participants x 3 repetitions x 8 gestures of synthetic data, Reachy's arm at the default resolution.
DATA = ["+debug=fast", "data.participants=6", "data.repetitions=3", "model.n_jobs=1"]


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    from sphri.config import register_schemas

    register_schemas()
    return tmp_path_factory.mktemp("hw_acceptance")


def stream_live(overrides, participant, model_path, out_dir):
    """Stream ``participant``'s trials from the simulator into `skin live`; (ledger, first touch per trial)."""
    from sphri.hardware.settings import SkinLiveSettings
    from sphri.hardware.sim_skin import SkinSimSettings, SkinSimulator, pipeline_stream
    from sphri.hardware.skin import live
    from sphri.hardware.transport import make_endpoint, start_in_thread

    stream = pipeline_stream(overrides, -1, participant, 0.5, 0)
    settings = SkinSimSettings(port="socket://127.0.0.1:0", realtime=False, hold_s=60.0)
    sim = SkinSimulator(stream, settings, make_endpoint(settings), say=lambda m: None)
    th = start_in_thread(sim)
    pred = out_dir / f"{participant}.jsonl"
    try:
        summary = live(
            SkinLiveSettings(
                port=sim.endpoint.url, model=str(model_path), idle_s=60.0, out=str(pred), stride=30, show="off"
            ),
            out=lambda m: None,
            until=sim.finished.is_set,
        )
    finally:
        sim.stop.set()
        th.join(10)
    assert summary["error"] is None and summary["frames"] == len(stream.values)
    touches = [r for r in map(json.loads, pred.read_text().splitlines()) if r["kind"] == "touch"]
    first = {}
    for k, trial in enumerate(sim.ledger.trials):
        mine = [t for t in touches if trial["good_start"] <= t["start"] < trial["good_end"]]
        first[k] = mine[0] if mine else None
    return sim.ledger, first


@pytest.mark.slow
def test_live_classifies_streamed_synthetic_gestures(out_dir):
    from sphri.export.model_file import save_model
    from sphri.export.train import fit_bundle, training_windows
    from sphri.hardware.source import open_pipeline

    overrides = [*DATA, f"output_dir={out_dir}"]
    p = open_pipeline(overrides)
    windows = training_windows(p)

    # a model trained on every participant: live must reproduce its labels on a participant's trials
    seen = fit_bundle(p, None, overrides)
    seen_path = save_model(seen, out_dir / "all.sphrimodel")
    ledger, first = stream_live(overrides, "participant_02", seen_path, out_dir)
    n = len(ledger.trials)
    detected = sum(t is not None for t in first.values())
    right = sum(t is not None and t["gesture"] == tr["gesture"] for t, tr in zip(first.values(), ledger.trials))
    assert n == 24 and detected >= 22
    assert right >= 0.75 * n, f"{right} of {n} streamed trials classified right"

    # a participant the model never saw: live agrees with the model's offline predictions on its windows
    held = fit_bundle(p, "participant_06", overrides)
    held_path = save_model(held, out_dir / "holdout.sphrimodel")
    ledger, first = stream_live(overrides, "participant_06", held_path, out_dir)
    agree = right = right_offline = 0
    aligned = []
    for t, tr in zip(first.values(), ledger.trials):
        rows = np.flatnonzero(windows.trial_row == tr["row"])
        offline = held.labels[int(held.estimator.predict(windows.x[rows])[0])]
        agree += t is not None and t["gesture"] == offline
        right += t is not None and t["gesture"] == tr["gesture"]
        right_offline += offline == tr["gesture"]
        if t is not None and t["start"] == tr["good_onset"]:
            aligned.append((t["gesture"], offline))
    # where live finds the onset the offline window starts at, it sees the same noisy frames
    # (the simulator streams the model's own noise draws): it must name the same gesture
    assert len(aligned) >= 0.6 * len(ledger.trials), f"live found the offline onset in {len(aligned)} trials"
    assert all(live_g == off_g for live_g, off_g in aligned), aligned
    assert agree >= 0.75 * len(ledger.trials), f"live agrees with offline on {agree} of {len(ledger.trials)}"
    # live names an unseen participant's gestures about as well as the model does offline
    # (how well that is, at this tiny training set, is the model's business, not live's)
    assert abs(right - right_offline) <= 2, (right, right_offline)
