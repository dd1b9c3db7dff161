"""Skin: `record` against the simulator (faults, unplug/replug), the recording format."""

from __future__ import annotations

import json

import numpy as np
import pytest
from skin_sim import check_good_frames_kept, run_record

from sphri.args import ArgsError, parse
from sphri.hardware.recording import RecordingError, SkinRecording, load_recording, save_recording
from sphri.hardware.settings import SkinRecordSettings
from sphri.hardware.skin import SkinReader
from sphri.hardware.skin_protocol import SYNC, SkinDecoder, ValueFormat, encode_frame


def trailing_lost(ledger) -> int:
    """Slots lost after the last intact frame: no later sequence number reveals them."""
    return ledger.slots - 1 - ledger.good_seq[-1]


@pytest.mark.parametrize("port", ["pty", "socket://127.0.0.1:0"])
def test_record_keeps_every_good_frame_with_5_percent_corrupt(tmp_path, port):
    ledger, summary, rec, stream, lines = run_record(tmp_path, {"port": port, "corrupt_rate": 0.05})
    dec = summary["decoder"]
    assert ledger.corrupt >= 10
    check_good_frames_kept(ledger, rec, stream)
    # every corrupt frame is reported, as a bad header or a bad checksum, and as a missing sequence number
    assert dec["bad_header"] == ledger.corrupt_header
    assert dec["bad_checksum"] == ledger.corrupt_body
    assert dec["truncated"] == 0 and dec["wrong_count"] == 0
    assert dec["seq_missing"] == ledger.corrupt - trailing_lost(ledger)
    # every byte read is accounted for: good frames or skipped (nothing left buffered)
    assert dec["good_bytes"] == ledger.good_bytes
    assert dec["skipped_bytes"] == dec["bytes_in"] - dec["good_bytes"]
    # the recorder stops once the simulator finished and nothing is in flight; the tail of a
    # trailing broken frame may still be in flight: at most one frame unread
    frame_bytes = ledger.good_bytes // ledger.good
    assert 0 <= ledger.bytes_sent - dec["bytes_in"] < frame_bytes
    assert rec.grid_shape == (18, 6) and rec.meta["decoder"] == dec
    assert any("skipped" in ln and f"bad_checksum={ledger.corrupt_body}" in ln for ln in lines)


def test_a_finished_source_gives_the_frame_behind_a_cut_one_and_every_byte_is_counted():
    """The stream ends with a frame cut short (claiming more bytes than ever come), one good frame
    behind it and a lone sync byte: the good frame is still read, the rest counted."""
    good = [encode_frame(i, 1000 * i, np.full(20, 0.5)) for i in range(3)]
    cut = encode_frame(1, 1000, np.zeros(20), ValueFormat.U16)[:15]  # claims 55 bytes, 36 follow
    data = good[0] + cut + good[2] + SYNC[:1]
    with SkinReader("loop://", taxels=20, start_command=False) as reader:
        reader.link.write(data)
        got = list(reader.frames(until=lambda: True, idle_s=10.0))
        assert reader.stop_reason == "the source finished"
    assert [rf.frame.seq for rf in got] == [0, 2]
    st = reader.stats
    assert st.truncated == 1 and st.bad_checksum == 0 and st.bad_header == 0
    assert st.bytes_in == len(data) == st.good_bytes + st.skipped_bytes


def test_a_stopped_reader_counts_the_bytes_it_held():
    data = b"".join(encode_frame(i, 1000 * i, np.full(20, 0.5)) for i in range(2))
    with SkinReader("loop://", taxels=20, start_command=False) as reader:
        reader.link.write(data[:-10])
        got = list(reader.frames(max_frames=1, idle_s=10.0))
    assert [rf.frame.seq for rf in got] == [0]
    st = reader.stats
    assert st.truncated == 1 and st.skipped_bytes == len(data) // 2 - 10
    assert st.bytes_in == len(data) - 10 == st.good_bytes + st.skipped_bytes


def test_record_survives_every_kind_of_fault(tmp_path):
    ledger, summary, rec, stream, _ = run_record(
        tmp_path,
        {
            "port": "socket://127.0.0.1:0",
            "garbage_rate": 0.05,
            "corrupt_rate": 0.04,
            "drop_rate": 0.03,
            "truncate_rate": 0.04,
            "wrong_count_rate": 0.03,
        },
        frames=600,
    )
    dec = summary["decoder"]
    assert min(ledger.garbage_bursts, ledger.corrupt, ledger.dropped, ledger.truncated, ledger.wrong_count) > 0
    check_good_frames_kept(ledger, rec, stream)
    assert dec["wrong_count"] == ledger.wrong_count
    # truncated vs corrupted is a heuristic; their total is exact
    assert dec["bad_header"] + dec["bad_checksum"] + dec["truncated"] == ledger.corrupt + ledger.truncated
    assert dec["seq_missing"] == ledger.lost - trailing_lost(ledger)
    assert dec["skipped_bytes"] == ledger.bytes_sent - ledger.good_bytes - ledger.wrong_count_bytes


