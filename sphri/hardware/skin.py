"""Read a tactile skin over serial: record frames, or classify touch live.

::

    sphri skin record port=/dev/ttyACM0 out=rec.npz grid=18x6 duration_s=60
    sphri skin live port=/dev/ttyACM0 model=outputs/models/rf.sphrimodel
    sphri skin live port=socket://127.0.0.1:7777 model=runs:/<run_id>/model/rf.sphrimodel allow_remote=true

:class:`SkinReader` turns a port into a stream of :class:`ReceivedFrame`
(decoded by :class:`~sphri.hardware.skin_protocol.SkinDecoder`: garbage,
truncated frames, bad checksums, wrong taxel counts and sequence gaps are
counted, logged and skipped; a reconnect resets the stream). ``record``
saves the frames with timestamps (:mod:`sphri.hardware.recording`);
``live`` runs a model file on them (:mod:`sphri.hardware.live`).
"""

from __future__ import annotations

import json
import logging
import os
import signal
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from sphri.args import settings_main
from sphri.hardware.recording import PartialWriter, RecordingError, SkinRecording, save_with_fallback
from sphri.hardware.settings import SkinLiveSettings, SkinRecordSettings, SkinStreamSettings, parse_grid
from sphri.hardware.skin_protocol import CMD_START, SkinDecoder, SkinFrame, encode_control
from sphri.hardware.transport import Link, PortLost

if TYPE_CHECKING:
    from types import FrameType
    from typing import TypeAlias

    from sphri.hardware.live import LiveClassifier

    #: What :func:`signal.signal` takes and returns: a handler, SIG_DFL/SIG_IGN, or None (not set from Python).
    SignalHandler: TypeAlias = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None

log = logging.getLogger(__name__)

#: Refuse a stream after this many frames of the wrong taxel count and no good one.
WRONG_COUNT_LIMIT = 20
#: With no taxel count given, the count carried by a majority of this many first frames is the skin's.
CONSENSUS_FRAMES = 9
#: after ``until()`` says the source finished, the port must stay empty this long before a reader stops (s)
FINISH_QUIET_S = 0.2


class StreamMismatch(RuntimeError):
    """The skin streams frames that can never be used (e.g. another taxel count)."""


@dataclass(frozen=True)
class ReceivedFrame:
    """A decoded frame and when the host got it."""

    frame: SkinFrame
    host_time_s: float
    """Unix time (s) when the bytes completing the frame were read."""
    received: float
    """``time.perf_counter()`` at the same moment (for latencies)."""
    segment: int
    """Connection number: 0, then +1 after each reconnect."""


