"""Drive the haptic glove: schedule actuator messages, send them, check ACKs.

::

    sphri glove replay port=loop:// trial=0 participant=participant_01 +debug=fast
    sphri glove replay port=/dev/rfcomm0 trial=3 robot=nao_child realtime=true

``replay`` composes the pipeline config from the remaining overrides, takes
the trial's contacts (``contact`` stage, cached), maps them to the glove's
six actuators (:mod:`sphri.hardware.actuators`), schedules messages
(:func:`schedule`: only when the glove's state must change, at most
``rate_hz`` per second) and sends them (:class:`GloveDriver`), in real time
or as fast as possible. With ``port=loop://`` it prints the command stream
and checks that every message reads back intact. Protocol:
``docs/PROTOCOLS.md`` and :mod:`sphri.hardware.glove_protocol`.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from sphri.args import settings_main
from sphri.config import ConfigError
from sphri.hardware.actuators import ActuatorMap, part_depths
from sphri.hardware.framing import TRAFFIC
from sphri.hardware.glove_protocol import (
    ACTUATORS,
    N_ACTUATORS,
    Ack,
    AckStatus,
    ActuateCommand,
    GloveDecoder,
    encode_actuate,
)
from sphri.hardware.settings import GloveReplaySettings
from sphri.hardware.transport import Link, PortError, is_loopback

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PlannedMessage:
    """One ACTUATE to send at stream time ``t_s`` (frame ``frame`` of the trial)."""

    frame: int
    t_s: float
    intensity: tuple[int, ...]
    pulse_ms: tuple[int, ...]


def schedule(
    intensity: np.ndarray,
    remaining_ms: np.ndarray,
    frame_rate_hz: float,
    rate_hz: float | None = None,
) -> list[PlannedMessage]:
    """Messages that make the glove follow the desired actuator states.

    ``intensity`` (F, 6) uint8 and ``remaining_ms`` (F, 6) are the desired
    state at each frame (:meth:`ActuatorMap.desired`). The glove runs each
    pulse out by itself, so a message is sent only when its predicted state
    differs from the desired one: an intensity change (on, off, level), or
    a pulse about to end (within 1.5 frames) while it should go on. At most
    one message per ``1 / rate_hz`` seconds of stream time (default: the
    frame rate); a deferred change goes out with the next allowed frame.
    After the last frame, anything still on is stopped.
    """
    intensity = np.asarray(intensity)
    remaining_ms = np.asarray(remaining_ms, dtype=np.float64)
    if intensity.shape != remaining_ms.shape or intensity.ndim != 2 or intensity.shape[1] != N_ACTUATORS:
        raise ValueError(
            f"intensity and remaining_ms must both be (F, {N_ACTUATORS}), got {intensity.shape} and {remaining_ms.shape}"
        )
    if not frame_rate_hz > 0:
        raise ValueError(f"frame_rate_hz={frame_rate_hz} must be > 0")
    rate_hz = frame_rate_hz if not rate_hz else float(rate_hz)
    frame_ms = 1000.0 / frame_rate_hz
    refresh = 1.5 * frame_ms
    min_gap_ms = 1000.0 / rate_hz - 1e-6
    glove_level = np.zeros(N_ACTUATORS, dtype=np.int64)
    glove_until = np.zeros(N_ACTUATORS, dtype=np.float64)  # stream time (ms) each pulse ends
    last_sent = -np.inf
    out: list[PlannedMessage] = []
    n = intensity.shape[0]
    for f in range(n + 1):
        t = f * frame_ms
        if f < n:
            want = np.where(remaining_ms[f] > 0, intensity[f].astype(np.int64), 0)
            want_rem = np.where(want > 0, remaining_ms[f], 0.0)
        else:  # after the trial: everything off
            want = np.zeros(N_ACTUATORS, dtype=np.int64)
            want_rem = np.zeros(N_ACTUATORS)
        left = glove_until - t
        predicted = np.where(left > 1e-9, glove_level, 0)
        ending = (want > 0) & (left < np.minimum(refresh, want_rem) - 1e-6)
        if not (np.any(predicted != want) or np.any(ending)):
            continue
        if t - last_sent < min_gap_ms and f < n:
            continue  # rate limit: the next frame re-evaluates
        pulse = np.where(want > 0, np.clip(np.rint(want_rem), 1, 65535), 0).astype(np.int64)
        out.append(PlannedMessage(f, t / 1000.0, tuple(int(v) for v in want), tuple(int(v) for v in pulse)))
        glove_level = want
        glove_until = t + pulse.astype(np.float64)
        last_sent = t
    return out


@dataclass
class GloveReport:
    """What a replay did."""

    sent: int = 0
    acked: int = 0
    missing_acks: int = 0
    refused: int = 0
    """ACKs with a status other than OK."""
    unexpected_acks: int = 0
    """ACKs for no outstanding message (late, duplicated or for another host)."""
    echoed: int = 0
    """loop:// only: messages read back intact."""
    echo_mismatch: int = 0
    """loop:// only: messages read back different from what was sent."""
    ack_latency_ms: list[float] = field(default_factory=list)
    decoder: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0

    def lines(self) -> list[str]:
        out = [f"sent {self.sent} message(s) in {self.seconds:.2f} s"]
        if self.echoed or self.echo_mismatch:
            out.append(f"loopback: {self.echoed} read back intact, {self.echo_mismatch} differ")
        if self.acked or self.missing_acks or self.refused:
            lat = np.asarray(self.ack_latency_ms)
            med = f", median ACK latency {np.median(lat):.1f} ms" if lat.size else ""
            out.append(
                f"acks: {self.acked} ok, {self.refused} refused, {self.missing_acks} missing, "
                f"{self.unexpected_acks} unexpected{med}"
            )
        errors = {k: v for k, v in self.decoder.items() if v and k not in TRAFFIC}
        if errors:
            out.append("receive errors: " + ", ".join(f"{k}={v}" for k, v in errors.items()))
        return out