def test_an_unpaced_simulator_sends_the_same_bytes_for_the_same_seed(tmp_path):
    """realtime=false stamps each frame with its time at rate_hz, not the clock's: two runs of one seed
    record the same frames, timestamps and decoder counts, so the exact totals of the test above hold
    for its seed in every run. With the clock's time the test above failed once in a suite run
    (2026-11-28: 52 bad frames counted for 51 sent; not reproduced in 60 reruns). The clock's time was
    the one input of the byte stream that changed between runs, and it can change the count: the
    sync bytes inside a broken frame's timestamp are one more bad candidate (next test)."""
    faults = {"port": "socket://127.0.0.1:0", "garbage_rate": 0.05, "corrupt_rate": 0.04, "truncate_rate": 0.04}
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    _, first, a, _, _ = run_record(tmp_path / "a", faults, frames=200)
    _, second, b, _, _ = run_record(tmp_path / "b", faults, frames=200)
    np.testing.assert_array_equal(a.device_time_us, b.device_time_us)
    np.testing.assert_array_equal(a.seq, b.seq)
    np.testing.assert_array_equal(a.values, b.values)
    assert first["decoder"] == second["decoder"]
    # the stamp is the frame's time at 90 Hz (the pattern's rate): frame k at k / 90 s
    assert a.device_time_us.tolist() == [round(int(k) * (1.0 / 90.0) * 1e6) for k in a.seq]


def test_the_sync_bytes_inside_a_cut_frame_are_one_more_bad_candidate():
    """A frame cut short inside its header, between two good frames: one bad frame, unless its
    timestamp holds the sync bytes, which the decoder (scanning on from the failed candidate) then
    also tries as a frame. What made the fault test's totals depend on the clock."""
    values = np.full(108, 1.0)

    def bad_candidates(t_us: int) -> int:
        cut = encode_frame(5, t_us, values, ValueFormat.BITS)[:12]
        data = encode_frame(4, 0, values, ValueFormat.BITS) + cut + encode_frame(6, 2, values, ValueFormat.BITS)
        decoder = SkinDecoder()
        assert [f.seq for f in decoder.feed(data)] == [4, 6]
        decoder.close()
        st = decoder.stats
        return st.bad_header + st.bad_checksum + st.truncated

    assert bad_candidates(1234567) == 1
    assert bad_candidates(int.from_bytes(b"\x00" + SYNC + b"\x00", "little")) == 2


@pytest.mark.parametrize("port", ["pty", "socket://127.0.0.1:0"])
def test_unplugged_and_plugged_back_with_reconnect(tmp_path, port):
    ledger, summary, rec, stream, _ = run_record(
        tmp_path,
        {
            "port": port,
            "link": str(tmp_path / "skin.tty") if port == "pty" else "",
            "realtime": True,
            "rate_hz": 500.0,
            "unplug_after_s": 0.25,
            "unplug_s": 0.4,
            "hold_s": 2.0,
        },
        {"reconnect": True, "reconnect_timeout_s": 5.0},
    )
    assert ledger.unplugs == 1 and ledger.starts == 2
    check_good_frames_kept(ledger, rec, stream)
    assert summary["reconnects"] == 1 and summary["error"] is None
    dec = summary["decoder"]
    assert dec["truncated"] == ledger.truncated_by_unplug == 1
    assert dec["resets"] == 1 and dec["seq_restarts"] == 0
    seg0, seg1 = (rec.segment == 0).sum(), (rec.segment == 1).sum()
    assert seg0 > 0 and seg1 > 0 and rec.seq[seg0] == 0  # the device restarted its sequence


def test_vanished_port_without_reconnect_saves_and_says_so(tmp_path):
    ledger, summary, rec, stream, lines = run_record(
        tmp_path,
        {
            "port": "pty",
            "link": str(tmp_path / "skin.tty"),
            "realtime": True,
            "rate_hz": 500.0,
            "unplug_after_s": 0.2,
            "unplug_s": 0.5,
            "hold_s": 0.5,
        },
    )
    assert summary["error"] is not None
    assert "skin.tty" in summary["error"] and "vanished" in summary["error"] and "reconnect=true" in summary["error"]
    assert ledger.unplugs == 1 and ledger.slots < 400  # the recorder stopped while the device was away
    check_good_frames_kept(ledger, rec, stream)  # every frame before the unplug is saved
    assert rec.meta["stop_reason"] == summary["error"]
    assert any("stopped early" in ln for ln in lines)


