"""The skin simulator: streams frames in the skin protocol on a pseudo-terminal or socket.

::

    sphri simulate skin +debug=fast trials=8 corrupt_rate=0.05
    sphri simulate skin source=pattern grid=18x6 port=socket://127.0.0.1:7777

The frames are encoded synthetic trials of the composed pipeline config
(``source=pipeline``: the encoder's output with its noise, untouched gaps
between trials) or moving blobs (``source=pattern``), with optional injected
faults (garbage bursts, corrupted bytes, dropped frames, truncated frames,
wrong taxel counts, an unplug/replug). A ledger of what it did
(``report=file.json``) is what tests check the real reader against.
Endpoints (``port=pty`` with ``link=``, or ``port=socket://HOST:PORT``):
:mod:`sphri.hardware.transport`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from sphri.config import ConfigError, require, setting
from sphri.hardware.settings import parse_grid
from sphri.hardware.skin_protocol import CMD_START, ValueFormat, encode_frame, find_control
from sphri.hardware.transport import DeviceSettings, HostGone, Stopped, make_endpoint, open_endpoint
from sphri.types import GESTURES

log = logging.getLogger(__name__)


@dataclass
class SkinSimSettings(DeviceSettings):
    """``sphri simulate skin``: the skin's settings (and the endpoint's)."""

    source: str = setting("pipeline", choices=("pipeline", "pattern"))
    """pipeline (encoded synthetic trials of the composed config) or pattern (moving blobs)."""
    trials: int = 8
    """pipeline source: number of trials streamed (-1 = all selected)."""
    participant: str | None = None
    """pipeline source: stream only this participant's trials."""
    taxels: int = setting(0, lo=0, hi=4096)
    """pattern source: taxel count (0 = from grid)."""
    grid: str = "18x6"
    """pattern source: grid shape HxW."""
    frames: int = setting(600, lo=1)
    """pattern source: frames to stream."""
    rate_hz: float = setting(0.0, lo=0.0, hi=10_000.0)
    """Frames per second (0 = the dataset's frame rate, 90 for patterns)."""
    realtime: bool = True
    """Pace frames at rate_hz; false streams as fast as the link takes them, each frame stamped with
    the time it has at rate_hz (the same bytes for the same seed)."""
    format: str = setting("auto", choices=("auto", "u8", "u16", "bits"))
    """Value format u8, u16, bits, or auto (bits for binary encoders, u8 otherwise)."""
    gap_s: float = setting(0.5, lo=0.0, hi=60.0)
    """pipeline source: untouched (noise-only) seconds before each trial."""
    garbage_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """Probability per frame of a burst of random bytes before it."""
    corrupt_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """Probability per frame of a flipped byte (bad checksum)."""
    drop_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """Probability per frame of not sending it (sequence gap)."""
    truncate_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """Probability per frame of sending only its first part."""
    wrong_count_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """Probability per frame of a valid frame with a wrong taxel count instead."""
    unplug_after_s: float = setting(0.0, lo=0.0)
    """Simulate unplugging after this many seconds of streaming (0 = never)."""
    unplug_s: float = setting(1.0, lo=0.0, hi=600.0)
    """How long the device stays unplugged (seconds)."""
    wait_start: bool = True
    """Wait for the host's START message before streaming (and after a replug)."""
    hold_s: float = setting(1.0, lo=0.0, hi=600.0)
    """Keep the port open this long after the last frame (seconds)."""

    def check(self) -> None:
        super().check()
        require(self.trials == -1 or self.trials >= 1, "trials", self.trials, "a count >= 1, or -1 for all")
        parse_grid(self.grid)
        total = self.corrupt_rate + self.drop_rate + self.truncate_rate + self.wrong_count_rate
        require(
            total <= 1.0,
            "corrupt_rate",
            self.corrupt_rate,
            f"corrupt + drop + truncate + wrong_count rates must sum to <= 1 (got {total:g})",
        )


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
        return {**asdict(self), "corrupt": self.corrupt, "lost": self.lost}


def choose_format(fmt: str, binary: bool) -> ValueFormat:
    if fmt == "auto":
        return ValueFormat.BITS if binary else ValueFormat.U8
    return ValueFormat[fmt.upper()]


@dataclass
class _Playback:
    """Where the simulator is in its stream: the sequence number, the schedule's start (``time.monotonic``
    s), and where the intact frames went."""

    t0: float
    seq: int = 0
    good_at: dict[int, int] = field(default_factory=dict)
    """Stream frame -> its position among the intact frames."""
    trial_good: dict[int, list[int]] = field(default_factory=dict)
    """Trial -> the positions of its intact frames."""


