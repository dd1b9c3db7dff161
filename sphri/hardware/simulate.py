"""Device simulators: a tactile skin and a haptic glove on a pseudo-terminal or socket.

::

    python -m sphri.hardware.simulate skin +debug=fast trials=8 corrupt_rate=0.05
    python -m sphri.hardware.simulate skin source=pattern grid=18x6 port=socket://127.0.0.1:7777
    python -m sphri.hardware.simulate glove ack_drop_rate=0.1

The skin simulator streams frames in the skin protocol: encoded synthetic
trials of the composed pipeline config (``source=pipeline``: the encoder's
output with its noise, untouched gaps between trials) or moving blobs
(``source=pattern``), with optional injected faults (garbage bursts,
corrupted bytes, dropped frames, truncated frames, wrong taxel counts, an
unplug/replug). The glove simulator acknowledges ACTUATE messages (and can
drop ACKs). Each keeps a ledger of what it did (``report=file.json``), so
tests check the real reader and driver against it.

``port=pty`` makes a pseudo-terminal; its path is printed (and symlinked
at ``link=`` if given, re-pointed after a replug, like a udev name).
``port=socket://HOST:PORT`` listens there (port 0 = any free port).
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
import select
import socket
import struct
import sys
import termios
import threading
import time
import tty
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from sphri.config import ConfigError
from sphri.errors import clean_errors
from sphri.hardware.glove_protocol import Ack, ActuateCommand, GloveDecoder, encode_ack
from sphri.hardware.settings import SimulateSettings, parse_cli, parse_grid
from sphri.hardware.skin_protocol import CMD_START, ValueFormat, encode_frame, find_control
from sphri.types import GESTURES

log = logging.getLogger(__name__)


class HostGone(RuntimeError):
    """The host side closed the connection (socket endpoints)."""


class Stopped(RuntimeError):
    """The simulator was asked to stop."""


# --------------------------------------------------------------------------- endpoints
class PtyEndpoint:
    """A pseudo-terminal: the host opens :attr:`name` (or the ``link`` symlink)."""

    def __init__(self, link: str = "") -> None:
        self.link = link
        self.master: int | None = None
        self.slave: int | None = None
        self.name = ""

    @property
    def url(self) -> str:
        return self.link or self.name

    def open(self, stop: threading.Event) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no line editing, before any host opens it
        os.set_blocking(self.master, False)
        self.name = os.ttyname(self.slave)
        if self.link:
            tmp = f"{self.link}.tmp{os.getpid()}"
            if os.path.lexists(tmp):
                os.unlink(tmp)
            os.symlink(self.name, tmp)
            os.replace(tmp, self.link)

    def write(self, data: bytes, stop: threading.Event) -> None:
        view = memoryview(data)
        while view:
            if stop.is_set():
                raise Stopped()
            _, w, _ = select.select([], [self.master], [], 0.1)
            if not w:
                continue
            try:
                n = os.write(self.master, view)
            except BlockingIOError:
                continue
            view = view[n:]

    def read(self) -> bytes:
        r, _, _ = select.select([self.master], [], [], 0)
        if not r:
            return b""
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b""
        except OSError as exc:  # EIO: no slave open (cannot happen while we hold one)
            if exc.errno == errno.EIO:
                return b""
            raise

    def pending(self) -> int:
        """Bytes written but not yet read by the host."""
        if self.slave is None:
            return 0
        return struct.unpack("i", fcntl.ioctl(self.slave, termios.FIONREAD, b"\0\0\0\0"))[0]

    def drain(self, stop: threading.Event, timeout_s: float = 5.0) -> None:
        """Wait until the host has read everything written (the kernel moves
        bytes to the slave side asynchronously: settle twice, 20 ms apart)."""
        t0 = time.monotonic()
        settled = 0
        while settled < 2 and time.monotonic() - t0 < timeout_s and not stop.is_set():
            time.sleep(0.02)
            settled = settled + 1 if self.pending() == 0 else 0

    def unplug(self) -> None:
        if self.link and os.path.islink(self.link):
            os.unlink(self.link)
        for fd in (self.master, self.slave):
            if fd is not None:
                os.close(fd)
        self.master = self.slave = None

    close = unplug


class SocketEndpoint:
    """A listening TCP socket; the host connects with ``socket://HOST:PORT``."""

    def __init__(self, url: str) -> None:
        hostport = url[len("socket://") :].split("?", 1)[0]
        host, _, port = hostport.rpartition(":")
        try:
            port_n = int(port)
        except ValueError:
            raise ConfigError(f"port={url!r} is invalid: expected socket://HOST:PORT") from None
        self.server = socket.create_server((host or "127.0.0.1", port_n))
        self.server.settimeout(0.1)
        self.host, self.port = self.server.getsockname()[:2]
        self.conn: socket.socket | None = None
        self._rx = b""

    @property
    def url(self) -> str:
        return f"socket://{self.host}:{self.port}"

    def open(self, stop: threading.Event) -> None:
        while not stop.is_set():
            try:
                self.conn, _ = self.server.accept()
            except TimeoutError:
                continue
            self.conn.settimeout(1.0)
            self.conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            return
        raise Stopped()

    def write(self, data: bytes, stop: threading.Event) -> None:
        assert self.conn is not None
        view = memoryview(data)
        while view:
            if stop.is_set():
                raise Stopped()
            try:
                n = self.conn.send(view)
            except TimeoutError:
                continue
            except OSError as exc:
                raise HostGone(str(exc)) from None
            view = view[n:]

    def read(self) -> bytes:
        assert self.conn is not None
        r, _, _ = select.select([self.conn], [], [], 0)
        if not r:
            return b""
        try:
            data = self.conn.recv(4096)
        except OSError as exc:
            raise HostGone(str(exc)) from None
        if not data:
            raise HostGone("the host closed the connection")
        return data

    def drain(self, stop: threading.Event, timeout_s: float = 5.0) -> None:
        pass  # TCP delivers what was sent before the close

    def unplug(self) -> None:
        if self.conn is not None:
            try:
                self.conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self.conn.close()
            self.conn = None

    def close(self) -> None:
        self.unplug()
        self.server.close()