class SkinReader:
    """Frames from a skin on ``port`` (context manager).

    ``taxels``: expected count; 0 = a consensus over the first frames: the
    checksum-valid frames are held until one count is carried by
    ``consensus_frames // 2 + 1`` of them (a majority of the first
    ``consensus_frames`` when there is one), then the held frames with that
    count are passed on (with their own arrival times) and the others counted
    as ``wrong_count``; one glitched first frame cannot decide. A stream that
    ends before the count is settled gives the held frames of its most
    common count (:meth:`release_held`). ``reconnect``: retry a vanished port
    (up to ``reconnect_timeout_s``, 0 = forever) instead of raising
    :class:`~sphri.hardware.transport.PortLost`. ``start_command``: send
    START on every (re)connection.
    """

    def __init__(
        self,
        port: str,
        baud: int = 1_000_000,
        taxels: int = 0,
        reconnect: bool = False,
        reconnect_timeout_s: float = 30.0,
        start_command: bool = True,
        consensus_frames: int = CONSENSUS_FRAMES,
    ) -> None:
        self.consensus_frames = max(1, int(consensus_frames))
        self.decoder = SkinDecoder(expected_taxels=taxels or None, lock_first=self.consensus_frames == 1)
        self._held: list[ReceivedFrame] = []
        self.start_command = start_command
        self.link = Link(
            port,
            baud,
            read_timeout_s=0.02,
            reconnect=reconnect,
            reconnect_interval_s=0.2,
            reconnect_timeout_s=reconnect_timeout_s,
            on_connect=self._on_connect,
        )
        self.segment = 0
        self.stop_reason = ""

    def _on_connect(self, link: Link) -> None:
        if self.start_command:
            link.write(encode_control(CMD_START))

    def __enter__(self) -> SkinReader:
        self.link.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.link.close()
        self.decoder.close()  # bytes left buffered at the stop are counted, not silently dropped

    @property
    def stats(self):
        return self.decoder.stats

    # -- taxel-count consensus (taxels=0) ----------------------------------------------
    def _admit(self, rf: ReceivedFrame) -> list[ReceivedFrame]:
        """The frames to pass on now that ``rf`` arrived (held ones included once the count is settled)."""
        if self.decoder.expected_taxels is not None:
            return [rf]
        self._held.append(rf)
        counts = Counter(h.frame.n_taxels for h in self._held)
        n, votes = counts.most_common(1)[0]
        if votes >= self.consensus_frames // 2 + 1:
            return self._settle(n)
        if len(self._held) >= 4 * self.consensus_frames:
            seen = ", ".join(f"{k} taxels x{v}" for k, v in counts.most_common())
            self._held.clear()
            raise StreamMismatch(
                f"{self.link.port}: no taxel count agreed over the first {4 * self.consensus_frames} "
                f"valid frames ({seen}); give taxels= or grid="
            )
        return []

    def _settle(self, n: int) -> list[ReceivedFrame]:
        held, self._held = self._held, []
        kept = {id(f) for f in self.decoder.settle_count(n, [h.frame for h in held])}
        keep = [h for h in held if id(h.frame) in kept]
        log.info("skin stream: %d taxels per frame (%d of the first %d frames agree)", n, len(keep), len(held))
        return keep

    def release_held(self) -> list[ReceivedFrame]:
        """The stream ended (or was stopped) before the first frames agreed on a taxel count: settle on
        the most common count among the held frames (ties: the one seen first) and return its frames."""
        if not self._held:
            return []
        counts = Counter(h.frame.n_taxels for h in self._held)
        top = max(counts.values())
        n = next(h.frame.n_taxels for h in self._held if counts[h.frame.n_taxels] == top)
        if top < self.consensus_frames // 2 + 1:
            log.warning(
                "skin stream: only %d frame(s) read before the stream stopped; taking %d taxels (%d of them agree)",
                len(self._held),
                n,
                top,
            )
        return self._settle(n)

    def frames(
        self,
        max_frames: int = 0,
        duration_s: float = 0.0,
        idle_s: float = 0.0,
        until: Callable[[], bool] | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> Iterator[ReceivedFrame]:
        """Yield good frames until ``max_frames``, ``duration_s`` or ``idle_s`` without a frame (0 = no limit),
        until ``until()`` is true once nothing more is waiting on the port (a source that can say it has
        finished, e.g. the simulator's ``finished`` event: the stop is then an event, not a timeout), or
        until ``stop()`` is true (checked after every read, e.g. a signal asked to stop).

        Frames held for the taxel-count consensus are yielded before a stop
        (not when an exception ends the stream: :meth:`release_held` has them).
        Sets :attr:`stop_reason`. Raises ``PortLost`` (no reconnect) and
        :class:`StreamMismatch` when only wrong-count frames arrive.
        """
        count = 0
        for rf in self._frames(max_frames, duration_s, idle_s, until, stop):
            count += 1
            yield rf
        for rf in self.release_held():
            if max_frames and count >= max_frames:
                break
            count += 1
            yield rf

    def _frames(
        self,
        max_frames: int,
        duration_s: float,
        idle_s: float,
        until: Callable[[], bool] | None,
        stop: Callable[[], bool] | None,
    ) -> Iterator[ReceivedFrame]:
        t_start = time.monotonic()
        last = t_start
        count = 0
        seen_reconnects = self.link.reconnects
        finishing: float | None = None  # when the port was first found empty after until() held
        while True:
            data = self.link.read()
            now = time.monotonic()
            if self.link.reconnects != seen_reconnects:
                seen_reconnects = self.link.reconnects
                self.decoder.reset_stream()
                self.segment += 1
                last = now
            frames: list = []
            ended = False
            if data:
                finishing = None
                frames = self.decoder.feed(data)
                st = self.decoder.stats
                if st.frames == 0 and st.wrong_count >= WRONG_COUNT_LIMIT:  # so no frame to hand on either
                    raise StreamMismatch(
                        f"{self.link.port}: {st.wrong_count} frames with the wrong taxel count and none with "
                        f"the expected {self.decoder.expected_taxels}; is this the skin the model/layout was made for?"
                    )
            elif until is not None and until():
                # the source said it finished: stop once the port stayed empty for FINISH_QUIET_S
                # (a pty's kernel buffer can hold written bytes back for a while on a loaded machine)
                if finishing is None:
                    finishing = now
                elif now - finishing >= FINISH_QUIET_S:
                    # the stream ended: a frame that was waiting behind a cut-short one is still decoded
                    frames, ended = self.decoder.finish(), True
            if frames:
                wall, perf = time.time(), time.perf_counter()
                for f in frames:
                    last = now
                    for rf in self._admit(ReceivedFrame(f, wall, perf, self.segment)):
                        count += 1
                        yield rf
                        if max_frames and count >= max_frames:
                            self.stop_reason = f"{count} frames"
                            return
            if ended:
                self.stop_reason = "the source finished"
                return
            if stop is not None and stop():
                self.stop_reason = "stopped"
                return
            if duration_s and now - t_start >= duration_s:
                self.stop_reason = f"{duration_s:g} s elapsed"
                return
            if idle_s and now - last >= idle_s:
                self.stop_reason = f"no frame for {idle_s:g} s"
                return


# --------------------------------------------------------------------------- record
class _StopSignals:
    """While active (main thread only): the first SIGTERM or SIGINT asks the recorder to stop (a flag it
    checks after every read), so the frames read so far are saved; a second one raises
    KeyboardInterrupt (a recorder stuck waiting for a port still ends, saving what it has)."""

    SIGNALS = (signal.SIGTERM, signal.SIGINT)

    def __init__(self) -> None:
        self.received: str | None = None
        self._old: dict[int, SignalHandler] = {}

    def _handle(self, signum, frame) -> None:
        if self.received is not None:
            raise KeyboardInterrupt
        self.received = signal.Signals(signum).name

    def __enter__(self) -> _StopSignals:
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)

    def __call__(self) -> bool:
        return self.received is not None