def test_wrong_skin_is_refused_with_a_clear_message(tmp_path):
    ledger, summary, rec, _, _ = run_record(
        tmp_path, {"port": "socket://127.0.0.1:0"}, {"taxels": 50, "grid": ""}, frames=100
    )
    assert "50" in summary["error"] and "wrong taxel count" in summary["error"]
    assert rec.n_frames == 0


def test_record_settings():
    s = parse(SkinRecordSettings, ["port=/dev/ttyACM0", "out=x.npz", "grid=18x6", "taxels=108"])
    assert s.grid == "18x6"
    assert parse(SkinRecordSettings, ["--port", "p", "--out=x.npz", "--chunk-frames", "7"]).chunk_frames == 7
    with pytest.raises(ArgsError, match=r"^grid='18x6' is invalid: H\*W must equal taxels=100$"):
        parse(SkinRecordSettings, ["port=p", "out=x.npz", "grid=18x6", "taxels=100"])
    with pytest.raises(ArgsError, match="^grid='eighteen' is invalid"):
        parse(SkinRecordSettings, ["port=p", "out=x.npz", "grid=eighteen"])
    with pytest.raises(ArgsError, match="^unknown argument 'robot'"):  # record composes no config
        parse(SkinRecordSettings, ["port=p", "out=x.npz", "robot=reachy"])
    with pytest.raises(ArgsError, match="^missing out=TEXT"):  # "???": required
        parse(SkinRecordSettings, ["port=p"])
    with pytest.raises(ArgsError, match=r"^baud=1 is invalid: must be in \[300, "):  # setting()'s range
        parse(SkinRecordSettings, ["port=p", "out=x", "baud=1"])
    with pytest.raises(ArgsError, match="^baud=1.5 is invalid: must be an integer$"):
        parse(SkinRecordSettings, ["port=p", "out=x", "baud=1.5"])


# ------------------------------------------------------------------ recording format
def _recording(n: int = 30) -> SkinRecording:
    rng = np.random.default_rng(0)
    return SkinRecording(
        values=(rng.random((n, 12)) > 0.5).astype(np.float32),
        host_time_s=1.7e9 + np.arange(n) / 90.0,
        device_time_us=np.arange(n) * 11111,
        seq=np.arange(n),
        segment=np.zeros(n, dtype=np.int64),
        grid_shape=(4, 3),
        meta={"port": "loop://"},
    )


def test_recording_round_trip_and_windows(tmp_path):
    rec = _recording()
    path = save_recording(rec, tmp_path / "sub" / "r.npz")
    back = load_recording(path)
    np.testing.assert_array_equal(back.values, rec.values)
    np.testing.assert_array_equal(back.seq, rec.seq)
    assert back.grid_shape == (4, 3) and back.meta["port"] == "loop://"
    assert back.rate_hz == pytest.approx(90.0)
    assert back.frames().as_grid().shape == (30, 4, 3)
    w = back.windows(10, stride=5)
    assert w.shape == (5, 10, 12) and w.dtype == np.float32
    np.testing.assert_array_equal(w[1], rec.values[5:15])


def test_recording_errors_name_the_file_and_field(tmp_path):
    with pytest.raises(RecordingError, match="not found"):
        load_recording(tmp_path / "nope.npz")
    p = tmp_path / "partial.npz"
    np.savez(p, values=np.zeros((2, 3), np.float32))
    with pytest.raises(RecordingError, match=r"partial\.npz.*missing"):
        load_recording(p)
    rec = _recording()
    rec.values[0, 0] = 2.0
    bad = tmp_path / "bad.npz"
    save_recording(rec, bad)
    with pytest.raises(RecordingError, match=r"bad\.npz.*values"):
        load_recording(bad)
    with pytest.raises(RecordingError, match="grid_shape"):
        SkinRecording(np.zeros((2, 12)), np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2), (5, 5))
    with pytest.raises(RecordingError, match="seq"):
        SkinRecording(np.zeros((2, 12)), np.zeros(2), np.zeros(2), np.zeros(3), np.zeros(2), None)
    blob = tmp_path / "junk.npz"
    blob.write_bytes(b"not a zip")
    with pytest.raises(RecordingError, match="junk"):
        load_recording(blob)
    meta_bad = tmp_path / "meta.npz"
    save_recording(_recording(), meta_bad)
    with np.load(meta_bad) as z:
        d = dict(z)
    d["meta"] = np.asarray(json.dumps({"format": "other/9"}))
    np.savez(meta_bad, **d)
    with pytest.raises(RecordingError, match="other/9"):
        load_recording(meta_bad)
