"""Pure protocol encoding/decoding: checksums, round trips, resynchronization, counters."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sphri.hardware.framing import crc8, crc16
from sphri.hardware.glove_protocol import (
    START,
    Ack,
    ActuateCommand,
    GloveDecoder,
    encode_ack,
    encode_actuate,
)
from sphri.hardware.skin_protocol import (
    CMD_START,
    CMD_STOP,
    HEADER_LEN,
    SYNC,
    SkinDecoder,
    ValueFormat,
    encode_control,
    encode_frame,
    find_control,
    payload_len,
)


def feed_chunks(decoder, data: bytes, cuts: list[int]) -> list:
    out, prev = [], 0
    for c in sorted(set(min(max(c, 0), len(data)) for c in cuts)) + [len(data)]:
        out += decoder.feed(data[prev:c])
        prev = c
    return out


def check_invariant(decoder) -> None:
    s = decoder.stats
    assert s.bytes_in == s.good_bytes + s.skipped_bytes + decoder.buffered


def test_crc_check_values():
    assert crc16(b"123456789") == 0x29B1
    assert crc8(b"123456789") == 0xF4
    assert crc16(b"") == 0xFFFF and crc8(b"") == 0


# ------------------------------------------------------------------ glove
@settings(max_examples=50, deadline=None)
@given(
    seq=st.integers(0, 255),
    gid=st.integers(0, 255),
    inten=st.lists(st.integers(0, 255), min_size=6, max_size=6),
    pulse=st.lists(st.integers(0, 65535), min_size=6, max_size=6),
    cuts=st.lists(st.integers(0, 40), max_size=6),
)
def test_glove_round_trip_any_chunking(seq, gid, inten, pulse, cuts):
    cmd = ActuateCommand(seq, gid, tuple(inten), tuple(pulse))
    ack = Ack(seq, gid, 0)
    data = encode_actuate(cmd) + encode_ack(ack)
    assert len(encode_actuate(cmd)) == 26 and len(encode_ack(ack)) == 9
    dec = GloveDecoder()
    assert feed_chunks(dec, data, cuts) == [cmd, ack]
    assert dec.stats.errors == 0 and dec.stats.skipped_bytes == 0
    check_invariant(dec)


def test_glove_command_validation():
    with pytest.raises(ValueError, match="intensity"):
        ActuateCommand(0, 1, (0, 0, 0, 0, 0, 256), (0,) * 6)
    with pytest.raises(ValueError, match="6 values"):
        ActuateCommand(0, 1, (0,) * 5, (0,) * 5)
    with pytest.raises(ValueError, match="seq"):
        ActuateCommand(300, 1, (0,) * 6, (0,) * 6)


def test_glove_decoder_counts_and_resyncs():
    good = [encode_actuate(ActuateCommand(i, 1, (i, 0, 0, 0, 0, 0), (60,) * 6)) for i in range(4)]
    bad = bytearray(good[1])
    bad[10] ^= 0x40
    wrong_version = bytearray(good[2])
    wrong_version[2] = 9  # version byte; recompute the CRC so only the version is wrong
    body = bytes(wrong_version[1:-2])
    wrong_version[-2:] = crc16(body).to_bytes(2, "little")
    stream = b"\xa5\x07junk" + good[0] + bytes(bad) + bytes(wrong_version) + good[3]
    dec = GloveDecoder()
    out = dec.feed(stream)
    assert [m.seq for m in out] == [0, 3]
    assert dec.stats.bad_checksum == 1
    assert dec.stats.bad_message == 1
    assert dec.stats.bad_header == 1  # 0xA5 then length 7
    check_invariant(dec)


# ------------------------------------------------------------------ skin
@settings(max_examples=50, deadline=None)
@given(
    n=st.integers(1, 300),
    fmt=st.sampled_from(list(ValueFormat)),
    seq=st.integers(0, 65535),
    t_us=st.integers(0, 2**32 - 1),
    seed=st.integers(0, 2**16),
    cuts=st.lists(st.integers(0, 700), max_size=8),
)
def test_skin_round_trip_any_chunking(n, fmt, seq, t_us, seed, cuts):
    rng = np.random.default_rng(seed)
    values = rng.random(n)
    if fmt is ValueFormat.BITS:
        values = (values > 0.5).astype(float)
    data = encode_frame(seq, t_us, values, fmt)
    assert len(data) == HEADER_LEN + payload_len(fmt, n) + 2  # header, payload, CRC-16
    dec = SkinDecoder()
    (f,) = feed_chunks(dec, data, cuts)
    assert (f.seq, f.device_time_us, f.fmt, f.n_taxels) == (seq, t_us, fmt, n)
    tol = {ValueFormat.U8: 0.5 / 255, ValueFormat.U16: 0.5 / 65535, ValueFormat.BITS: 0.0}[fmt]
    assert f.values.dtype == np.float32
    np.testing.assert_allclose(f.values, values, atol=tol + 1e-6)
    check_invariant(dec)


@settings(max_examples=50, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    garbage=st.lists(st.binary(max_size=40), min_size=12, max_size=12),
    cuts=st.lists(st.integers(0, 3000), max_size=10),
)
def test_skin_no_good_frame_lost_among_garbage(seed, garbage, cuts):
    """Arbitrary bytes between frames never cost a good frame or invent one."""
    rng = np.random.default_rng(seed)
    frames = [encode_frame(i, 1000 * i, rng.random(40), ValueFormat.U8) for i in range(12)]
    data = b"".join(g + f for g, f in zip(garbage, frames)) + bytes(64)
    dec = SkinDecoder(expected_taxels=40)
    out = feed_chunks(dec, data, cuts)
    assert [f.seq for f in out] == list(range(12))
    assert dec.stats.seq_missing == 0
    check_invariant(dec)


@settings(max_examples=50, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    garbage=st.lists(st.binary(max_size=20), min_size=6, max_size=6),
    stop=st.integers(0, 400),
    cuts=st.lists(st.integers(0, 400), max_size=8),
)
def test_every_byte_is_accounted_for_wherever_the_reader_stops(seed, garbage, stop, cuts):
    """Frames and garbage, the reader stopped at any byte: after close() nothing is buffered and every
    byte read is in a good frame or skipped."""
    rng = np.random.default_rng(seed)
    frames = [encode_frame(i, 1000 * i, rng.random(20), ValueFormat.U8) for i in range(6)]
    data = b"".join(g + f for g, f in zip(garbage, frames))[:stop]
    dec = SkinDecoder(expected_taxels=20)
    feed_chunks(dec, data, cuts)
    dec.close()
    assert dec.buffered == 0 and dec.stats.bytes_in == len(data)
    check_invariant(dec)  # with nothing buffered: bytes_in == good_bytes + skipped_bytes


def _frames(n_frames: int, n: int = 20, fmt=ValueFormat.U8, seed: int = 0) -> list[bytes]:
    rng = np.random.default_rng(seed)
    return [encode_frame(i, 1000 * i, rng.random(n), fmt) for i in range(n_frames)]


@pytest.mark.parametrize("fmt", list(ValueFormat))
def test_every_corrupted_byte_is_caught_and_the_next_frame_kept(fmt):
    frames = _frames(3, fmt=fmt)
    for k in range(len(frames[1])):
        bad = bytearray(frames[1])
        bad[k] ^= 0x5A
        dec = SkinDecoder()
        out = dec.feed(frames[0] + bytes(bad) + frames[2])
        assert [f.seq for f in out] == [0, 2], k
        s = dec.stats
        if k < 2:  # the sync itself: the frame is unrecognisable garbage
            assert s.bad_header + s.bad_checksum == 0
        elif k < HEADER_LEN:
            assert s.bad_header == 1 and s.bad_checksum == 0, k
        else:
            assert s.bad_checksum == 1 and s.bad_header == 0, k
        assert s.truncated == 0 and s.seq_missing == 1
        check_invariant(dec)


def test_every_truncation_is_counted_and_the_next_frame_kept():
    frames = _frames(3)
    for k in range(2, len(frames[1])):
        dec = SkinDecoder()
        out = dec.feed(frames[0] + frames[1][:k] + frames[2])
        assert [f.seq for f in out] == [0, 2], k
        assert dec.stats.truncated == 1 and dec.stats.bad_checksum == 0 and dec.stats.bad_header == 0, k
        check_invariant(dec)


def test_wrong_count_duplicates_gaps_restarts():
    rng = np.random.default_rng(1)
    f = lambda seq, n=20: encode_frame(seq, 0, rng.random(n))  # noqa: E731
    dec = SkinDecoder(expected_taxels=20)
    out = dec.feed(f(10) + f(11, 21) + f(12) + f(12) + f(15) + f(3) + f(4))
    assert [x.seq for x in out] == [10, 12, 15, 3, 4]
    s = dec.stats
    assert (s.wrong_count, s.duplicates, s.seq_gaps, s.seq_missing, s.seq_restarts) == (1, 1, 1, 2, 1)


def test_first_frame_sets_the_expected_count():
    rng = np.random.default_rng(2)
    dec = SkinDecoder()
    out = dec.feed(
        encode_frame(0, 0, rng.random(8)) + encode_frame(1, 0, rng.random(9)) + encode_frame(2, 0, rng.random(8))
    )
    assert [x.seq for x in out] == [0, 2] and dec.expected_taxels == 8 and dec.stats.wrong_count == 1


def test_sequence_wraps_without_a_gap():
    dec = SkinDecoder()
    out = dec.feed(b"".join(encode_frame(s, 0, np.zeros(4)) for s in (65534, 65535, 0, 1)))
    assert len(out) == 4 and dec.stats.seq_gaps == 0 and dec.stats.seq_restarts == 0


def test_reset_stream_counts_a_partial_frame_and_forgets_the_sequence():
    frames = _frames(4)
    dec = SkinDecoder()
    assert len(dec.feed(frames[0] + frames[1][:15])) == 1
    dec.reset_stream()
    assert dec.stats.truncated == 1 and dec.stats.resets == 1 and dec.buffered == 0
    out = dec.feed(encode_frame(0, 0, np.zeros(20)) + encode_frame(1, 0, np.zeros(20)))
    assert [x.seq for x in out] == [0, 1]
    assert dec.stats.seq_restarts == 0 and dec.stats.seq_gaps == 0
    check_invariant(dec)


def test_finish_counts_a_frame_the_stream_ended_in():
    frames = _frames(3)
    dec = SkinDecoder()
    out = dec.feed(frames[0] + frames[1][:20] + frames[2][:5])
    out += dec.finish()
    assert [x.seq for x in out] == [0]
    assert dec.stats.truncated == 2 and dec.buffered == 0
    check_invariant(dec)


def test_close_counts_every_buffered_byte():
    """A reader that stops keeps no byte unaccounted: a partial frame is truncated and skipped,
    a lone first sync byte (a broken frame's last byte can be one) is skipped."""
    frames = _frames(2)
    dec = SkinDecoder()
    assert len(dec.feed(frames[0] + frames[1][:15])) == 1 and dec.buffered == 15
    dec.close()
    assert dec.stats.truncated == 1 and dec.stats.skipped_bytes == 15 and dec.buffered == 0
    check_invariant(dec)
    dec = SkinDecoder()
    broken = bytearray(frames[1])
    broken[5] ^= 0xFF  # bad header CRC
    broken[-1] = SYNC[0]  # the frame's last byte looks like the start of the next one
    assert len(dec.feed(frames[0] + bytes(broken))) == 1 and dec.buffered == 1
    dec.close()
    assert dec.stats.bad_header == 1 and dec.stats.truncated == 0 and dec.buffered == 0
    assert dec.stats.skipped_bytes == len(broken) == dec.stats.bytes_in - dec.stats.good_bytes
    assert dec.stats.resets == 0


def test_header_rejects_a_corrupted_count_at_once():
    """A corrupted taxel count must not make the decoder wait for the bytes it claims."""
    frames = _frames(3)
    bad = bytearray(frames[1])
    bad[11] = 0x0F  # N high byte: 3860 taxels
    dec = SkinDecoder()
    out = dec.feed(frames[0] + bytes(bad) + frames[2])
    assert [x.seq for x in out] == [0, 2] and dec.buffered == 0


def test_control_messages():
    data = b"xx" + encode_control(CMD_START) + b"\xaa\x53\x01\x01\x00" + encode_control(CMD_STOP)
    assert find_control(data) == [CMD_START, CMD_STOP]
    assert encode_control(CMD_START)[:2] == b"\xaa\x53"
    assert START == 0xA5


def test_encode_rejects_bad_shapes():
    with pytest.raises(ValueError, match="values"):
        encode_frame(0, 0, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="values"):
        encode_frame(0, 0, np.zeros(5000))