def _reader_for(settings: SkinStreamSettings, taxels: int, consensus_frames: int = CONSENSUS_FRAMES) -> SkinReader:
    """The reader of ``settings``' port (baud, reconnection, START) expecting ``taxels`` per frame
    (0 = a consensus over the first ``consensus_frames`` frames)."""
    return SkinReader(
        settings.port,
        settings.baud,
        taxels,
        settings.reconnect,
        settings.reconnect_timeout_s,
        start_command=settings.start_command,
        consensus_frames=consensus_frames,
    )


@dataclass
class _Recorder:
    """One recording under way: the reader, the partial file its frames go to, and what went wrong."""

    reader: SkinReader
    partial: PartialWriter
    signals: _StopSignals
    n_read: int = 0
    unwritten: list[ReceivedFrame] = field(default_factory=list)
    """Frames read but not in the partial file: after a failed write (a full disk) the frames already read
    (the rest of that read, the held ones) are kept here, a bounded few, and saved after the file's."""
    write_error: RecordingError | None = None
    error: BaseException | None = None

    def keep(self, rf: ReceivedFrame) -> None:
        """Write ``rf`` to the partial file, or keep it in memory once a write failed."""
        self.n_read += 1
        if self.write_error is not None:
            self.unwritten.append(rf)
            return
        before = self.partial.n_written
        try:
            self.partial.append(rf.frame.values, rf.host_time_s, rf.frame.device_time_us, rf.frame.seq, rf.segment)
        except RecordingError as exc:
            self.write_error = exc
            if self.partial.n_written == before:  # not in the file (a failed fsync comes after the frame's write)
                self.unwritten.append(rf)

    def stop(self) -> bool:
        """True once a signal asked to stop or a write failed (checked after each read: its frames are all kept first)."""
        return self.signals() or self.write_error is not None

    def read(self, settings: SkinRecordSettings, until: Callable[[], bool] | None, out: Callable[[str], None]) -> None:
        """Read and keep frames until a stop condition, then the held ones, and flush the partial file; a
        lost port, a stream mismatch or a failed write end the reading with :attr:`error` set."""
        reader = self.reader
        try:
            try:
                with reader:
                    for rf in reader.frames(settings.frames, settings.duration_s, settings.idle_s, until, self.stop):
                        self.keep(rf)
                        if self.n_read % 500 == 0:
                            out(f"  {self.n_read} frames; {reader.stats.errors} bad; {reader.stats.problems()}")
            except KeyboardInterrupt:
                reader.stop_reason = "interrupted"
            except (PortLost, StreamMismatch) as exc:
                self.error = exc
                reader.stop_reason = str(exc)
            if self.error is None or isinstance(self.error, PortLost):  # frames held for the count consensus
                for rf in reader.release_held():
                    self.keep(rf)
            if self.write_error is None:
                self.partial.flush()
        except RecordingError as exc:  # the last fsync failed (a full disk): the frames stay in the file
            self.write_error = exc
        except KeyboardInterrupt:  # a second signal while releasing the held frames
            reader.stop_reason = "interrupted"
        except BaseException:
            self.partial.close()
            raise
        if self.write_error is not None:  # writing the partial file failed: keep what was read
            self.error = self.write_error
            reader.stop_reason = str(self.write_error)
        if self.signals.received:
            reader.stop_reason = f"{self.signals.received} received"

    def tail(self, n: int) -> SkinRecording:
        """The frames kept in memory (:attr:`unwritten`, ``n`` taxels each) as a recording without a grid."""
        unwritten = self.unwritten
        return SkinRecording(
            np.asarray([rf.frame.values for rf in unwritten], dtype=np.float32).reshape(len(unwritten), n),
            np.asarray([rf.host_time_s for rf in unwritten]),
            np.asarray([rf.frame.device_time_us for rf in unwritten]),
            np.asarray([rf.frame.seq for rf in unwritten]),
            np.asarray([rf.segment for rf in unwritten]),
            None,
        )


