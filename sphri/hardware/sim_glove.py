"""The glove simulator: acknowledges ACTUATE messages like the glove firmware, on a pseudo-terminal or socket.

::

    sphri simulate glove ack_drop_rate=0.1

It can drop or delay ACKs, and keeps a ledger of what it received and answered (``report=file.json``),
so tests check the real driver (:mod:`sphri.hardware.glove`) against it. Endpoints:
:mod:`sphri.hardware.transport`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from sphri.config import setting
from sphri.hardware.glove_protocol import ACTUATORS, Ack, ActuateCommand, GloveDecoder, encode_ack
from sphri.hardware.transport import DeviceSettings, HostGone, Stopped, open_endpoint

log = logging.getLogger(__name__)


@dataclass
class GloveSimSettings(DeviceSettings):
    """``sphri simulate glove``: the glove's settings (and the endpoint's)."""

    ack_drop_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """Probability of not acknowledging a command."""
    ack_delay_s: float = setting(0.0, lo=0.0, hi=10.0)
    """Delay before each acknowledgement (seconds)."""
    duration_s: float = setting(0.0, lo=0.0)
    """Stop after this many seconds (0 = until the host disconnects)."""


@dataclass
class GloveLedger:
    """What the glove simulator received and answered."""

    commands: int = 0
    acks_sent: int = 0
    acks_dropped: int = 0
    actuations: int = 0
    """Commands with at least one actuator on."""
    on_frames: dict[str, int] = field(default_factory=dict)
    """Per actuator: commands that switched it on."""
    decoder: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0

    def to_json(self) -> dict:
        return asdict(self)


class GloveSimulator:
    """Acknowledges ACTUATE messages like the glove firmware (optionally dropping ACKs)."""

    def __init__(self, settings: GloveSimSettings, endpoint, say: Callable[[str], None] = print, verbose: bool = False):
        self.s = settings
        self.endpoint = endpoint
        self.say = say
        self.verbose = verbose
        self.ledger = GloveLedger()
        self.decoder = GloveDecoder()
        self.rng = np.random.default_rng(settings.seed)
        self.stop = threading.Event()
        self.ready = threading.Event()

    def run(self) -> GloveLedger:
        t0 = time.monotonic()
        try:
            open_endpoint(self.endpoint, self.stop, self.ready)
            while not self.stop.is_set():
                if self.s.duration_s and time.monotonic() - t0 >= self.s.duration_s:
                    break
                data = self.endpoint.read()
                if not data:
                    time.sleep(0.002)
                    continue
                for msg in self.decoder.feed(data):
                    if not isinstance(msg, ActuateCommand):
                        continue
                    self.ledger.commands += 1
                    if msg.active:
                        self.ledger.actuations += 1
                    for name, level in zip(ACTUATORS, msg.intensity):
                        if level:
                            self.ledger.on_frames[name] = self.ledger.on_frames.get(name, 0) + 1
                    if self.verbose:
                        self.say(f"glove simulator: {msg.describe()}")
                    if self.rng.random() < self.s.ack_drop_rate:
                        self.ledger.acks_dropped += 1
                        continue
                    if self.s.ack_delay_s:
                        time.sleep(self.s.ack_delay_s)
                    self.endpoint.write(encode_ack(Ack(msg.seq, msg.glove_id, 0)), self.stop)
                    self.ledger.acks_sent += 1
        except (Stopped, HostGone) as exc:
            log.info("glove simulator stopped: %s", exc or type(exc).__name__)
        finally:
            self.ledger.decoder = self.decoder.stats.as_dict()
            self.ledger.seconds = time.monotonic() - t0
            self.endpoint.close()
            self.ready.set()
        return self.ledger