def open_endpoint(endpoint: PtyEndpoint | SocketEndpoint, stop: threading.Event, ready: threading.Event) -> None:
    """Open ``endpoint`` and set ``ready`` as soon as a host can connect to its url."""
    if isinstance(endpoint, SocketEndpoint):
        ready.set()  # already listening; accept() waits for the host
    endpoint.open(stop)
    ready.set()


def make_endpoint(settings: SimulateSettings) -> PtyEndpoint | SocketEndpoint:
    if settings.port == "pty":
        return PtyEndpoint(settings.link)
    return SocketEndpoint(settings.port)


# --------------------------------------------------------------------------- skin
@dataclass
class SkinStream:
    """What the skin simulator streams: frames, and which trial each belongs to."""

    values: np.ndarray
    """(T, N) float32 in [0, 1]."""
    trial: np.ndarray
    """(T,) int64 index into ``trials`` of each frame, -1 for untouched gaps."""
    trials: list[dict]
    """Per trial: row, label, gesture, participant."""
    rate_hz: float
    binary: bool
    grid_shape: tuple[int, int] | None


def pipeline_stream(
    overrides: Sequence[str], trials: int, participant: str | None, gap_s: float, seed: int
) -> SkinStream:
    """Encoded trials (with the configured noise) of the composed config, separated by gaps."""
    from sphri.hardware.source import encode_trials, open_pipeline, pick_rows

    p = open_pipeline(overrides)
    dataset = p.get("data")
    rows = pick_rows(dataset.trials, trials, participant, seed)
    enc = encode_trials(p, rows, gap_s=gap_s)
    chunks, owner, meta = [], [], []
    for k, (gap, vals, tail) in enumerate(zip(enc.gap, enc.values, enc.tail)):
        chunks += [gap, vals, tail]
        owner += [np.full(len(gap), -1), np.full(len(vals), k), np.full(len(tail), -1)]
        meta.append(
            {
                "row": int(enc.rows[k]),
                "label": int(enc.labels[k]),
                "gesture": GESTURES[int(enc.labels[k])],
                "participant": enc.participants[k],
                "onset": int(enc.onsets[k]),
            }
        )
    if enc.gap:
        chunks.append(enc.gap[0])
        owner.append(np.full(len(enc.gap[0]), -1))
    n = enc.n_taxels
    values = np.concatenate(chunks) if chunks else np.zeros((0, n), np.float32)
    return SkinStream(
        values.astype(np.float32),
        np.concatenate(owner).astype(np.int64) if owner else np.zeros(0, np.int64),
        meta,
        enc.frame_rate_hz,
        enc.binary,
        enc.geometry.grid_shape,
    )