@dataclass
class _Saved:
    """Where a recording went: ``path``, its frame count, rate (Hz), and the error of a first failed try
    (``lost``: it could not be saved anywhere, ``path`` is then the partial file)."""

    path: str | os.PathLike
    n_frames: int
    rate_hz: float = 0.0
    error: BaseException | None = None
    lost: bool = False


def _save(
    rec: _Recorder, out_path: str, tail: SkinRecording, grid: tuple[int, int] | None, meta: dict, say: Callable
) -> _Saved:
    """Save the frames of the partial file (memory-mapped) and then ``tail`` to ``out_path`` (or a fallback
    file) and remove the partial file; when no file can be written, say where the frames are."""
    partial = rec.partial
    n = tail.values.shape[1]
    n_frames = partial.n_written + tail.n_frames
    try:
        # the frames in the partial file, mapped from it: memory does not grow with the recording
        records = partial.records()
        recording = SkinRecording(
            records["values"] if len(records) else np.zeros((0, n), dtype=np.float32),
            records["host_time_s"],
            records["device_time_us"],
            records["seq"],
            records["segment"],
            grid,
            meta,
        )
        n_frames = recording.n_frames + tail.n_frames
        path, save_error = save_with_fallback(recording, out_path, say=say, tail=tail)
    except Exception as exc:  # the fallback failed too: the partial file holds what was written
        say(
            f"could not save the recording anywhere ({type(exc).__name__}: {exc}); {n_frames - tail.n_frames} "
            f'of {n_frames} frames are in {partial.path} (python -c "from sphri.hardware.recording import '
            f"load_recording; load_recording('{partial.path}')\" reads it)"
        )
        return _Saved(partial.path, n_frames, error=exc, lost=True)
    finally:
        partial.close()
    rate = recording.rate_hz
    del recording, records  # the memory map of the partial file, before it is removed
    partial.remove()
    return _Saved(path, n_frames, rate, save_error)


