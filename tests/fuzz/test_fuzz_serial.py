"""Fuzz campaign, target 5: serial streams of the skin reader (issue 29, item 5).

A stream of valid skin frames (U8, U16 or BITS values) is corrupted between and inside its frames:
random garbage (sync bytes included), frames cut short, flipped bytes, frames of another taxel count,
repeated frames, and fed to the decoder in random chunk sizes. Every frame left intact must come out,
in order and with its values; nothing else may come out (a corrupted frame is counted, never passed
on); no exception may escape; the decoder's byte accounting must balance.
"""

from __future__ import annotations

import numpy as np
from fuzz_support import LOST, SILENT, UNCHANGED, WARNED, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st

from sphri.hardware.skin_protocol import SYNC, SkinDecoder, ValueFormat, encode_frame, quantize

N = 12  # taxels


def _frame(seq: int, fmt: ValueFormat, rng: np.random.Generator, n: int = N) -> tuple[bytes, np.ndarray]:
    raw = rng.random(n)
    sent = quantize(raw, fmt).astype(np.float32)  # what the decoder gives back: values in [0, 1]
    scale = {ValueFormat.U8: 255, ValueFormat.U16: 65535}.get(fmt, 1)
    return encode_frame(seq, 1000 * seq, raw, fmt), sent / np.float32(scale)


@fuzz_settings(small=40, large=400)
@given(
    fmt=st.sampled_from(list(ValueFormat)),
    n_frames=st.integers(1, 30),
    seed=st.integers(0, 2**32 - 1),
    faults=st.lists(st.sampled_from(["garbage", "sync garbage", "cut", "flip", "wrong count", "repeat"]), max_size=30),
    chunks=st.lists(st.integers(1, 64), min_size=1, max_size=8),
    data=st.data(),
)
def test_corrupted_serial_streams_lose_no_intact_frame(tally, fmt, n_frames, seed, faults, chunks, data):
    rng = np.random.default_rng(seed)
    stream = bytearray()
    intact: list[tuple[int, np.ndarray]] = []
    kinds = set()
    for seq in range(n_frames):
        blob, values = _frame(seq, fmt, rng)
        fault = faults[seq] if seq < len(faults) else None
        if fault in ("garbage", "sync garbage"):
            junk = data.draw(st.binary(min_size=1, max_size=40), label="garbage")
            if fault == "sync garbage":
                junk = SYNC + junk
            stream += junk  # before an intact frame
        if fault == "cut":
            stream += blob[: data.draw(st.integers(1, len(blob) - 1), label="keep")]
        elif fault == "flip":
            b = bytearray(blob)
            b[data.draw(st.integers(2, len(b) - 1), label="offset")] ^= data.draw(st.integers(1, 255), label="xor")
            stream += b
        elif fault == "wrong count":
            stream += _frame(seq, fmt, rng, n=N + data.draw(st.integers(1, 5), label="extra"))[0]
        else:
            stream += blob
            intact.append((seq, values))
            if fault == "repeat":
                stream += blob  # the same sequence number again: dropped as a duplicate
        if fault:
            kinds.add(fault)
    decoder = SkinDecoder(expected_taxels=N)
    out = []
    pos, k = 0, 0
    while pos < len(stream):
        step = chunks[k % len(chunks)]
        out += decoder.feed(bytes(stream[pos : pos + step]))
        pos, k = pos + step, k + 1
    out += decoder.finish()
    s = decoder.stats
    assert s.bytes_in == len(stream) == s.good_bytes + s.skipped_bytes + decoder.buffered
    got = [(f.seq, f.values) for f in out]
    want_seqs = [q for q, _ in intact]
    lost = [q for q in want_seqs if q not in {g for g, _ in got}]
    extra = [g for g, _ in got if g not in set(want_seqs)]
    changed = [q for (q, v), (g, w) in zip(intact, got) if q == g and not np.array_equal(v, w)]
    kind = "+".join(sorted(kinds)) or "clean stream"
    if lost:
        v = LOST
    elif extra or changed or [g for g, _ in got] != want_seqs:
        v = SILENT
    else:
        v = WARNED if s.errors or s.duplicates else UNCHANGED
    tally.add(kind if len(kinds) <= 1 else "several faults", v)
    assert not lost, f"intact frames {lost} not decoded ({s.line()})"
    assert v != SILENT, f"frames passed on that were not sent intact: {extra or changed}"


@fuzz_settings(small=30, large=300)
@given(blob=st.binary(max_size=2000), chunk=st.integers(1, 300), lock=st.booleans())
def test_random_bytes_never_raise_and_balance(tally, blob, chunk, lock):
    decoder = SkinDecoder(expected_taxels=N if lock else None)
    out = []
    for i in range(0, len(blob), chunk):
        out += decoder.feed(blob[i : i + chunk])
    out += decoder.finish()
    s = decoder.stats
    assert s.bytes_in == len(blob) == s.good_bytes + s.skipped_bytes + decoder.buffered
    tally.add("random bytes", SILENT if out else (WARNED if s.errors else UNCHANGED))
    assert not out  # random bytes carrying two valid CRCs: never seen
