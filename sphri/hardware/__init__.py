"""Hardware over serial: the haptic glove, a tactile skin, and device simulators.

Entry points (``key=value`` arguments, pipeline overrides passed through):

- ``python -m sphri.hardware.glove replay``: play a trial's contacts to the glove;
- ``python -m sphri.hardware.skin record|live``: save a skin's frames, or
  classify touch live with a model file;
- ``python -m sphri.hardware.train_export``: fit the configured model on the
  pipeline's windows and save a model file;
- ``python -m sphri.hardware.simulate skin|glove``: emulate a device on a
  pseudo-terminal or socket.

Protocols (``docs/PROTOCOLS.md``) are pure encoders/decoders
(:mod:`~sphri.hardware.glove_protocol`, :mod:`~sphri.hardware.skin_protocol`,
:mod:`~sphri.hardware.framing`); transport is :mod:`~sphri.hardware.transport`.
"""

from sphri.hardware.framing import DecoderStats, StreamDecoder, crc8, crc16
from sphri.hardware.glove_protocol import Ack, ActuateCommand, GloveDecoder, encode_ack, encode_actuate
from sphri.hardware.model_file import ModelBundle, load_model, save_model
from sphri.hardware.recording import SkinRecording, load_recording, save_recording
from sphri.hardware.skin_protocol import SkinDecoder, SkinFrame, ValueFormat, encode_frame

__all__ = [
    "Ack",
    "ActuateCommand",
    "DecoderStats",
    "GloveDecoder",
    "ModelBundle",
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
    "load_model",
    "load_recording",
    "save_model",
    "save_recording",
]