def record(
    settings: SkinRecordSettings, out: Callable[[str], None] = print, until: Callable[[], bool] | None = None
) -> dict:
    """``skin record``: read frames until a stop condition, save them; returns a summary.

    ``until``: an extra stop condition for a source that can say it has
    finished (see :meth:`SkinReader.frames`).

    The taxel count is ``taxels``, else ``grid``'s H*W, else a consensus over
    the first frames (:class:`SkinReader`), never one frame's. The output
    path is checked (an existing file is refused: a recording is never
    replaced), and ``<out>.partial`` created, before the port is opened;
    every frame is written to it as it is read and fsynced every
    ``chunk_frames`` frames or ``sync_interval_s`` seconds
    (:class:`~sphri.hardware.recording.PartialWriter`). SIGTERM and SIGINT
    stop the recording and save it like any other stop. No frame is kept in
    memory: at the end the recording is built from the partial file (a
    memory map, :meth:`~sphri.hardware.recording.PartialWriter.records`) and
    goes to ``out`` (or a fallback file in the working directory), and the
    partial file is removed. When a write fails (a full disk) the recorder
    stops after the frames already read (the rest of that read, the held
    ones), keeps those in memory and saves them after the file's; the
    summary's ``not_written`` counts them.
    """
    grid = parse_grid(settings.grid)
    taxels = settings.taxels or (grid[0] * grid[1] if grid else 0)
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(time.time()))
    partial = PartialWriter(
        settings.out,
        settings.chunk_frames,
        {"port": settings.port, "grid_shape": list(grid) if grid else None, "started": started},
        sync_interval_s=settings.sync_interval_s,
    )
    reader = _reader_for(settings, taxels, settings.consensus_frames)
    out(
        f"recording {settings.port} -> {settings.out} (Ctrl+C to stop; frames written to {partial.path} as they arrive)"
    )
    rec = _Recorder(reader, partial, _StopSignals())
    with rec.signals:
        rec.read(settings, until, out)
        n = partial.n_taxels or (
            int(rec.unwritten[0].frame.values.shape[0]) if rec.unwritten else reader.decoder.expected_taxels or taxels
        )
        if grid is not None and n != grid[0] * grid[1]:  # only with no frame read
            grid = None
        stats = reader.stats.as_dict()
        meta = {
            "port": settings.port,
            "started": started,
            "stop_reason": reader.stop_reason,
            "reconnects": reader.link.reconnects,
            "decoder": stats,
            "protocol": "sphri-skin/1",
        }
        tail = rec.tail(n)
        saved = _save(rec, settings.out, tail, grid, meta, out)
        if saved.lost:
            return _record_summary(saved, tail.n_frames, stats, reader, saved.error)
    out(
        f"saved {saved.n_frames} frames x {n} taxels to {saved.path} ({reader.stop_reason}); "
        f"rate {saved.rate_hz:.1f} Hz; reconnects {reader.link.reconnects}"
    )
    out(f"skipped: {reader.stats.errors} bad frame(s): {reader.stats.problems()}")
    if tail.n_frames:
        out(
            f"{tail.n_frames} frame(s) read but not written to {partial.path} (the write failed); "
            f"saved from memory with the other {saved.n_frames - tail.n_frames}"
        )
    if rec.error is not None:
        out(f"stopped early: {rec.error}")
    return _record_summary(saved, tail.n_frames, stats, reader, rec.error or saved.error)


