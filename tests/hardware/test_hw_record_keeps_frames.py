"""A recorder that keeps every good frame (issue 29, item 1).

Reproducers of the issue: a glitched first frame set the taxel count (``grid=18x6`` ignored) and made
the recorder refuse almost every good frame; an existing ``out`` was replaced; SIGTERM lost the
recording; ``.partial`` held only whole chunks of ``chunk_frames``.
"""

from __future__ import annotations

import os
import signal
import stat
import subprocess
from pathlib import Path

import numpy as np
import pytest
from skin_sim import check_good_frames_kept, record_in_child, run_record, wait_for_frames

from sphri.hardware.recording import PartialWriter, RecordingError, SkinRecording, load_recording, save_recording
from sphri.hardware.settings import SkinRecordSettings
from sphri.hardware.sim_skin import SkinSimSettings, SkinSimulator, pattern_stream
from sphri.hardware.skin import main as skin_main
from sphri.hardware.skin import record
from sphri.hardware.skin_protocol import ValueFormat, quantize
from sphri.hardware.transport import make_endpoint, start_in_thread

#: with this seed and wrong_count_rate=0.05 the simulator's FIRST frame carries a wrong taxel count
#: (the issue's reproducer: ``simulate skin ... grid=18x6 frames=300 seed=34 wrong_count_rate=0.05``)
GLITCHED_FIRST_SEED = 34
SOCKET = "socket://127.0.0.1:0"


@pytest.mark.parametrize("rec_kw", [{"grid": "18x6"}, {"grid": ""}], ids=["grid_given", "consensus"])
def test_a_glitched_first_frame_costs_no_good_frame(tmp_path, rec_kw):
    ledger, summary, rec, stream, _ = run_record(
        tmp_path, {"port": SOCKET, "wrong_count_rate": 0.05}, rec_kw, 300, GLITCHED_FIRST_SEED
    )
    assert ledger.good_index[0] == 1 and ledger.good_seq[0] == 1  # the first frame sent was a wrong-count one
    assert ledger.wrong_count >= 5
    check_good_frames_kept(ledger, rec, stream)
    assert rec.n_taxels == 108
    assert rec.grid_shape == ((18, 6) if rec_kw["grid"] else None)
    assert summary["error"] is None
    assert summary["decoder"]["wrong_count"] == ledger.wrong_count
    assert summary["decoder"]["frames"] == ledger.good


def test_a_stream_shorter_than_the_consensus_is_saved(tmp_path):
    """Fewer frames than a consensus needs: the held frames are released at the end, none lost."""
    ledger, summary, rec, stream, _ = run_record(tmp_path, {"port": SOCKET}, {"grid": ""}, 3, 5)
    assert ledger.good == 3
    check_good_frames_kept(ledger, rec, stream)


def _small_recording(n: int = 5) -> SkinRecording:
    rng = np.random.default_rng(0)
    return SkinRecording(
        rng.random((n, 108)).astype(np.float32),
        np.arange(n, dtype=float),
        np.arange(n),
        np.arange(n),
        np.zeros(n),
        (18, 6),
        {},
    )


def test_an_existing_recording_is_never_replaced(tmp_path):
    out = save_recording(_small_recording(300), tmp_path / "rec.npz")
    before = out.read_bytes()
    settings = SkinSimSettings(
        source="pattern", port="socket://127.0.0.1:0", frames=50, seed=2, realtime=False, hold_s=30.0
    )
    sim = SkinSimulator(pattern_stream((18, 6), 50, 2), settings, make_endpoint(settings), say=lambda m: None)
    th = start_in_thread(sim)
    try:
        with pytest.raises(RecordingError, match=r"exists and is never replaced.*out=.*rec-2\.npz"):
            record(SkinRecordSettings(port=sim.endpoint.url, out=str(out), frames=40, grid="18x6"), out=lambda m: None)
    finally:
        sim.stop.set()
        th.join(10)
    assert sim.ledger.starts == 0 and sim.ledger.bytes_sent == 0  # refused before the port was opened
    assert out.read_bytes() == before
    assert not out.with_name("rec.npz.partial").exists()


