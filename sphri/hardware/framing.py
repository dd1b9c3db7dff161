"""Byte-stream framing shared by the glove and skin protocols (pure, no I/O).

- :func:`crc16` (CRC-16/CCITT-FALSE) and :func:`crc8` (CRC-8/SMBUS), the
  checksums of ``docs/PROTOCOLS.md``.
- :class:`StreamDecoder`: turns arbitrary chunks of bytes (as a serial port
  hands them out) into messages. It hunts for the sync bytes, checks each
  candidate frame, skips what is broken and resynchronizes on the next valid
  frame. Every problem is counted in :class:`DecoderStats` and logged; a
  good frame is never lost because a broken one before it claimed its bytes
  (after a failed candidate the scan restarts one byte after its sync).

Subclasses give the sync bytes and ``_parse`` (one candidate frame at an
offset of the buffer).
"""

from __future__ import annotations

import binascii
import enum
import logging
from dataclasses import asdict, dataclass
from typing import Any

log = logging.getLogger(__name__)


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, xorout 0.

    ``crc16(b"123456789") == 0x29B1``.
    """
    return binascii.crc_hqx(data, 0xFFFF)


def _crc8_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        c = byte
        for _ in range(8):
            c = ((c << 1) ^ 0x07) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table.append(c)
    return tuple(table)


_CRC8 = _crc8_table()


def crc8(data: bytes | bytearray | memoryview) -> int:
    """CRC-8/SMBUS: poly 0x07, init 0x00, no reflection. ``crc8(b"123456789") == 0xF4``."""
    c = 0
    for b in bytes(data):
        c = _CRC8[c ^ b]
    return c


class Parse(enum.Enum):
    """Outcome of checking one candidate frame."""

    NEED_MORE = 0
    OK = 1
    BAD_HEADER = 2
    BAD_CHECKSUM = 3


#: The counters of traffic; the others count problems.
TRAFFIC = ("bytes_in", "frames", "good_bytes")


@dataclass
class DecoderStats:
    """What a :class:`StreamDecoder` has seen (counts since creation).

    ``bytes_in == good_bytes + skipped_bytes + buffered`` at any time.
    """

    bytes_in: int = 0
    """Bytes fed."""
    frames: int = 0
    """Good frames returned."""
    good_bytes: int = 0
    """Bytes of the good frames (and of checksum-valid frames that were refused)."""
    skipped_bytes: int = 0
    """Bytes discarded: garbage between frames and the bytes of broken frames."""
    bad_header: int = 0
    """Sync bytes followed by an impossible header (usually garbage)."""
    bad_checksum: int = 0
    """Complete frames whose checksum failed (corrupted in transit)."""
    truncated: int = 0
    """Frames cut short: the next valid frame started inside their claimed length,
    or the stream was reset (reconnect) with a partial frame buffered."""
    wrong_count: int = 0
    """Valid frames with a taxel count other than the expected one (skin)."""
    bad_message: int = 0
    """Valid frames with an unknown version, type or format."""
    duplicates: int = 0
    """Valid frames repeating the previous sequence number (dropped)."""
    seq_gaps: int = 0
    """Jumps forward in the sequence number (frames lost on the way)."""
    seq_missing: int = 0
    """Sequence numbers never received, summed over the gaps."""
    seq_restarts: int = 0
    """Jumps backwards in the sequence number (the device restarted)."""
    resets: int = 0
    """Stream resets (:meth:`StreamDecoder.reset_stream`, e.g. after a reconnect)."""

    def as_dict(self) -> dict[str, int]:
        return asdict(self)

    @property
    def errors(self) -> int:
        """Broken or refused frames (headers, checksums, truncations, counts, messages)."""
        return self.bad_header + self.bad_checksum + self.truncated + self.wrong_count + self.bad_message

    def line(self) -> str:
        """One-line summary of the non-zero counters."""
        d = {k: v for k, v in self.as_dict().items() if v}
        return ", ".join(f"{k}={v}" for k, v in d.items()) or "nothing received"

    def problems(self) -> str:
        """Every problem counter (all but :data:`TRAFFIC`), zeros included, on one line."""
        return ", ".join(f"{k}={v}" for k, v in self.as_dict().items() if k not in TRAFFIC)


#: Per kind of problem, how many are logged at WARNING before switching to DEBUG.
LOG_FIRST = 20


class StreamDecoder:
    """Incremental decoder: ``feed(chunk) -> [messages]``, with resync and counters.

    Subclasses set :attr:`SYNC` and implement :meth:`_parse`; they may
    override :meth:`_accept` to refuse checksum-valid frames (wrong count)
    and to track sequence numbers.
    """

    SYNC: bytes = b""
    #: Human-readable name used in log messages.
    NAME = "stream"

    def __init__(self) -> None:
        if not self.SYNC:
            raise TypeError("StreamDecoder subclasses must define SYNC")
        self.stats = DecoderStats()
        self._buf = bytearray()
        self._base = 0  # absolute stream offset of _buf[0]
        self._pending: list[tuple[int, int, str, str]] = []  # failed candidates (start, end, kind, reason)
        self._logged: dict[str, int] = {}
        self._eof = False

    # -- to implement ---------------------------------------------------------------
    def _parse(self, buf: bytearray, i: int) -> tuple[Parse, int, Any]:
        """Check the candidate frame whose sync starts at ``buf[i]``.

        Returns ``(Parse.OK, length, message)``, ``(Parse.NEED_MORE, 0, None)``,
        or ``(Parse.BAD_HEADER | Parse.BAD_CHECKSUM, claimed_length, reason)``.
        """
        raise NotImplementedError

    def _accept(self, msg: Any, offset: int) -> bool:
        """Whether a checksum-valid message is passed on (count refusals here)."""
        return True

    # -- public ---------------------------------------------------------------------
    @property
    def buffered(self) -> int:
        """Bytes held waiting for the rest of a frame."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Any]:
        """Decode the messages completed by ``data`` (in stream order)."""
        self._buf += data
        self.stats.bytes_in += len(data)
        buf = self._buf
        out: list[Any] = []
        pos = 0
        sync = self.SYNC
        keep_tail = len(sync) - 1
        while True:
            i = buf.find(sync, pos)
            if i < 0:
                stop = max(pos, len(buf) - keep_tail)
                # a partial sync at the very end is kept; bytes before it are garbage
                if keep_tail and not sync.startswith(bytes(buf[stop:])):
                    stop = len(buf)
                self._skip(stop - pos)
                pos = stop
                break
            if i > pos:
                self._skip(i - pos)
            status, n, msg = self._parse(buf, i)
            if status is Parse.NEED_MORE:
                if not self._eof:
                    pos = i
                    break
                # end of stream: this frame will never be completed
                self._pending.append((self._base + i, self._base + len(buf), "truncated", "the stream ended inside it"))
                self._skip(1)
                pos = i + 1
                continue
            if status is Parse.OK:
                self._resolve(self._base + i)
                if self._accept(msg, self._base + i):
                    out.append(msg)
                    self.stats.frames += 1
                self.stats.good_bytes += n
                pos = i + n
                continue
            kind = "bad_header" if status is Parse.BAD_HEADER else "bad_checksum"
            self._pending.append((self._base + i, self._base + i + n, kind, str(msg)))
            self._skip(1)
            pos = i + 1
        del buf[:pos]
        self._base += pos
        self._resolve_before(self._base)
        return out

    def reset_stream(self) -> None:
        """Forget buffered bytes and sequence state (after a reconnect).

        A buffered partial frame (one starting with the sync bytes) counts
        as truncated; other buffered bytes as skipped.
        """
        self._discard_buffered("stream reset with a partial frame buffered")
        self._resolve_before(None)
        self.stats.resets += 1
        self._reset_sequence()

    def close(self) -> None:
        """The reader stops for good (a recording ended, the port is closed): the bytes still buffered
        will never complete a frame, so they are counted as skipped (a buffered partial frame, one
        starting with the sync bytes, also as truncated) and pending classifications are settled.
        Afterwards ``bytes_in == good_bytes + skipped_bytes``. Use :meth:`finish` instead where the
        stream itself ended and frames decodable from the buffer should still be returned."""
        self._discard_buffered("the reader stopped with a partial frame buffered")
        self._resolve_before(None)

    def finish(self) -> list[Any]:
        """End of stream (e.g. a byte dump): decode what is left, count a partial frame as truncated."""
        self._eof = True
        try:
            out = self.feed(b"")
        finally:
            self._eof = False
        self._skip(len(self._buf))
        self._base += len(self._buf)
        self._buf.clear()
        self._resolve_before(None)
        return out

    # -- internals ------------------------------------------------------------------
    def _reset_sequence(self) -> None:
        pass

    def _discard_buffered(self, reason: str) -> None:
        """Count the buffered bytes as skipped (a partial frame also as truncated, for ``reason``); empty the buffer."""
        if self._buf:
            if self._buf.startswith(self.SYNC):
                self._count("truncated", self._base, reason)
            self.stats.skipped_bytes += len(self._buf)
            self._base += len(self._buf)
            self._buf.clear()

    def _skip(self, n: int) -> None:
        self.stats.skipped_bytes += n

    def _resolve(self, good_start: int) -> None:
        """A good frame starts at ``good_start``: settle the failed candidates before it."""
        for start, end, kind, reason in self._pending:
            if end > good_start:
                self._count("truncated", start, f"cut short by the frame at offset {good_start} ({reason})")
            else:
                self._count(kind, start, reason)
        self._pending.clear()

    def _resolve_before(self, limit: int | None) -> None:
        """Settle failed candidates that end at or before ``limit`` (all if None)."""
        keep = []
        for start, end, kind, reason in self._pending:
            if limit is None or end <= limit:
                self._count(kind, start, reason)
            else:
                keep.append((start, end, kind, reason))
        self._pending = keep

    def _count(self, kind: str, offset: int, reason: str) -> None:
        setattr(self.stats, kind, getattr(self.stats, kind) + 1)
        self._note(kind, offset, reason)

    def _note(self, kind: str, offset: int, reason: str) -> None:
        """Log one event of ``kind`` (the first :data:`LOG_FIRST` at WARNING)."""
        n = self._logged.get(kind, 0) + 1
        self._logged[kind] = n
        level = logging.WARNING if n <= LOG_FIRST else logging.DEBUG
        suffix = f" (further {kind} events are logged at DEBUG level)" if n == LOG_FIRST else ""
        log.log(level, "%s: %s at byte %d: %s%s", self.NAME, kind.replace("_", " "), offset, reason, suffix)
