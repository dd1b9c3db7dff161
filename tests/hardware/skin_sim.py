"""The skin simulator read by ``sphri.hardware.skin.record`` and ``live``: the helpers the skin tests share."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from sphri.hardware.recording import load_recording
from sphri.hardware.settings import SkinLiveSettings, SkinRecordSettings
from sphri.hardware.sim_skin import SkinSimSettings, SkinSimulator, pattern_stream
from sphri.hardware.skin import live, record
from sphri.hardware.skin_protocol import ValueFormat, quantize
from sphri.hardware.transport import make_endpoint, start_in_thread


def run_record(tmp_path, sim_kw: dict, rec_kw: dict | None = None, frames: int = 400, seed: int = 1):
    """Start a pattern-source skin simulator, record from it, return (ledger, summary, recording, stream)."""
    settings = SkinSimSettings(
        source="pattern", frames=frames, seed=seed, **{"realtime": False, "hold_s": 3.0, **sim_kw}
    )
    stream = pattern_stream((18, 6), frames, seed)
    out = tmp_path / "rec.npz"
    lines: list[str] = []
    with skin_simulator(stream, settings) as sim:
        # stops when the simulator says every frame was sent and read (an event); idle_s only guards against a hang
        summary = record(
            SkinRecordSettings(
                port=sim.endpoint.url, out=str(out), **{"idle_s": 60.0, "grid": "18x6", **(rec_kw or {})}
            ),
            out=lines.append,
            until=sim.finished.is_set,
        )
    return sim.ledger, summary, load_recording(out), stream, lines


@contextmanager
def skin_simulator(stream, settings: SkinSimSettings) -> Iterator[SkinSimulator]:
    """A skin simulator sending ``stream`` from a thread, stopped and joined on leaving."""
    sim = SkinSimulator(stream, settings, make_endpoint(settings), say=lambda m: None)
    th = start_in_thread(sim)
    try:
        yield sim
    finally:
        sim.stop.set()
        th.join(10)


def live_on_simulator(stream, settings: SkinSimSettings, model_path, say=lambda m: None, **live_kw):
    """`skin live` with ``model_path`` (settings ``live_kw``, ``idle_s=60`` unless given) on a skin simulator
    sending ``stream`` until it has sent every frame; (summary, simulator)."""
    with skin_simulator(stream, settings) as sim:
        summary = live(
            SkinLiveSettings(port=sim.endpoint.url, model=str(model_path), **{"idle_s": 60.0, **live_kw}),
            out=say,
            until=sim.finished.is_set,
        )
    return summary, sim


REPO = Path(__file__).resolve().parents[2]


def record_in_child(sim, out, cwd, *settings: str, stdout=subprocess.DEVNULL) -> subprocess.Popen:
    """``python -m sphri skin record`` from ``sim`` into ``out`` (grid 18x6 and ``settings``,
    key=value) in a child process, its stderr piped."""
    env = {**os.environ, "PYTHONPATH": f"{REPO}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    cmd = [sys.executable, "-m", "sphri", "skin", "record", f"port={sim.endpoint.url}", f"out={out}", "grid=18x6"]
    return subprocess.Popen([*cmd, *settings], cwd=cwd, env=env, stdout=stdout, stderr=subprocess.PIPE)


def wait_for_frames(proc: subprocess.Popen, partial, want: int, frames_on_disk) -> int:
    """Wait until ``want`` frames are on disk in ``partial`` while the recorder ``proc`` runs (event-driven,
    a generous cap only against a hang); how many are."""
    deadline = time.monotonic() + 120
    while (on_disk := frames_on_disk(partial)) < want:
        assert proc.poll() is None, proc.stderr.read().decode()
        assert time.monotonic() < deadline, "the recorder wrote no frames"
        time.sleep(0.02)
    return on_disk


def check_good_frames_kept(ledger, rec, stream) -> None:
    assert rec.n_frames == ledger.good
    np.testing.assert_array_equal(rec.seq, ledger.good_seq)
    sent = stream.values[ledger.good_index]
    np.testing.assert_array_equal(rec.values, quantize(sent, ValueFormat.BITS).astype(np.float32))
