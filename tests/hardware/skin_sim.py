"""The skin simulator recorded by ``sphri.hardware.skin.record``: the helper the skin tests share."""

from __future__ import annotations

import numpy as np

from sphri.hardware.recording import load_recording
from sphri.hardware.settings import SkinRecordSettings
from sphri.hardware.sim_skin import SkinSimSettings, SkinSimulator, pattern_stream
from sphri.hardware.skin import record
from sphri.hardware.skin_protocol import ValueFormat, quantize
from sphri.hardware.transport import make_endpoint, start_in_thread


def run_record(tmp_path, sim_kw: dict, rec_kw: dict | None = None, frames: int = 400, seed: int = 1):
    """Start a pattern-source skin simulator, record from it, return (ledger, summary, recording, stream)."""
    settings = SkinSimSettings(
        source="pattern", frames=frames, seed=seed, **{"realtime": False, "hold_s": 3.0, **sim_kw}
    )
    stream = pattern_stream((18, 6), frames, seed)
    sim = SkinSimulator(stream, settings, make_endpoint(settings), say=lambda m: None)
    th = start_in_thread(sim)
    out = tmp_path / "rec.npz"
    lines: list[str] = []
    try:
        # stops when the simulator says every frame was sent and read (an event); idle_s only guards against a hang
        summary = record(
            SkinRecordSettings(
                port=sim.endpoint.url, out=str(out), **{"idle_s": 60.0, "grid": "18x6", **(rec_kw or {})}
            ),
            out=lines.append,
            until=sim.finished.is_set,
        )
    finally:
        sim.stop.set()
        th.join(10)
    return sim.ledger, summary, load_recording(out), stream, lines


def check_good_frames_kept(ledger, rec, stream) -> None:
    assert rec.n_frames == ledger.good
    np.testing.assert_array_equal(rec.seq, ledger.good_seq)
    sent = stream.values[ledger.good_index]
    np.testing.assert_array_equal(rec.values, quantize(sent, ValueFormat.BITS).astype(np.float32))