def pattern_stream(grid: tuple[int, int], frames: int, seed: int, noise: float = 0.01) -> SkinStream:
    """Blobs moving over an H x W grid (a 60-frame touch every 135 frames, the first at frame 60)
    with ``noise`` salt-and-pepper flips."""
    h, w = grid
    rng = np.random.default_rng(seed)
    values = np.zeros((frames, h * w), dtype=np.float32)
    trial = np.full(frames, -1, dtype=np.int64)
    meta = []
    uu, vv = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    period, length = 135, 60
    for k, t0 in enumerate(range(60, frames, period)):
        t1 = min(t0 + length, frames)
        u0, v0 = rng.uniform(0, h), rng.uniform(0, w)
        du, dv = rng.normal(0, 0.1, size=2)
        r = rng.uniform(0.8, 2.0)
        for t in range(t0, t1):
            cu, cv = u0 + du * (t - t0), v0 + dv * (t - t0)
            dvw = np.minimum(np.abs(vv - cv), w - np.abs(vv - cv))  # v wraps around the link
            values[t] = ((uu - cu) ** 2 + dvw**2 <= r * r).ravel()
        trial[t0:t1] = k
        meta.append({"row": k, "label": -1, "gesture": "pattern", "participant": "pattern"})
    flip = rng.random(values.shape) < noise
    values[flip] = 1.0 - values[flip]
    return SkinStream(values, trial, meta, 90.0, True, (h, w))


@dataclass
class SkinLedger:
    """What the skin simulator did: the ground truth a reader is checked against."""

    slots: int = 0
    """Frame slots played (each consumes a sequence number)."""
    good: int = 0
    """Frames sent intact."""
    good_bytes: int = 0
    bytes_sent: int = 0
    garbage_bursts: int = 0
    garbage_bytes: int = 0
    corrupt_header: int = 0
    """Frames with a byte flipped in the header (after the sync)."""
    corrupt_body: int = 0
    """Frames with a byte flipped in the values or CRC."""
    dropped: int = 0
    truncated: int = 0
    """Frames cut short (the next bytes are the next frame's)."""
    wrong_count: int = 0
    wrong_count_bytes: int = 0
    unplugs: int = 0
    truncated_by_unplug: int = 0
    """Frames cut short by an unplug (a reader counts them when it reconnects)."""
    starts: int = 0
    """START messages received."""
    format: str = ""
    n_taxels: int = 0
    rate_hz: float = 0.0
    grid_shape: list[int] | None = None
    good_index: list[int] = field(default_factory=list)
    """Stream frame index (row of SkinStream.values) of each intact frame, in order."""
    good_seq: list[int] = field(default_factory=list)
    trials: list[dict] = field(default_factory=list)
    """Per trial: row, label, gesture, participant, onset (first contact frame in
    the trial), and good_start/good_end/good_onset: positions among the intact
    frames (what a reader keeps) of its first, last + 1 and onset frames."""
    seconds: float = 0.0

    @property
    def corrupt(self) -> int:
        return self.corrupt_header + self.corrupt_body

    @property
    def lost(self) -> int:
        """Slots a reader never receives intact (sequence numbers it misses)."""
        return self.corrupt + self.dropped + self.truncated

    def to_json(self) -> dict:
        d = asdict(self)
        d["corrupt"] = self.corrupt
        d["lost"] = self.lost
        return d