class SkinSimulator:
    """Streams a :class:`SkinStream` over an endpoint with injected faults."""

    def __init__(self, stream: SkinStream, settings: SkinSimSettings, endpoint, say: Callable[[str], None] = print):
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
        """Connect, play every frame slot (paced at the rate when ``realtime``, unplugging once when asked),
        record each trial's intact frames in the ledger, then hold the port ``hold_s`` seconds."""
        s, led = self.s, self.ledger
        values = self.stream.values
        self._connect()
        self.say(
            f"skin simulator: streaming {len(values)} frames of {values.shape[1]} taxels ({self.fmt.name}) at {self.rate_hz:g} Hz"
        )
        play = _Playback(t0=time.monotonic())
        stream_t0 = play.t0
        unplug_done = False
        period = 1.0 / self.rate_hz
        for i in range(len(values)):
            if self.stop.is_set():
                raise Stopped()
            if s.realtime:
                delay = play.t0 + i * period - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            if s.unplug_after_s > 0 and not unplug_done and time.monotonic() - stream_t0 >= s.unplug_after_s:
                unplug_done = True
                pause_start = time.monotonic()
                self._unplug(encode_frame(play.seq, 0, values[i], self.fmt))
                led.slots += 1
                play.seq = 0  # the device restarts
                play.t0 += time.monotonic() - pause_start  # resume the schedule where it was
                continue
            # paced: the clock's time; as fast as the link goes: the time the frame has at rate_hz, so
            # that a seed gives the same bytes in every run (a clock-dependent timestamp changed which
            # bytes of a broken frame happened to look like a sync, and with it the decoder's counts)
            t_us = int((time.monotonic() - stream_t0) * 1e6) if s.realtime else round(i * period * 1e6)
            self._play_slot(i, t_us, play)
            play.seq = (play.seq + 1) & 0xFFFF
        led.trials.extend(self._trial_entries(play))
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

    def _play_slot(self, i: int, t_us: int, play: _Playback) -> None:
        """Send stream frame ``i`` (device time ``t_us`` microseconds, sequence ``play.seq``) with the faults
        the rates draw: garbage before it, then corrupted, dropped, truncated, of a wrong count, or intact
        (its position among the intact frames kept in ``play``); counted in the ledger."""
        s, led, rng = self.s, self.ledger, self.rng
        n_taxels = self.stream.values.shape[1]
        frame = encode_frame(play.seq, t_us, self.stream.values[i], self.fmt)
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
            wrong = encode_frame(play.seq, t_us, rng.random(n_taxels + delta).astype(np.float32), self.fmt)
            self._send(wrong)
            led.wrong_count += 1
            led.wrong_count_bytes += len(wrong)
        else:
            self._send(frame)
            led.good += 1
            led.good_bytes += len(frame)
            led.good_index.append(i)
            led.good_seq.append(play.seq)
            play.good_at[i] = led.good - 1
            k = int(self.stream.trial[i])
            if k >= 0:
                play.trial_good.setdefault(k, []).append(led.good - 1)

    def _trial_entries(self, play: _Playback) -> list[dict]:
        """Each trial's ledger entry: its metadata and the positions among the intact frames of its first,
        last + 1 and onset frames (-1 when none was sent intact)."""
        first_frame: dict[int, int] = {}  # trial -> its first stream frame
        for i, k in enumerate(self.stream.trial.tolist()):
            if k >= 0:
                first_frame.setdefault(k, i)
        entries = []
        for k, meta in enumerate(self.stream.trials):
            got = play.trial_good.get(k, [])
            entry = {**meta, "good_start": got[0] if got else -1, "good_end": got[-1] + 1 if got else -1}
            first = first_frame.get(k)
            onset = meta.get("onset", -1)
            if first is not None and onset >= 0:  # the onset frame's position among intact frames, if sent intact
                entry["good_onset"] = play.good_at.get(first + onset, -1)
            entries.append(entry)
        return entries

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


def skin_simulator(
    settings: SkinSimSettings, overrides: Sequence[str] = (), say: Callable[[str], None] = print
) -> SkinSimulator:
    """The simulator ``settings`` describe, on its endpoint: the pipeline's trials (composed from
    ``overrides``) or a pattern (no overrides). Raises ConfigError naming the setting."""
    if settings.source == "pipeline":
        stream = pipeline_stream(overrides, settings.trials, settings.participant, settings.gap_s, settings.seed)
    else:
        if overrides:
            raise ConfigError(f"pipeline overrides {list(overrides)} need source=pipeline")
        grid = parse_grid(settings.grid)
        assert grid is not None
        if settings.taxels and settings.taxels != grid[0] * grid[1]:
            raise ConfigError(f"taxels={settings.taxels} is invalid: grid={settings.grid} holds {grid[0] * grid[1]}")
        stream = pattern_stream(grid, settings.frames, settings.seed)
    return SkinSimulator(stream, settings, make_endpoint(settings), say)