class GloveDriver:
    """Sends ACTUATE messages over a :class:`Link` and accounts for the replies.

    ``acks``: expect an ACK for every message (missing ones are counted
    after ``ack_timeout_s``). On a loopback port the bytes read back are
    the messages themselves; they are compared with what was sent.
    """

    def __init__(
        self,
        link: Link,
        glove_id: int = 1,
        acks: bool = True,
        ack_timeout_s: float = 0.25,
        show: Callable[[str], None] | None = None,
    ) -> None:
        self.link = link
        self.glove_id = glove_id
        self.acks = acks
        self.ack_timeout_s = ack_timeout_s
        self.show = show
        self.loopback = is_loopback(link.port)
        self.decoder = GloveDecoder()
        self.report = GloveReport()
        self._seq = 0
        self._outstanding: dict[int, tuple[float, ActuateCommand]] = {}
        self._echo: dict[int, ActuateCommand] = {}

    def send(self, intensity: Sequence[int], pulse_ms: Sequence[int], label: str = "") -> ActuateCommand:
        """Send one ACTUATE (next sequence number) and process any replies."""
        cmd = ActuateCommand(
            self._seq, self.glove_id, tuple(int(v) for v in intensity), tuple(int(v) for v in pulse_ms)
        )
        self._seq = (self._seq + 1) % 256
        data = encode_actuate(cmd)
        self.link.write(data)
        now = time.monotonic()
        self.report.sent += 1
        if self.loopback:
            self._echo[cmd.seq] = cmd
        elif self.acks:
            if cmd.seq in self._outstanding:  # 256 messages in flight: the old one is lost
                self._missing(cmd.seq)
            self._outstanding[cmd.seq] = (now, cmd)
        if self.show is not None:
            self.show(f"{label}{data.hex(' ')}  {cmd.describe()}")
        self.poll()
        return cmd

    def poll(self) -> None:
        """Read and account for whatever arrived; expire overdue ACKs."""
        data = self.link.read(wait=False)
        if data:
            self._handle(self.decoder.feed(data))
        self._expire(time.monotonic())

    def finish(self) -> GloveReport:
        """Wait up to ``ack_timeout_s`` for outstanding ACKs (or loopback echoes), then report."""
        deadline = time.monotonic() + self.ack_timeout_s
        while (self._outstanding or self._echo) and time.monotonic() < deadline:
            data = self.link.read()
            if data:
                self._handle(self.decoder.feed(data))
        self.decoder.close()  # the session ends: bytes left buffered are counted in the report
        for seq in list(self._outstanding):
            self._missing(seq)
        self.report.echo_mismatch += len(self._echo)
        self._echo.clear()
        self.report.decoder = self.decoder.stats.as_dict()
        return self.report

    def _handle(self, messages: list[ActuateCommand | Ack]) -> None:
        now = time.monotonic()
        for msg in messages:
            if isinstance(msg, ActuateCommand):
                sent = self._echo.pop(msg.seq, None)
                if sent is not None and sent == msg:
                    self.report.echoed += 1
                else:
                    self.report.echo_mismatch += 1
                    log.warning("glove: read back %s, which was not sent", msg.describe())
                continue
            entry = self._outstanding.pop(msg.seq, None)
            if entry is None or msg.glove_id != self.glove_id:
                self.report.unexpected_acks += 1
                log.warning("glove: unexpected %s", msg.describe())
                continue
            self.report.ack_latency_ms.append((now - entry[0]) * 1000.0)
            if msg.status == AckStatus.OK:
                self.report.acked += 1
            else:
                self.report.refused += 1
                log.warning("glove refused message: %s", msg.describe())

    def _expire(self, now: float) -> None:
        for seq, (t, _) in list(self._outstanding.items()):
            if now - t > self.ack_timeout_s:
                self._missing(seq)

    def _missing(self, seq: int) -> None:
        self._outstanding.pop(seq, None)
        self.report.missing_acks += 1
        n = self.report.missing_acks
        if n <= 20:
            log.warning(
                "glove: no ACK for message seq=%d within %.2f s%s",
                seq,
                self.ack_timeout_s,
                " (further missing ACKs are logged at DEBUG level)" if n == 20 else "",
            )
        else:
            log.debug("glove: no ACK for message seq=%d", seq)