def test_an_existing_recording_is_one_line_from_the_command(tmp_path, capsys):
    out = save_recording(_small_recording(), tmp_path / "rec.npz")
    assert skin_main(["record", "port=socket://127.0.0.1:9", f"out={out}"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and "never replaced" in err[0] and "Traceback" not in err[0]
    assert load_recording(out).n_frames == 5


def test_a_file_appearing_at_out_while_recording_is_not_replaced(tmp_path, monkeypatch):
    """Another process writes ``out`` during the recording: the frames go to the fallback file instead."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "rec.npz"
    settings = SkinSimSettings(
        source="pattern", port="socket://127.0.0.1:0", frames=40, seed=2, realtime=False, hold_s=30.0
    )
    sim = SkinSimulator(pattern_stream((18, 6), 40, 2), settings, make_endpoint(settings), say=lambda m: None)
    th = start_in_thread(sim)

    def say(msg: str) -> None:
        if msg.startswith("recording "):
            out.write_bytes(b"someone else's file")

    try:
        summary = record(SkinRecordSettings(port=sim.endpoint.url, out=str(out), frames=30, grid="18x6"), out=say)
    finally:
        sim.stop.set()
        th.join(10)
    assert out.read_bytes() == b"someone else's file"
    saved = Path(summary["path"])
    assert saved != out and saved.parent == tmp_path and load_recording(saved).n_frames == 30


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_saves_the_recording(tmp_path, sig, frames_on_disk):
    want = 30
    settings = SkinSimSettings(
        source="pattern", port="socket://127.0.0.1:0", frames=20_000, seed=2, realtime=True, rate_hz=200.0, hold_s=30.0
    )
    stream = pattern_stream((18, 6), 20_000, 2)
    sim = SkinSimulator(stream, settings, make_endpoint(settings), say=lambda m: None)
    th = start_in_thread(sim)
    out = tmp_path / "rec.npz"
    # no fsync before 1000 frames or 60 s: the partial file must hold the frames all the same
    proc = record_in_child(sim, out, tmp_path, "chunk_frames=1000", "sync_interval_s=60", stdout=subprocess.PIPE)
    partial = out.with_name(out.name + ".partial")
    try:
        on_disk = wait_for_frames(proc, partial, want, frames_on_disk)
        assert on_disk < 1000  # frames are on disk before a chunk of chunk_frames is complete
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        sim.stop.set()
        th.join(10)
    assert proc.returncode == 0, stderr.decode()
    rec = load_recording(out)
    assert rec.n_frames >= want and not partial.exists()
    np.testing.assert_array_equal(rec.seq, np.arange(rec.n_frames))
    np.testing.assert_array_equal(
        rec.values, quantize(stream.values[: rec.n_frames], ValueFormat.BITS).astype(np.float32)
    )
    assert rec.meta["stop_reason"] == f"{sig.name} received"
    assert f"saved {rec.n_frames} frames" in stdout.decode()


def test_the_partial_file_holds_every_frame_appended(tmp_path):
    """Frames are in the file as soon as they are appended, not only once a chunk is complete."""
    w = PartialWriter(tmp_path / "rec.npz", chunk_frames=50, sync_interval_s=3600)
    rng = np.random.default_rng(1)
    vals = rng.random((7, 108)).astype(np.float32)
    for i in range(7):
        w.append(vals[i], float(i), i, i, 0)
    rec = load_recording(w.path)  # read while the writer is still open, as after a kill
    assert rec.n_frames == 7 and w.n_written == 7 and w.n_synced == 0
    np.testing.assert_array_equal(rec.values, vals)
    w.flush()
    assert w.n_synced == 7
    w.remove()


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_recordings_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        saved = save_recording(_small_recording(), tmp_path / "rec.npz")
        w = PartialWriter(tmp_path / "other.npz")
        partial = w.path
        w.close()
    finally:
        os.umask(old)
    want = 0o666 & ~umask
    assert stat.S_IMODE(saved.stat().st_mode) == want
    assert stat.S_IMODE(partial.stat().st_mode) == want


def test_two_glitched_first_frames_with_the_same_count_are_outvoted():
    """Frames are held until one count has 5 votes among the first frames; the earlier glitches are refused
    with their stream offsets, the good frames keep their own arrival times."""
    from sphri.hardware.skin import ReceivedFrame, SkinReader
    from sphri.hardware.skin_protocol import encode_frame

    rng = np.random.default_rng(3)
    counts = [109, 109, 108, 108, 108, 108, 108, 108]
    data = [encode_frame(i, 1000 * i, rng.random(n)) for i, n in enumerate(counts)]
    reader = SkinReader("socket://127.0.0.1:9")  # never opened
    out: list[ReceivedFrame] = []
    for i, chunk in enumerate(data):
        for f in reader.decoder.feed(chunk):
            out += reader._admit(ReceivedFrame(f, float(i), float(i), 0))
        if i < 5:
            assert out == []  # 108 has fewer than 5 votes: everything is held
    assert [r.frame.seq for r in out] == [2, 3, 4, 5, 6, 7]
    assert [r.host_time_s for r in out] == [2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    st = reader.decoder.stats
    assert reader.decoder.expected_taxels == 108 and st.wrong_count == 2 and st.frames == 6
    # after the consensus the decoder refuses another count itself
    assert reader.decoder.feed(encode_frame(8, 0, rng.random(109))) == [] and st.wrong_count == 3