def _record_summary(
    saved: _Saved, not_written: int, stats: dict, reader: SkinReader, error: BaseException | None
) -> dict:
    """``record``'s summary: frames saved, those saved from memory, where, the decoder's counts, the error."""
    return {
        "frames": saved.n_frames,
        "not_written": not_written,
        "path": str(saved.path),
        "decoder": stats,
        "error": str(error) if error else None,
        "reconnects": reader.link.reconnects,
    }


# --------------------------------------------------------------------------- live
def default_tracking_uri() -> str | None:
    try:
        from sphri.tracking.mlflow_tracker import default_uri

        return default_uri("outputs")
    except Exception:  # tracking not importable: plain MLflow defaults
        return None


@dataclass
class _LiveRun:
    """The state of ``skin live`` over a stream: the classifier, its predictions, and what was seen."""

    clf: LiveClassifier
    settings: SkinLiveSettings
    out: Callable[[str], None]
    sink: IO[str] | None = None
    """Where each prediction goes as a JSON line (``settings.out``), or None."""
    preds: list = field(default_factory=list)
    n_frames: int = 0
    first_t: float | None = None
    """Unix time (s) of the first frame; :attr:`last_t` of the last one."""
    last_t: float | None = None
    segment: int = 0
    announced: bool = False
    last_seq: int | None = None
    last_values: np.ndarray | None = None
    filled: int = 0
    """Lost frames filled by holding the previous one."""

    def push(self, rf: ReceivedFrame) -> None:
        """Feed one received frame (and, before it, copies of the last one for the frames lost between
        them) to the classifier; say and write the predictions it gives."""
        s, clf = self.settings, self.clf
        if rf.segment != self.segment:
            self.segment = rf.segment
            clf.reset()
            self.last_seq = self.last_values = None
            self.out("(reconnected: window restarted)")
        self.n_frames += 1
        self.first_t = rf.host_time_s if self.first_t is None else self.first_t
        self.last_t = rf.host_time_s
        got = []
        if self.last_seq is not None and self.last_values is not None and s.fill_gaps:  # set together
            # frames lost on the way: hold the last one so windows keep the stream's timing
            lost = ((rf.frame.seq - self.last_seq) & 0xFFFF) - 1
            if 0 < lost <= s.fill_gaps:
                for _ in range(lost):
                    got += clf.push(self.last_values, rf.received)
                self.filled += lost
        self.last_seq, self.last_values = rf.frame.seq, rf.frame.values
        got += clf.push(rf.frame.values, rf.received)
        if not self.announced and clf.threshold is not None:
            self.announced = True
            how = "calibrated from the first frames" if s.onset_taxels == 0 else "set"
            self.out(f"touch onset at activity >= {clf.threshold:.2f} ({how})")
        for p in got:
            self.preds.append(p)
            if s.show == "all" or (s.show == "touches" and p.kind == "touch"):
                self.out(p.line())
            if self.sink is not None:
                self.sink.write(json.dumps({**p.as_dict(), "seq": rf.frame.seq, "host_time_s": rf.host_time_s}) + "\n")

    def summary(self, wall_s: float, reader: SkinReader, error: BaseException | None) -> dict:
        """``skin live``'s summary after ``wall_s`` seconds: counts, rates (Hz, per s), latencies (ms)."""
        preds, n_frames, first_t, last_t = self.preds, self.n_frames, self.first_t, self.last_t
        lat = np.asarray([p.latency_ms for p in preds])
        comp = np.asarray(self.clf.compute_ms)
        stream_rate = (
            (n_frames - 1) / (last_t - first_t)
            if n_frames > 1 and last_t is not None and first_t is not None and last_t > first_t
            else 0.0
        )
        return {
            "frames": n_frames,
            "predictions": len(preds),
            "touches": sum(p.kind == "touch" for p in preds),
            "filled_frames": self.filled,
            "stream_rate_hz": stream_rate,
            "predictions_per_s": len(preds) / wall_s if wall_s > 0 else 0.0,
            "latency_ms_median": float(np.median(lat)) if lat.size else float("nan"),
            "latency_ms_p95": float(np.percentile(lat, 95)) if lat.size else float("nan"),
            "model_ms_mean": float(comp.mean()) if comp.size else float("nan"),
            "capacity_predictions_per_s": float(1000.0 / comp.mean())
            if comp.size and comp.mean() > 0
            else float("nan"),
            "decoder": reader.stats.as_dict(),
            "error": str(error) if error else None,
        }


