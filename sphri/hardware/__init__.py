"""Hardware over serial: the haptic glove, a tactile skin, and device simulators.

Entry points (``key=value`` arguments, pipeline overrides passed through):

- ``sphri glove replay``: play a trial's contacts to the glove;
- ``sphri skin record|live``: save a skin's frames, or
  classify touch live with a model file (:mod:`sphri.export`, which also
  trains and saves one: ``sphri export``);
- ``sphri simulate skin|glove``: emulate a device on a
  pseudo-terminal or socket (:mod:`~sphri.hardware.sim_skin`,
  :mod:`~sphri.hardware.sim_glove`).

Protocols (``docs/PROTOCOLS.md``) are pure encoders/decoders
(:mod:`~sphri.hardware.glove_protocol`, :mod:`~sphri.hardware.skin_protocol`,
:mod:`~sphri.hardware.framing`); transport is :mod:`~sphri.hardware.transport`.
"""

from sphri.hardware.framing import DecoderStats, StreamDecoder, crc8, crc16
from sphri.hardware.glove_protocol import Ack, ActuateCommand, GloveDecoder, encode_ack, encode_actuate
from sphri.hardware.recording import SkinRecording, load_recording, save_recording
from sphri.hardware.skin_protocol import SkinDecoder, SkinFrame, ValueFormat, encode_frame

__all__ = [
    "Ack",
    "ActuateCommand",
    "DecoderStats",
    "GloveDecoder",
    "SkinDecoder",
    "SkinFrame",
    "SkinRecording",
    "StreamDecoder",
    "ValueFormat",
    "crc16",
    "crc8",
    "encode_ack",
    "encode_actuate",
    "encode_frame",
    "load_recording",
    "save_recording",
]
