"""The recorder's memory does not grow with the recording: no frame is kept in memory, the saved
recording is built from the partial file, and it equals the frames sent byte for byte, a full disk
midway included."""

from __future__ import annotations

import errno
import tracemalloc

import numpy as np
import pytest

import sphri.hardware.recording as recording
import sphri.hardware.skin as skin
from sphri.hardware.recording import load_recording
from sphri.hardware.settings import SkinRecordSettings
from sphri.hardware.sim_skin import pattern_stream
from sphri.hardware.skin_protocol import ValueFormat, encode_frame, quantize

GRID = (18, 6)


class FrameLink:
    """A port serving ``n`` skin frames, ``per_read`` at a time, encoded as they are read (the simulator's
    pattern values, cycled; sequence numbers and device times count up), so the source holds no frame."""

    def __init__(self, n: int, per_read: int = 20, seed: int = 3) -> None:
        self.base = pattern_stream(GRID, 64, seed).values
        self.n, self.per_read, self.pos = n, per_read, 0
        self.port, self.reconnects = "socket://127.0.0.1:9", 0

    def __call__(self, port, baud, **kw) -> FrameLink:  # stands in for transport.Link
        return self

    def open(self) -> FrameLink:
        return self

    def close(self) -> None:
        pass

    def write(self, data: bytes) -> None:
        pass

    def read(self) -> bytes:
        end = min(self.pos + self.per_read, self.n)
        data = b"".join(self.frame(i) for i in range(self.pos, end))
        self.pos = end
        return data

    def frame(self, i: int) -> bytes:
        return encode_frame(i & 0xFFFF, 1000 * i, self.base[i % len(self.base)], ValueFormat.U16)

    def sent(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(values as the skin sent them, decoded to float32; seq; device_time_us) of the first ``n`` frames."""
        i = np.arange(n)
        q = np.stack([quantize(self.base[k % len(self.base)], ValueFormat.U16) for k in i])
        return q.astype(np.float32) / np.float32(65535), i & 0xFFFF, 1000 * i


def _record(tmp_path, monkeypatch, link: FrameLink, name: str, **kw) -> dict:
    monkeypatch.setattr(skin, "Link", link)
    settings = SkinRecordSettings(
        port=link.port, out=str(tmp_path / name), frames=link.n, grid="18x6", idle_s=30.0, **kw
    )
    return skin.record(settings, out=lambda m: None)


def _peak_bytes(tmp_path, monkeypatch, n: int) -> int:
    link = FrameLink(n)
    tracemalloc.start()
    try:
        summary = _record(tmp_path, monkeypatch, link, f"rec{n}.npz", chunk_frames=100_000, sync_interval_s=3600)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert summary["frames"] == n and summary["error"] is None
    return peak


def test_the_recorders_memory_does_not_grow_with_the_frames(tmp_path, monkeypatch):
    _peak_bytes(tmp_path, monkeypatch, 50)  # imports and first-use allocations out of the way
    small = _peak_bytes(tmp_path, monkeypatch, 2_000)
    large = _peak_bytes(tmp_path, monkeypatch, 40_000)
    # frames held in memory would make the 20x recording's peak about 20x (measured: 18x)
    assert large < 3 * small, f"peak traced memory {large} bytes for 40000 frames, {small} for 2000"


def _check_sent(rec, link: FrameLink) -> None:
    values, seq, device_time_us = link.sent(rec.n_frames)
    assert rec.values.tobytes() == values.tobytes()
    assert rec.seq.tobytes() == seq.astype(np.int64).tobytes()
    assert rec.device_time_us.tobytes() == device_time_us.astype(np.int64).tobytes()
    assert rec.grid_shape == GRID and not (rec.segment != 0).any()


def test_the_saved_recording_is_the_frames_sent_byte_for_byte(tmp_path, monkeypatch):
    link = FrameLink(1_234)
    summary = _record(tmp_path, monkeypatch, link, "rec.npz", chunk_frames=100)
    rec = load_recording(tmp_path / "rec.npz")
    assert rec.n_frames == 1_234 and summary["not_written"] == 0
    _check_sent(rec, link)
    assert not (tmp_path / "rec.npz.partial").exists()


@pytest.mark.parametrize("torn", [False, True], ids=["write_refused", "record_torn"])
def test_a_full_disk_midway_saves_every_frame_read_byte_for_byte(tmp_path, monkeypatch, torn):
    """Writing frame 500 fails with ENOSPC (nothing written, or half its record): the 500 frames in the partial
    file and the ones read but not written (frame 500 and the rest of its read) are saved, in order, and the
    summary counts the ones not written."""
    real = recording.PartialWriter._write_all

    def write_all(self, data: bytes) -> None:
        if self.n_written == 500:
            if torn:
                real(self, data[: len(data) // 2])
            raise OSError(errno.ENOSPC, "No space left on device")
        real(self, data)

    monkeypatch.setattr(recording.PartialWriter, "_write_all", write_all)
    link = FrameLink(2_000, per_read=7)
    summary = _record(tmp_path, monkeypatch, link, "rec.npz", chunk_frames=50)
    rec = load_recording(tmp_path / "rec.npz")
    # reads of 7 frames: frame 500 is the 4th of the read 497..503, whose frames are all kept
    assert rec.n_frames == 504 and summary["frames"] == 504
    assert summary["not_written"] == 4
    assert "No space left" in summary["error"] and "after 500 frames" in summary["error"]
    _check_sent(rec, link)
    assert not (tmp_path / "rec.npz.partial").exists()
