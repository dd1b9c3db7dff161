"""Recordings that survive (issue 16, item 4): the output path is checked before a byte is read,
frames are on disk while recording (a SIGKILL keeps them), and a failure at the end saves elsewhere."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np
import pytest
from skin_sim import record_in_child, wait_for_frames

from sphri.hardware.recording import RecordingError, load_recording
from sphri.hardware.settings import SkinRecordSettings
from sphri.hardware.sim_skin import SkinSimSettings, SkinSimulator, pattern_stream
from sphri.hardware.skin import main as skin_main
from sphri.hardware.skin import record
from sphri.hardware.skin_protocol import ValueFormat, quantize
from sphri.hardware.transport import make_endpoint, start_in_thread


def _simulator(frames: int, **kw):
    settings = SkinSimSettings(
        source="pattern",
        port="socket://127.0.0.1:0",
        frames=frames,
        seed=2,
        **{"realtime": False, "hold_s": 30.0, **kw},
    )
    stream = pattern_stream((18, 6), frames, 2)
    sim = SkinSimulator(stream, settings, make_endpoint(settings), say=lambda m: None)
    return sim, stream, start_in_thread(sim)


def _bad_outputs(tmp_path: Path) -> dict[str, Path]:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    (tmp_path / "a_dir").mkdir()
    return {
        "proc": Path("/proc/rec.npz"),
        "directory": tmp_path / "a_dir",
        "under_a_file": a_file / "rec.npz",
    }


@pytest.mark.parametrize("case", ["proc", "directory", "under_a_file"])
def test_unwritable_output_fails_before_reading(tmp_path, case):
    out = _bad_outputs(tmp_path)[case]
    sim, _, th = _simulator(50)
    try:
        with pytest.raises(RecordingError, match=str(out).replace(".", r"\.")):
            record(SkinRecordSettings(port=sim.endpoint.url, out=str(out), frames=10), out=lambda m: None)
    finally:
        sim.stop.set()
        th.join(10)
    assert sim.ledger.starts == 0 and sim.ledger.bytes_sent == 0  # the port was never opened


def test_unwritable_output_is_one_clean_line_from_the_command(tmp_path, capsys):
    assert skin_main(["record", "port=socket://127.0.0.1:9", "out=/proc/rec.npz"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "/proc/rec.npz" in err[0] and "Traceback" not in err[0]


def test_killed_mid_recording_keeps_the_frames_read_so_far(tmp_path, frames_on_disk):
    want = 40
    sim, stream, th = _simulator(20_000, realtime=True, rate_hz=200.0)
    out = tmp_path / "rec.npz"
    proc = record_in_child(sim, out, tmp_path, "chunk_frames=5")
    partial = out.with_name(out.name + ".partial")
    try:
        wait_for_frames(proc, partial, want, frames_on_disk)
        proc.send_signal(signal.SIGKILL)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
        sim.stop.set()
        th.join(10)
    assert not out.exists()
    rec = load_recording(partial)
    assert rec.n_frames >= want and rec.grid_shape == (18, 6)
    # the frames on disk are the first ones the skin sent, intact
    np.testing.assert_array_equal(rec.seq, np.arange(rec.n_frames))
    np.testing.assert_array_equal(
        rec.values, quantize(stream.values[: rec.n_frames], ValueFormat.BITS).astype(np.float32)
    )


def test_a_failure_at_the_end_saves_to_a_fallback_in_the_working_directory(tmp_path, monkeypatch):
    """The output folder disappears while recording: the frames go to the working directory."""
    import shutil

    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    sim, stream, th = _simulator(60)
    out = tmp_path / "gone" / "rec.npz"
    lines: list[str] = []

    def say(msg: str) -> None:
        lines.append(msg)
        if msg.startswith("recording "):  # the partial file is open: remove the folder under it
            shutil.rmtree(out.parent)
            out.parent.write_text("now a file")

    try:
        summary = record(SkinRecordSettings(port=sim.endpoint.url, out=str(out), frames=30), out=say)
    finally:
        sim.stop.set()
        th.join(10)
    saved = Path(summary["path"])
    assert saved.parent == work and summary["frames"] == 30 and summary["error"]
    assert load_recording(saved).n_frames == 30
    assert any(str(saved) in ln and "30 frames" in ln for ln in lines)


def test_a_full_disk_while_recording_stops_and_keeps_every_frame_read(tmp_path, monkeypatch):
    """The second chunk's fsync fails with ENOSPC: the first chunk stays in the partial file, and all
    frames read so far are saved at the end."""
    import errno

    import sphri.hardware.recording as recording

    calls = {"n": 0}
    real_fsync = os.fsync

    def fsync(fd):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_fsync(fd)

    monkeypatch.setattr(recording.os, "fsync", fsync)
    sim, stream, th = _simulator(200)
    out = tmp_path / "rec.npz"
    try:
        summary = record(
            SkinRecordSettings(port=sim.endpoint.url, out=str(out), frames=100, chunk_frames=10), out=lambda m: None
        )
    finally:
        sim.stop.set()
        th.join(10)
    assert "No space left" in summary["error"] and "after 10 frames" in summary["error"]
    rec = load_recording(out)
    assert rec.n_frames == 20  # the recorder stopped at the failed chunk, with every frame it had read
    np.testing.assert_array_equal(rec.seq, np.arange(20))
