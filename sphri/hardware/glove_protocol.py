"""The haptic glove's serial protocol, version 1 (pure encoding/decoding).

Documented with byte-level examples in ``docs/PROTOCOLS.md`` (section
"Glove protocol"); a test decodes the examples printed there.

Every message is ``START (0xA5) | LEN | payload (LEN bytes) | CRC16`` where
the CRC-16/CCITT-FALSE covers ``LEN`` and the payload and is sent
little-endian. The payload starts with ``version, type, seq, glove_id``.

- ``ACTUATE`` (host -> glove, type 0x01, LEN 22): six intensities (uint8,
  0 = off) then six pulse lengths (uint16 LE, milliseconds), in the order
  of :data:`ACTUATORS`. Each actuator with intensity > 0 vibrates at that
  intensity for its pulse length from the moment the message arrives; a
  new ACTUATE replaces the running pulses (intensity 0 stops at once).
- ``ACK`` (glove -> host, type 0x81, LEN 5): echoes ``seq`` and
  ``glove_id`` with a status byte (:class:`AckStatus`). A message with a
  bad checksum is not acknowledged; the host counts it as missing.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass
from typing import Any

from sphri.hardware.framing import Parse, StreamDecoder, crc16

#: Protocol version carried in every message.
VERSION = 1
#: Start byte of every message.
START = 0xA5
#: Actuator order of the intensity and pulse arrays (one per finger, one on the palm).
ACTUATORS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "pinky", "palm")
N_ACTUATORS = len(ACTUATORS)

TYPE_ACTUATE = 0x01
TYPE_ACK = 0x81

_ACTUATE = struct.Struct("<BBBB6B6H")  # version, type, seq, glove_id, intensity[6], pulse_ms[6]
_ACK = struct.Struct("<BBBBB")  # version, type, seq, glove_id, status
#: Payload length of each message type.
PAYLOAD_LEN = {TYPE_ACTUATE: _ACTUATE.size, TYPE_ACK: _ACK.size}


class AckStatus(enum.IntEnum):
    """Status byte of an ACK."""

    OK = 0
    BAD_VERSION = 1
    """The glove does not speak this protocol version (nothing was actuated)."""
    BAD_VALUE = 2
    """A field was out of range for this glove (e.g. pulse too long); nothing actuated."""


@dataclass(frozen=True)
class ActuateCommand:
    """Drive the six actuators: intensity 0..255 (0 = off), pulse length in ms."""

    seq: int
    glove_id: int
    intensity: tuple[int, ...]
    pulse_ms: tuple[int, ...]

    def __post_init__(self) -> None:
        if not 0 <= self.seq <= 255:
            raise ValueError(f"seq={self.seq} must be in [0, 255]")
        if not 0 <= self.glove_id <= 255:
            raise ValueError(f"glove_id={self.glove_id} must be in [0, 255]")
        if len(self.intensity) != N_ACTUATORS or len(self.pulse_ms) != N_ACTUATORS:
            raise ValueError(f"intensity and pulse_ms need {N_ACTUATORS} values ({', '.join(ACTUATORS)})")
        if any(not 0 <= int(v) <= 255 for v in self.intensity):
            raise ValueError(f"intensity={self.intensity} values must be in [0, 255]")
        if any(not 0 <= int(v) <= 65535 for v in self.pulse_ms):
            raise ValueError(f"pulse_ms={self.pulse_ms} values must be in [0, 65535] ms")

    @property
    def active(self) -> bool:
        return any(self.intensity)

    def describe(self) -> str:
        parts = [
            f"{name}={i}/{p}ms" if i else f"{name}=off" for name, i, p in zip(ACTUATORS, self.intensity, self.pulse_ms)
        ]
        return f"ACTUATE seq={self.seq} glove={self.glove_id} " + " ".join(parts)


@dataclass(frozen=True)
class Ack:
    """The glove's acknowledgement of the ACTUATE with sequence number ``seq``."""

    seq: int
    glove_id: int
    status: int

    def describe(self) -> str:
        try:
            st = AckStatus(self.status).name
        except ValueError:
            st = f"status {self.status}"
        return f"ACK seq={self.seq} glove={self.glove_id} {st}"


def _frame(payload: bytes) -> bytes:
    body = bytes([len(payload)]) + payload
    return bytes([START]) + body + struct.pack("<H", crc16(body))


def encode_actuate(cmd: ActuateCommand) -> bytes:
    """The 26 bytes of an ACTUATE message."""
    return _frame(_ACTUATE.pack(VERSION, TYPE_ACTUATE, cmd.seq, cmd.glove_id, *cmd.intensity, *cmd.pulse_ms))


def encode_ack(ack: Ack) -> bytes:
    """The 9 bytes of an ACK message."""
    return _frame(_ACK.pack(VERSION, TYPE_ACK, ack.seq, ack.glove_id, ack.status))


class GloveDecoder(StreamDecoder):
    """Streaming decoder of glove messages (either direction).

    ``feed(chunk)`` returns :class:`ActuateCommand` and :class:`Ack` objects;
    broken messages are counted in ``stats`` and skipped.
    """

    SYNC = bytes([START])
    NAME = "glove stream"

    def _parse(self, buf: bytearray, i: int) -> tuple[Parse, int, Any]:
        if len(buf) - i < 2:
            return Parse.NEED_MORE, 0, None
        n = buf[i + 1]
        if n not in PAYLOAD_LEN.values():
            return Parse.BAD_HEADER, 2, f"length {n} is no message's length ({sorted(PAYLOAD_LEN.values())})"
        total = n + 4
        if len(buf) - i < total:
            return Parse.NEED_MORE, 0, None
        body = buf[i + 1 : i + 2 + n]
        (got,) = struct.unpack_from("<H", buf, i + 2 + n)
        want = crc16(body)
        if got != want:
            return Parse.BAD_CHECKSUM, total, f"CRC {got:#06x} != {want:#06x}"
        return Parse.OK, total, bytes(body[1:])

    def _accept(self, payload: Any, offset: int) -> bool:
        version, mtype = payload[0], payload[1]
        if version != VERSION:
            self._count("bad_message", offset, f"protocol version {version} (this host speaks {VERSION})")
            return False
        if PAYLOAD_LEN.get(mtype) != len(payload):
            self._count("bad_message", offset, f"message type {mtype:#04x} with {len(payload)} payload bytes")
            return False
        return True

    def feed(self, data: bytes | bytearray | memoryview) -> list[ActuateCommand | Ack]:
        out: list[ActuateCommand | Ack] = []
        for payload in super().feed(data):
            mtype = payload[1]
            if mtype == TYPE_ACTUATE:
                _, _, seq, gid, *rest = _ACTUATE.unpack(payload)
                out.append(ActuateCommand(seq=seq, glove_id=gid, intensity=tuple(rest[:6]), pulse_ms=tuple(rest[6:])))
            else:
                _, _, seq, gid, status = _ACK.unpack(payload)
                out.append(Ack(seq=seq, glove_id=gid, status=status))
        return out