def live(
    settings: SkinLiveSettings, out: Callable[[str], None] = print, until: Callable[[], bool] | None = None
) -> dict:
    """``skin live``: classify the streamed frames; returns a summary with latencies.

    ``until``: an extra stop condition, as in :func:`record`."""
    from sphri.export.model_file import load_model, resolve_model_path
    from sphri.hardware.live import LiveClassifier, auto_stride

    bundle = load_model(
        resolve_model_path(
            settings.model, settings.tracking_uri or default_tracking_uri(), allow_remote=settings.allow_remote
        ),
        plugins=settings.plugins,
        allow_unverified=settings.allow_unverified,
    )
    stride = settings.stride or auto_stride(bundle.frame_rate_hz)
    clf = LiveClassifier(
        bundle,
        stride,
        settings.onset_taxels,
        settings.calibrate_frames,
        settings.release_frames,
        min(settings.persist, bundle.window_length),
        cluster_taxels=settings.cluster_taxels,
    )
    out(
        f"model {bundle.meta.get('model', type(bundle.estimator).__name__)}: {bundle.n_taxels} taxels, "
        f"window {bundle.window_length} frames at {bundle.frame_rate_hz:g} Hz; a prediction every {stride} frames"
    )
    reader = _reader_for(settings, bundle.n_taxels)
    run = _LiveRun(clf, settings, out, open(settings.out, "w") if settings.out else None)
    error: BaseException | None = None
    t0 = time.perf_counter()
    try:
        with reader:
            for rf in reader.frames(settings.frames, settings.duration_s, settings.idle_s, until):
                run.push(rf)
    except KeyboardInterrupt:
        reader.stop_reason = "interrupted"
    except (PortLost, StreamMismatch) as exc:
        error = exc
    finally:
        if run.sink is not None:
            run.sink.close()
    wall = time.perf_counter() - t0
    summary = run.summary(wall, reader, error)
    stream_rate = summary["stream_rate_hz"]
    if bundle.frame_rate_hz and stream_rate and abs(stream_rate / bundle.frame_rate_hz - 1) > 0.2:
        out(
            f"warning: the skin streams at {stream_rate:.1f} Hz but the model was trained at {bundle.frame_rate_hz:g} Hz"
        )
    out(
        f"{run.n_frames} frames, {len(run.preds)} predictions ({summary['touches']} touches) in {wall:.1f} s: "
        f"{summary['predictions_per_s']:.1f} predictions/s; latency median {summary['latency_ms_median']:.1f} ms, "
        f"p95 {summary['latency_ms_p95']:.1f} ms; model {summary['model_ms_mean']:.1f} ms per window "
        f"(up to {summary['capacity_predictions_per_s']:.0f} predictions/s)"
    )
    out(
        f"skipped: {reader.stats.errors} bad frame(s): {reader.stats.problems()}; "
        f"{run.filled} lost frame(s) filled by holding the previous one"
    )
    if error is not None:
        out(f"stopped early: {error}")
    return summary


#: The commands and their settings (``sphri skin --help`` lists each setting with its meaning).
COMMANDS = {"record": (SkinRecordSettings, False), "live": (SkinLiveSettings, False)}


@settings_main("sphri skin", COMMANDS)
def main(cmd: str, settings: SkinRecordSettings | SkinLiveSettings, _overrides: list[str]) -> int:
    """``sphri skin record|live key=value ...``."""
    # read_settings builds COMMANDS[cmd]'s class: SkinRecordSettings for record only
    summary = record(settings) if isinstance(settings, SkinRecordSettings) else live(settings)
    # port, model-file and recording errors: one line from @clean_errors
    return 1 if summary.get("error") else 0