def play(
    messages: Sequence[PlannedMessage],
    driver: GloveDriver,
    realtime: bool = True,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> GloveReport:
    """Send ``messages`` at their stream times (``realtime``) or back to back."""
    t0 = clock()
    try:
        for m in messages:
            if realtime:
                while True:
                    wait = t0 + m.t_s - clock()
                    if wait <= 0:
                        break
                    driver.poll()
                    sleep(min(wait, 0.005))
            driver.send(m.intensity, m.pulse_ms, label=f"t={m.t_s:7.3f}s frame {m.frame:5d}  ")
    except KeyboardInterrupt:
        driver.send((0,) * N_ACTUATORS, (0,) * N_ACTUATORS, label="interrupted: all off  ")
        raise
    report = driver.finish()
    report.seconds = clock() - t0
    return report


def select_trial(trials, trial: int, participant: str | None) -> int:
    """Row of ``trials`` (GestureDataset.trials) for ``trial`` (0-based) of ``participant``."""
    if participant is not None:
        rows = np.flatnonzero(trials["participant"].to_numpy() == participant)
        if rows.size == 0:
            names = sorted(set(trials["participant"]))
            shown = ", ".join(names[:10]) + (" ..." if len(names) > 10 else "")
            raise ConfigError(f"participant={participant!r} is invalid: the dataset has {shown}")
        if trial >= rows.size:
            raise ConfigError(f"trial={trial} is invalid: {participant} has {rows.size} trials (0..{rows.size - 1})")
        return int(rows[trial])
    if trial >= len(trials):
        raise ConfigError(f"trial={trial} is invalid: the dataset has {len(trials)} trials (0..{len(trials) - 1})")
    return trial


def replay(settings: GloveReplaySettings, overrides: Sequence[str], out: Callable[[str], None] = print) -> GloveReport:
    """``glove replay``: compose the pipeline, pick the trial, play its contacts to the glove."""
    from sphri.hardware.source import open_pipeline

    p = open_pipeline(overrides)
    dataset = p.get("data")
    contacts = p.get("contact")
    hand = p.get("hand")
    row = select_trial(dataset.trials, settings.trial, settings.participant)
    t = dataset.trials.iloc[row]
    start, n = int(t["start"]), int(t["n_frames"])
    depth = part_depths(contacts, hand, start, n)
    amap = ActuatorMap(
        settings.pulse_ms,
        settings.intensity,
        settings.intensity_min,
        settings.intensity_max,
        settings.depth_full_m,
        settings.trigger,
    )
    level, remaining = amap.desired(depth, dataset.frame_rate_hz)
    messages = schedule(level, remaining, dataset.frame_rate_hz, settings.rate_hz or None)
    touching = (depth > 0).sum(axis=0)
    out(
        f"trial {row}: {t['participant']} {t['region']} #{int(t['trial_ordinal'])} {t['trial_id']} "
        f"({t['gesture']}), {n} frames at {dataset.frame_rate_hz:g} Hz = {n / dataset.frame_rate_hz:.2f} s"
    )
    out("frames in contact per actuator: " + ", ".join(f"{a}={int(c)}" for a, c in zip(ACTUATORS, touching)))
    out(
        f"{len(messages)} message(s) to {settings.port} (glove {settings.glove_id}, "
        f"{'real time' if settings.realtime else 'as fast as possible'})"
    )
    loop = is_loopback(settings.port)
    acks = settings.acks == "on" or (settings.acks == "auto" and not loop)
    show = settings.show == "on" or (settings.show == "auto" and loop)
    with Link(settings.port, settings.baud) as link:
        driver = GloveDriver(link, settings.glove_id, acks, settings.ack_timeout_s, show=out if show else None)
        report = play(messages, driver, realtime=settings.realtime)
    for line in report.lines():
        out(line)
    return report


#: The commands and their settings (``replay`` also takes config overrides).
COMMANDS = {"replay": (GloveReplaySettings, True)}


@settings_main("sphri glove", COMMANDS)
def main(_cmd: str, settings: GloveReplaySettings, overrides: list[str]) -> int:
    """``sphri glove replay key=value ... [overrides ...]``: the keys of :class:`GloveReplaySettings`, any
    other ``key=value`` a config override (+debug=fast)."""
    try:
        report = replay(settings, overrides)
    except PortError as exc:
        print(f"sphri glove: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    return 1 if report.missing_acks or report.echo_mismatch else 0
