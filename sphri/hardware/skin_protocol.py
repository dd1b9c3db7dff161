"""The tactile skin's serial protocol, version 1 (pure encoding/decoding).

Documented with byte-level examples in ``docs/PROTOCOLS.md`` (section
"Skin protocol"); a test decodes the examples printed there.

Skin -> host, one frame per sensor scan (all integers little-endian)::

    0   2  sync 0xAA 0x55
    2   1  version (1)
    3   1  value format: 0 = U8, 1 = U16, 2 = BITS (see ValueFormat)
    4   2  sequence number, uint16, +1 per scan, wraps 65535 -> 0
    6   4  device time in microseconds, uint32, wraps
    10  2  taxel count N, uint16, 1..4096
    12  1  header CRC-8/SMBUS over bytes 2..11
    13  P  values: N bytes (U8), 2N bytes (U16) or ceil(N / 8) bytes (BITS,
           taxel i is bit i % 8, LSB first, of byte i // 8)
    13+P 2 CRC-16/CCITT-FALSE over bytes 2 .. 12+P

Taxels are in the layout's order (row-major (u, v) for a grid: u along the
link). The header CRC lets a receiver reject a corrupted taxel count at
once instead of waiting for the bytes it claims.

Host -> skin, optional control message (5 bytes)::

    0  2  sync 0xAA 0x53
    2  1  version (1)
    3  1  command: 0x01 START (begin streaming, sequence from 0), 0x02 STOP
    4  1  CRC-8/SMBUS over bytes 2..3

A skin may stream without waiting for START; it must ignore bytes it does
not understand.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from sphri.hardware.framing import Parse, StreamDecoder, crc8, crc16

VERSION = 1
SYNC = b"\xaa\x55"
CONTROL_SYNC = b"\xaa\x53"
HEADER = struct.Struct("<BBHIH")  # version, format, seq, t_us, n
HEADER_LEN = 2 + HEADER.size + 1  # sync, fields, header CRC = 13
#: Largest taxel count a frame may carry.
MAX_TAXELS = 4096
CMD_START = 0x01
CMD_STOP = 0x02


class ValueFormat(enum.IntEnum):
    """How taxel values are packed; all decode to float32 in [0, 1]."""

    U8 = 0
    """One byte per taxel, value / 255."""
    U16 = 1
    """Two bytes per taxel (LE), value / 65535."""
    BITS = 2
    """Binary taxels, 8 per byte, LSB first; 0 or 1."""


def payload_len(fmt: ValueFormat | int, n: int) -> int:
    """Bytes of the values of ``n`` taxels in format ``fmt``."""
    fmt = ValueFormat(fmt)
    if fmt is ValueFormat.U8:
        return n
    if fmt is ValueFormat.U16:
        return 2 * n
    return (n + 7) // 8


@dataclass(frozen=True)
class SkinFrame:
    """One decoded scan: ``values`` (N,) float32 in [0, 1]."""

    seq: int
    device_time_us: int
    fmt: ValueFormat
    values: np.ndarray

    @property
    def n_taxels(self) -> int:
        return int(self.values.shape[0])


def quantize(values: np.ndarray, fmt: ValueFormat | int) -> np.ndarray:
    """(N,) values in [0, 1] -> the integers sent for ``fmt`` (BITS: value >= 0.5)."""
    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0)
    fmt = ValueFormat(fmt)
    if fmt is ValueFormat.U8:
        return np.rint(v * 255).astype(np.uint8)
    if fmt is ValueFormat.U16:
        return np.rint(v * 65535).astype("<u2")
    return (v >= 0.5).astype(np.uint8)


def encode_frame(seq: int, device_time_us: int, values: np.ndarray, fmt: ValueFormat | int = ValueFormat.U8) -> bytes:
    """Bytes of one frame carrying ``values`` (N,) in [0, 1] (see :func:`quantize`)."""
    fmt = ValueFormat(fmt)
    values = np.asarray(values)
    if values.ndim != 1 or not 1 <= values.shape[0] <= MAX_TAXELS:
        raise ValueError(f"values must be (N,) with 1 <= N <= {MAX_TAXELS}, got shape {values.shape}")
    q = quantize(values, fmt)
    if fmt is ValueFormat.BITS:
        data = np.packbits(q, bitorder="little").tobytes()
    else:
        data = q.tobytes()
    head = HEADER.pack(VERSION, int(fmt), seq & 0xFFFF, device_time_us & 0xFFFFFFFF, values.shape[0])
    head = head + bytes([crc8(head)])
    return SYNC + head + data + struct.pack("<H", crc16(head + data))


def decode_values(data: bytes | bytearray | memoryview, fmt: ValueFormat | int, n: int) -> np.ndarray:
    """Values bytes -> (n,) float32 in [0, 1]."""
    fmt = ValueFormat(fmt)
    if fmt is ValueFormat.U8:
        return np.frombuffer(data, dtype=np.uint8, count=n).astype(np.float32) / np.float32(255)
    if fmt is ValueFormat.U16:
        return np.frombuffer(data, dtype="<u2", count=n).astype(np.float32) / np.float32(65535)
    bits = np.unpackbits(np.frombuffer(data, dtype=np.uint8), bitorder="little", count=n)
    return bits.astype(np.float32)


def encode_control(command: int) -> bytes:
    """A host -> skin control message (``CMD_START`` or ``CMD_STOP``)."""
    body = bytes([VERSION, command])
    return CONTROL_SYNC + body + bytes([crc8(body)])


def find_control(data: bytes | bytearray) -> list[int]:
    """Commands of the valid control messages in ``data`` (device side)."""
    out = []
    i = data.find(CONTROL_SYNC)
    while i >= 0 and i + 5 <= len(data):
        body = bytes(data[i + 2 : i + 4])
        if data[i + 4] == crc8(body) and body[0] == VERSION:
            out.append(body[1])
        i = data.find(CONTROL_SYNC, i + 1)
    return out


class SkinDecoder(StreamDecoder):
    """Streaming decoder of skin frames with sequence tracking.

    ``expected_taxels``: frames with another count are counted
    (``wrong_count``) and skipped; None accepts the count of the first valid
    frame and then holds to it, or, with ``lock_first=False``, passes every
    count on until the caller decides (:meth:`settle_count`, used by
    :class:`~sphri.hardware.skin.SkinReader`'s consensus over the first
    frames; :meth:`settle_count` also counts the held frames it refuses).
    Sequence numbers: a repeat is dropped (``duplicates``), a jump forward counted (``seq_gaps``, ``seq_missing``)
    and a jump back of more than half the range treated as a device restart
    (``seq_restarts``); the frame is kept in the last two cases.
    """

    SYNC = SYNC
    NAME = "skin stream"

    def __init__(self, expected_taxels: int | None = None, lock_first: bool = True) -> None:
        super().__init__()
        if expected_taxels is not None and not 1 <= expected_taxels <= MAX_TAXELS:
            raise ValueError(f"expected_taxels={expected_taxels} must be in [1, {MAX_TAXELS}]")
        self.expected_taxels = expected_taxels
        self.lock_first = lock_first
        self.last_seq: int | None = None
        self._unsettled: dict[int, int] = {}  # id(frame) -> stream offset, for frames passed before settling

    def settle_count(self, n: int, held: list[SkinFrame]) -> list[SkinFrame]:
        """From now on frames must carry ``n`` taxels (decided by a consensus over the first frames).

        ``held``: the frames passed on before (``lock_first=False``); those with
        another count are counted as ``wrong_count`` (and no longer as good
        frames). Returns the others, in order.
        """
        if not 1 <= n <= MAX_TAXELS:
            raise ValueError(f"taxel count {n} must be in [1, {MAX_TAXELS}]")
        self.expected_taxels = n
        keep = []
        for frame in held:
            if frame.n_taxels == n:
                keep.append(frame)
                continue
            self.stats.frames -= 1
            self._count(
                "wrong_count",
                self._unsettled.get(id(frame), -1),
                f"{frame.n_taxels} taxels, expected {n} (seq {frame.seq}; outvoted among the first frames)",
            )
        self._unsettled.clear()
        return keep

    def _parse(self, buf: bytearray, i: int) -> tuple[Parse, int, Any]:
        if len(buf) - i < HEADER_LEN:
            return Parse.NEED_MORE, 0, None
        head = bytes(buf[i + 2 : i + 12])
        if buf[i + 12] != crc8(head):
            return Parse.BAD_HEADER, HEADER_LEN, "header CRC-8 mismatch"
        version, fmt, seq, t_us, n = HEADER.unpack(head)
        if version != VERSION:
            return Parse.BAD_HEADER, HEADER_LEN, f"protocol version {version} (this host speaks {VERSION})"
        if fmt not in ValueFormat._value2member_map_:
            return Parse.BAD_HEADER, HEADER_LEN, f"unknown value format {fmt}"
        if not 1 <= n <= MAX_TAXELS:
            return Parse.BAD_HEADER, HEADER_LEN, f"taxel count {n} outside [1, {MAX_TAXELS}]"
        p = payload_len(fmt, n)
        total = HEADER_LEN + p + 2
        if len(buf) - i < total:
            return Parse.NEED_MORE, 0, None
        (got,) = struct.unpack_from("<H", buf, i + HEADER_LEN + p)
        want = crc16(memoryview(buf)[i + 2 : i + HEADER_LEN + p])
        if got != want:
            return Parse.BAD_CHECKSUM, total, f"CRC {got:#06x} != {want:#06x} (seq {seq})"
        values = decode_values(bytes(buf[i + HEADER_LEN : i + HEADER_LEN + p]), fmt, n)
        return Parse.OK, total, SkinFrame(seq=seq, device_time_us=t_us, fmt=ValueFormat(fmt), values=values)

    def _accept(self, frame: SkinFrame, offset: int) -> bool:
        if not self._track_seq(frame.seq, offset):
            return False
        if self.expected_taxels is None:
            if self.lock_first:
                self.expected_taxels = frame.n_taxels
            else:
                self._unsettled[id(frame)] = offset
        elif frame.n_taxels != self.expected_taxels:
            self._count(
                "wrong_count", offset, f"{frame.n_taxels} taxels, expected {self.expected_taxels} (seq {frame.seq})"
            )
            return False
        return True

    def _track_seq(self, seq: int, offset: int) -> bool:
        last, self.last_seq = self.last_seq, seq
        if last is None:
            return True
        d = (seq - last) & 0xFFFF
        if d == 1:
            return True
        if d == 0:
            self._count("duplicates", offset, f"sequence number {seq} repeated")
            return False
        if d < 0x8000:
            self.stats.seq_gaps += 1
            self.stats.seq_missing += d - 1
            self._note("seq_gaps", offset, f"sequence jumped {last} -> {seq}: {d - 1} frame(s) lost")
            return True
        self.stats.seq_restarts += 1
        self._note("seq_restarts", offset, f"sequence went back {last} -> {seq}: device restarted")
        return True

    def _reset_sequence(self) -> None:
        self.last_seq = None