def choose_format(fmt: str, binary: bool) -> ValueFormat:
    if fmt == "auto":
        return ValueFormat.BITS if binary else ValueFormat.U8
    return {"u8": ValueFormat.U8, "u16": ValueFormat.U16, "bits": ValueFormat.BITS}[fmt]


class SkinSimulator:
    """Streams a :class:`SkinStream` over an endpoint with injected faults."""

    def __init__(self, stream: SkinStream, settings: SimulateSettings, endpoint, say: Callable[[str], None] = print):
        self.stream = stream
        self.s = settings
        self.endpoint = endpoint
        self.say = say
        self.fmt = choose_format(settings.format, stream.binary)
        self.rate_hz = settings.rate_hz or stream.rate_hz
        self.ledger = SkinLedger(
            format=self.fmt.name,
            n_taxels=int(stream.values.shape[1]),
            rate_hz=self.rate_hz,
            grid_shape=list(stream.grid_shape) if stream.grid_shape else None,
        )
        self.rng = np.random.default_rng(settings.seed)
        self.stop = threading.Event()
        self.ready = threading.Event()
        #: set once every frame was written and the host has read it all (or the simulator stopped)
        self.finished = threading.Event()

    def _wait_start(self) -> None:
        buf = b""
        while not self.stop.is_set():
            try:
                buf += self.endpoint.read()
            except HostGone:
                self.endpoint.unplug()
                self.endpoint.open(self.stop)
                buf = b""
                continue
            cmds = find_control(buf)
            if CMD_START in cmds:
                self.ledger.starts += 1
                return
            buf = buf[-4:]
            time.sleep(0.005)
        raise Stopped()

    def _connect(self) -> None:
        open_endpoint(self.endpoint, self.stop, self.ready)
        if self.s.wait_start:
            self._wait_start()

    def run(self) -> SkinLedger:
        """Stream every frame (blocking); returns the ledger."""
        t_begin = time.monotonic()
        try:
            self._run()
        except (Stopped, HostGone) as exc:
            log.info("skin simulator stopped: %s", exc or type(exc).__name__)
        finally:
            self.ledger.seconds = time.monotonic() - t_begin
            self.endpoint.close()
            self.ready.set()
            self.finished.set()
        return self.ledger

    def _run(self) -> None:
        s, led, rng = self.s, self.ledger, self.rng
        values = self.stream.values
        n_taxels = values.shape[1]
        trial_good: dict[int, list[int]] = {}
        good_at: dict[int, int] = {}  # stream frame -> position among intact frames
        first_frame = {}  # trial -> its first stream frame
        for i, k in enumerate(self.stream.trial.tolist()):
            if k >= 0:
                first_frame.setdefault(k, i)
        self._connect()
        self.say(
            f"skin simulator: streaming {len(values)} frames of {n_taxels} taxels ({self.fmt.name}) at {self.rate_hz:g} Hz"
        )
        seq = 0
        t0 = time.monotonic()
        stream_t0 = t0
        unplug_done = False
        period = 1.0 / self.rate_hz
        for i in range(len(values)):
            if self.stop.is_set():
                raise Stopped()
            if s.realtime:
                delay = t0 + i * period - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            if s.unplug_after_s > 0 and not unplug_done and time.monotonic() - stream_t0 >= s.unplug_after_s:
                unplug_done = True
                pause_start = time.monotonic()
                self._unplug(encode_frame(seq, 0, values[i], self.fmt))
                led.slots += 1
                seq = 0  # the device restarts
                t0 += time.monotonic() - pause_start  # resume the schedule where it was
                continue
            t_us = int((time.monotonic() - stream_t0) * 1e6)
            frame = encode_frame(seq, t_us, values[i], self.fmt)
            if s.garbage_rate and rng.random() < s.garbage_rate:
                junk = rng.integers(0, 256, size=int(rng.integers(1, 33)), dtype=np.uint8).tobytes()
                self._send(junk)
                led.garbage_bursts += 1
                led.garbage_bytes += len(junk)
            r = rng.random()
            edges = np.cumsum([s.corrupt_rate, s.drop_rate, s.truncate_rate, s.wrong_count_rate])
            led.slots += 1
            if r < edges[0]:
                bad = bytearray(frame)
                k = int(rng.integers(2, len(bad)))
                bad[k] ^= int(rng.integers(1, 256))
                self._send(bytes(bad))
                if k < 13:
                    led.corrupt_header += 1
                else:
                    led.corrupt_body += 1
            elif r < edges[1]:
                led.dropped += 1
            elif r < edges[2]:
                self._send(frame[: int(rng.integers(2, len(frame)))])
                led.truncated += 1
            elif r < edges[3]:
                delta = int(rng.integers(1, 4)) * (1 if rng.random() < 0.5 or n_taxels <= 3 else -1)
                wrong = encode_frame(seq, t_us, rng.random(n_taxels + delta).astype(np.float32), self.fmt)
                self._send(wrong)
                led.wrong_count += 1
                led.wrong_count_bytes += len(wrong)
            else:
                self._send(frame)
                led.good += 1
                led.good_bytes += len(frame)
                led.good_index.append(i)
                led.good_seq.append(seq)
                good_at[i] = led.good - 1
                k = int(self.stream.trial[i])
                if k >= 0:
                    trial_good.setdefault(k, []).append(led.good - 1)
            seq = (seq + 1) & 0xFFFF
        for k, meta in enumerate(self.stream.trials):
            got = trial_good.get(k, [])
            entry = {**meta, "good_start": got[0] if got else -1, "good_end": got[-1] + 1 if got else -1}
            first = first_frame.get(k)
            onset = meta.get("onset", -1)
            if (
                first is not None and onset >= 0
            ):  # the onset frame's position among intact frames, if it was sent intact
                entry["good_onset"] = good_at.get(first + onset, -1)
            led.trials.append(entry)
        self.endpoint.drain(self.stop)
        self.finished.set()
        self.say(f"skin simulator: done ({led.good} intact of {led.slots} frames); holding the port {s.hold_s:g} s")
        end = time.monotonic() + s.hold_s
        while time.monotonic() < end and not self.stop.is_set():
            try:
                self.endpoint.read()
            except HostGone:
                break
            time.sleep(0.01)

    def _send(self, data: bytes) -> None:
        self.endpoint.write(data, self.stop)
        self.ledger.bytes_sent += len(data)

    def _unplug(self, frame: bytes) -> None:
        """Send half a frame, wait until the host has read it, disconnect, wait, come back."""
        self._send(frame[: max(2, len(frame) // 2)])
        self.endpoint.drain(self.stop)
        self.endpoint.unplug()
        self.ledger.unplugs += 1
        self.ledger.truncated_by_unplug += 1
        self.say(f"skin simulator: unplugged for {self.s.unplug_s:g} s")
        end = time.monotonic() + self.s.unplug_s
        while time.monotonic() < end:
            if self.stop.is_set():
                raise Stopped()
            time.sleep(0.01)
        self._connect()
        self.say(f"skin simulator: plugged back in at {self.endpoint.url}")


# --------------------------------------------------------------------------- glove
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

    def __init__(self, settings: SimulateSettings, endpoint, say: Callable[[str], None] = print, verbose: bool = False):
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
        from sphri.hardware.glove_protocol import ACTUATORS

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


# --------------------------------------------------------------------------- running
def start_in_thread(sim: SkinSimulator | GloveSimulator, timeout_s: float = 10.0) -> threading.Thread:
    """Run ``sim`` in a daemon thread; returns once its endpoint is open (``sim.endpoint.url``)."""
    result: dict = {}

    def target() -> None:
        result["ledger"] = sim.run()

    th = threading.Thread(target=target, name=f"sphri-{type(sim).__name__}", daemon=True)
    th.start()
    if not sim.ready.wait(timeout_s):
        raise TimeoutError(f"{type(sim).__name__} did not open its endpoint within {timeout_s} s")
    return th


USAGE = """usage: python -m sphri.hardware.simulate skin|glove [key=value ...] [pipeline overrides ...]

skin:  streams frames (skin protocol) of encoded synthetic trials (source=pipeline, with the
       pipeline overrides, e.g. +debug=fast) or moving blobs (source=pattern grid=18x6)
       trials=8 participant=... rate_hz=0 realtime=true format=auto|u8|u16|bits gap_s=0.5
       faults: garbage_rate corrupt_rate drop_rate truncate_rate wrong_count_rate (per frame)
       unplug_after_s=0 unplug_s=1 wait_start=true hold_s=1
glove: acknowledges ACTUATE messages; ack_drop_rate=0 ack_delay_s=0 duration_s=0
both:  port=pty|socket://HOST:PORT link=/tmp/skin.tty seed=0 report=ledger.json
"""


@clean_errors("sphri.hardware.simulate")
def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE)
        return 0 if argv else 2
    device, args = argv[0], argv[1:]
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if device not in ("skin", "glove"):
        print(f"sphri.hardware.simulate: unknown device {device!r} (skin or glove)\n\n{USAGE}", file=sys.stderr)
        return 2
    try:
        settings, overrides = parse_cli(args, SimulateSettings, pipeline=(device == "skin"))
        if device == "skin":
            if settings.source == "pipeline":
                stream = pipeline_stream(
                    overrides, settings.trials, settings.participant, settings.gap_s, settings.seed
                )
            else:
                if overrides:
                    raise ConfigError(f"pipeline overrides {overrides} need source=pipeline")
                grid = parse_grid(settings.grid)
                assert grid is not None
                if settings.taxels and settings.taxels != grid[0] * grid[1]:
                    raise ConfigError(
                        f"taxels={settings.taxels} is invalid: grid={settings.grid} holds {grid[0] * grid[1]}"
                    )
                stream = pattern_stream(grid, settings.frames, settings.seed)
            endpoint = make_endpoint(settings)
            sim: SkinSimulator | GloveSimulator = SkinSimulator(stream, settings, endpoint)
        else:
            endpoint = make_endpoint(settings)
            sim = GloveSimulator(settings, endpoint, verbose=True)
    except ConfigError as exc:
        print(f"sphri.hardware.simulate: invalid setting: {exc}", file=sys.stderr)
        return 2

    def announce() -> None:
        sim.ready.wait()
        where = endpoint.url
        extra = f" (pseudo-terminal {endpoint.name})" if isinstance(endpoint, PtyEndpoint) and endpoint.link else ""
        print(f"{device} simulator ready on {where}{extra}", flush=True)

    threading.Thread(target=announce, daemon=True).start()
    try:
        ledger = sim.run()
    except KeyboardInterrupt:
        sim.stop.set()
        ledger = sim.ledger
    if settings.report:
        Path(settings.report).parent.mkdir(parents=True, exist_ok=True)
        Path(settings.report).write_text(json.dumps(ledger.to_json(), indent=1))
    summary = {k: v for k, v in ledger.to_json().items() if isinstance(v, (int, float)) and v}
    print(
        f"{device} simulator finished: "
        + ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in summary.items()),
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
