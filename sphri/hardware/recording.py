"""Skin recordings on disk: what ``skin record`` writes and other stages load.

A recording is one ``.npz`` file (numpy, no pickles) holding:

- ``values``: (F, N) float32 in [0, 1], frame f = one skin scan in the
  encoder's output format (row-major (u, v) taxel order for a grid);
- ``host_time_s``: (F,) float64 Unix time (seconds) when the host received
  each frame;
- ``device_time_us``: (F,) int64 the skin's own clock (microseconds, as sent;
  wraps at 2^32);
- ``seq``: (F,) int64 the frames' sequence numbers (wrap at 65536);
- ``segment``: (F,) int64 connection number (increments after a reconnect);
- ``grid_shape``: (2,) int64 (H, W), or (0,) when the layout is not a grid;
- ``meta``: a JSON string (format version, port, decoder counters, ...).

:func:`load_recording` validates every field and names the file and field
on any problem; :meth:`SkinRecording.frames` gives :class:`~sphri.types.Frames`
and :meth:`SkinRecording.windows` model-ready (n, L, N) windows.

While ``skin record`` runs, frames go to a *partial* file next to the output
(``rec.npz.partial``, :class:`PartialWriter`): each frame is written to the
file as it is read (a killed process loses none) and the file is fsynced every
``chunk_frames`` frames or ``sync_interval_s`` seconds (what a power cut can
cost), so a crash, a kill or a full disk keeps what was read
(:func:`load_recording` reads a partial file too). The output path is checked
before a byte is read (:func:`check_output_path`: an existing file is never
replaced); at the end the frames are saved to ``out`` and the partial file
removed, or, when that fails, to a fallback file in the working directory
(:func:`save_with_fallback`). The saved recording is built from the partial
file's records (:meth:`PartialWriter.records`, a read-only memory map) and
written field by field in chunks of ``SAVE_CHUNK_BYTES``, so the recorder's
memory does not grow with the recording's length. Files are created with the mode the umask
gives (:func:`sphri.fsutil.umask_mode`), not 0600.
"""

from __future__ import annotations

import json
import os
import struct
import tempfile
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sphri.fsutil import umask_mode
from sphri.types import Frames

#: Format version written in ``meta["format"]``.
FORMAT = "sphri-skin-recording/1"
#: The per-frame timing arrays beside ``values`` (module docstring) and their dtypes: the recording's
#: attributes, its .npz fields and the partial file's record fields.
_TIMING: dict[str, type[np.generic]] = {
    "host_time_s": np.float64,
    "device_time_us": np.int64,
    "seq": np.int64,
    "segment": np.int64,
}
_FIELDS = ("values", *_TIMING, "grid_shape", "meta")
#: First bytes of a partial recording (then uint32 LE header length, JSON header, fixed-size frame records).
PARTIAL_MAGIC = b"SPHRISKINPART1\n"
#: Bytes of a field copied at a time when a recording is saved (the saver's buffer).
SAVE_CHUNK_BYTES = 1 << 20


class RecordingError(ValueError):
    """A recording file is missing, unreadable or malformed (the message names it)."""


@dataclass
class SkinRecording:
    """Frames read from a skin, with their timing (see the module docstring)."""

    values: np.ndarray
    host_time_s: np.ndarray
    device_time_us: np.ndarray
    seq: np.ndarray
    segment: np.ndarray
    grid_shape: tuple[int, int] | None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.values = np.asarray(self.values, dtype=np.float32)
        if self.values.ndim != 2:
            raise RecordingError(f"values must be (F, N), got shape {self.values.shape}")
        f, n = self.values.shape
        for name, dtype in _TIMING.items():
            arr = np.asarray(getattr(self, name), dtype=dtype)
            if arr.shape != (f,):
                raise RecordingError(f"{name} must be ({f},) like values' frames, got shape {arr.shape}")
            setattr(self, name, arr)
        if self.grid_shape is not None:
            h, w = (int(v) for v in self.grid_shape)
            if h * w != n:
                raise RecordingError(f"grid_shape {h}x{w} does not hold the {n} taxels of values")
            self.grid_shape = (h, w)

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def n_taxels(self) -> int:
        return int(self.values.shape[1])

    @property
    def rate_hz(self) -> float:
        """Mean frame rate from the host timestamps (0 with fewer than 2 frames)."""
        if self.n_frames < 2:
            return 0.0
        span = float(self.host_time_s[-1] - self.host_time_s[0])
        return (self.n_frames - 1) / span if span > 0 else 0.0

    def frames(self) -> Frames:
        """The readings as :class:`~sphri.types.Frames` (F, N) float32."""
        return Frames(values=self.values, grid_shape=self.grid_shape)

    def windows(self, length: int, stride: int = 1) -> np.ndarray:
        """(n, length, N) float32 sliding windows (start every ``stride`` frames), the models' input."""
        if length < 1 or stride < 1:
            raise ValueError(f"length={length} and stride={stride} must be >= 1")
        if self.n_frames < length:
            return np.zeros((0, length, self.n_taxels), dtype=np.float32)
        w = np.lib.stride_tricks.sliding_window_view(self.values, length, axis=0)[::stride]
        return np.ascontiguousarray(np.moveaxis(w, -1, 1))


def _write_npy(fh, parts: list[np.ndarray]) -> None:
    """One .npy array made of ``parts`` joined along their first axis, written ``SAVE_CHUNK_BYTES`` at a time
    (a part may be a memory map: it is never copied whole)."""
    first = parts[0]
    shape = (sum(len(p) for p in parts), *first.shape[1:]) if first.ndim else first.shape
    np.lib.format.write_array_header_1_0(
        fh, {"descr": np.lib.format.dtype_to_descr(first.dtype), "fortran_order": False, "shape": shape}
    )
    for part in parts:
        part = np.asarray(part, dtype=first.dtype)
        if part.ndim == 0:
            fh.write(part.tobytes())
            continue
        row = part.itemsize * int(np.prod(part.shape[1:]))
        step = max(1, SAVE_CHUNK_BYTES // max(1, row))
        for i in range(0, len(part), step):
            fh.write(np.ascontiguousarray(part[i : i + step]).tobytes())


def save_recording(
    rec: SkinRecording, path: str | os.PathLike, replace: bool = True, tail: SkinRecording | None = None
) -> Path:
    """Write ``rec`` to ``path`` (.npz) atomically (temp file + rename).

    ``replace=False`` (what ``skin record`` uses) never replaces an existing
    file: the name is reserved with an exclusive create first, and a file
    already there raises :class:`RecordingError`. ``tail``: frames saved
    after ``rec``'s in the same recording (same taxel count; ``rec``'s grid
    and meta), e.g. frames that never reached the partial file. Each field
    is written in chunks (:func:`_write_npy`), so ``rec`` may be a memory map
    of any length.
    """
    path = Path(path)
    if tail is not None and tail.n_frames and tail.n_taxels != rec.n_taxels:
        raise RecordingError(f"{path}: tail has {tail.n_taxels} taxels, the recording {rec.n_taxels}")
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"format": FORMAT, **rec.meta}
    grid = np.asarray(rec.grid_shape if rec.grid_shape is not None else (), dtype=np.int64)
    parts = [rec] if tail is None or tail.n_frames == 0 else [rec, tail]
    fields = {name: [getattr(p, name) for p in parts] for name in ("values", *_TIMING)}
    fields["grid_shape"] = [grid]
    fields["meta"] = [np.asarray(json.dumps(meta, default=str))]
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    reserved = False
    try:
        os.fchmod(fd, umask_mode())
        with os.fdopen(fd, "wb") as fh:
            with zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_DEFLATED, allowZip64=True) as zf:
                for name, arrays in fields.items():
                    with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                        _write_npy(member, arrays)
        if not replace:
            try:
                os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
            except FileExistsError:
                raise RecordingError(f"{path} exists; a recording is never replaced") from None
            reserved = True
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if reserved:
            try:
                os.unlink(path)
            except OSError:
                pass
        raise
    return path


def free_name(path: Path) -> Path:
    """``path`` itself when nothing is there, else the first free ``<stem>-2<suffix>``, ``-3``, ..."""
    cand, i = path, 1
    while cand.exists() or cand.is_symlink():
        i += 1
        cand = path.with_name(f"{path.stem}-{i}{path.suffix}")
    return cand


def check_output_path(path: str | os.PathLike) -> Path:
    """Refuse an output path that cannot be written (before any frame is read), naming it.

    Catches an existing directory, an existing file (a recording is never
    replaced: the error names a free name), a path under a file and a folder
    that cannot be created; whether the folder takes new files is shown by
    :class:`PartialWriter` creating its file there.
    """
    path = Path(path)
    if path.is_dir():
        raise RecordingError(f"out={path} is an existing directory; give a file name, e.g. out={path / 'rec.npz'}")
    if path.exists() or path.is_symlink():
        raise RecordingError(
            f"out={path} exists and is never replaced; remove it first or give another name, e.g. out={free_name(path)}"
        )
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise RecordingError(f"out={path} is invalid: {parent} is a file, not a directory")
            break
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordingError(f"out={path}: cannot create its folder {path.parent} ({exc.strerror or exc})") from None
    return path


def _record_dtype(n_taxels: int) -> np.dtype:
    timing = [(name, np.dtype(dtype).newbyteorder("<")) for name, dtype in _TIMING.items()]
    return np.dtype([("values", "<f4", (n_taxels,)), *timing])


class PartialWriter:
    """Write frames to ``<out>.partial`` as they arrive; fsync every ``chunk_frames`` frames or
    ``sync_interval_s`` seconds.

    Opening it creates the file, so an output folder that takes no new file
    fails here, before the port is opened. The header (taxel count, grid
    shape, meta) is written with the first frame; each frame is a
    fixed-size record written to the file (one unbuffered ``write``) when it
    is appended, so a killed process leaves every frame it appended, and a
    file cut anywhere loads up to its last whole frame. ``n_written``: frames
    in the file; ``n_synced``: frames fsynced (safe from a power cut too).
    :meth:`records` maps the frames in the file back (through the open file,
    so a partial file whose folder was removed still gives them).
    """

    def __init__(
        self,
        out: str | os.PathLike,
        chunk_frames: int = 50,
        meta: dict[str, Any] | None = None,
        sync_interval_s: float = 1.0,
    ) -> None:
        self.out = check_output_path(out)
        self.chunk_frames = max(1, int(chunk_frames))
        self.sync_interval_s = float(sync_interval_s)
        self.meta = dict(meta or {})
        self.path = self._free_name()
        try:
            fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_RDWR, 0o666)  # less the umask
            self._fh = os.fdopen(fd, "r+b", buffering=0)
        except OSError as exc:
            raise RecordingError(f"out={self.out}: cannot write in {self.out.parent} ({exc.strerror or exc})") from None
        self._dtype: np.dtype | None = None
        self._row: np.ndarray | None = None
        self._data_start: int | None = None  # offset of the first frame record, once the header is written
        self.n_written = 0
        self.n_synced = 0
        self._last_sync = time.monotonic()

    def _free_name(self) -> Path:
        base = self.out.with_name(self.out.name + ".partial")
        cand, i = base, 1
        while cand.exists():  # an earlier recording's leftover: keep it
            i += 1
            cand = base.with_name(f"{base.name}-{i}")
        return cand

    def append(self, values: np.ndarray, host_time_s: float, device_time_us: int, seq: int, segment: int) -> None:
        """Write one frame to the file; a failed write or fsync raises :class:`RecordingError`."""
        if self._fh.closed:
            return
        try:
            if self._dtype is None:
                n = int(np.asarray(values).shape[0])
                self._dtype = _record_dtype(n)
                self._row = np.zeros(1, dtype=self._dtype)
                head = json.dumps({"format": FORMAT, "n_taxels": n, **self.meta}, default=str).encode()
                self._write_all(PARTIAL_MAGIC + struct.pack("<I", len(head)) + head)
                self._data_start = len(PARTIAL_MAGIC) + 4 + len(head)
            row = self._row
            if row is None:  # set together with self._dtype above
                raise RecordingError(f"{self.path}: frame buffer missing after the header was written")
            row["values"][0] = values
            row["host_time_s"][0] = host_time_s
            row["device_time_us"][0] = device_time_us
            row["seq"][0] = seq
            row["segment"][0] = segment
            self._write_all(row.tobytes())
            self.n_written += 1
            if (
                self.n_written - self.n_synced >= self.chunk_frames
                or time.monotonic() - self._last_sync >= self.sync_interval_s
            ):
                self._sync()
        except OSError as exc:
            raise self._failed(exc) from None

    def _failed(self, exc: OSError) -> RecordingError:
        return RecordingError(f"writing {self.path} failed after {self.n_synced} frames ({exc.strerror or exc})")

    def _write_all(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = self._fh.write(view)
            view = view[n:]

    def _sync(self) -> None:
        os.fsync(self._fh.fileno())
        self.n_synced = self.n_written
        self._last_sync = time.monotonic()

    def flush(self) -> None:
        """fsync the frames written so far; a failure (e.g. a full disk) raises :class:`RecordingError`.

        The frames written before stay in the file.
        """
        if self._fh.closed or self.n_synced == self.n_written:
            return
        try:
            self._sync()
        except OSError as exc:
            raise self._failed(exc) from None

    @property
    def n_taxels(self) -> int:
        """Taxels per frame record (0 before the first frame)."""
        return 0 if self._dtype is None else int(self._dtype["values"].shape[0])

    def records(self) -> np.ndarray:
        """The whole frame records in the file (structured: ``values`` and the timing fields), a read-only
        memory map through the open file (a torn last record is left out); empty before the header is
        written. Call before :meth:`close`; a failure to map raises :class:`RecordingError`."""
        if self._dtype is None or self._data_start is None:
            return np.zeros(0, dtype=self._dtype or _record_dtype(0))
        try:
            size = os.fstat(self._fh.fileno()).st_size
            k = max(0, size - self._data_start) // self._dtype.itemsize
            if k == 0:
                return np.zeros(0, dtype=self._dtype)
            return np.memmap(self._fh, dtype=self._dtype, mode="r", offset=self._data_start, shape=(k,))
        except (OSError, ValueError) as exc:
            raise RecordingError(f"reading back {self.path} failed ({exc})") from None

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()

    def remove(self) -> None:
        """Delete the partial file once its frames are saved elsewhere (a vanished folder is fine)."""
        self.close()
        try:
            self.path.unlink(missing_ok=True)
        except OSError:
            pass


def _load_partial(path: Path, blob: bytes) -> SkinRecording:
    h0 = len(PARTIAL_MAGIC) + 4
    if len(blob) < h0:
        raise RecordingError(f"{path}: partial recording cut inside its header")
    (n,) = struct.unpack_from("<I", blob, len(PARTIAL_MAGIC))
    try:
        head = json.loads(blob[h0 : h0 + n])
        dtype = _record_dtype(int(head["n_taxels"]))
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError, RecursionError) as exc:
        raise RecordingError(f"{path}: partial recording header unreadable ({type(exc).__name__}: {exc})") from None
    body = blob[h0 + n :]
    k = len(body) // dtype.itemsize  # a torn last record is dropped
    rec = np.frombuffer(body[: k * dtype.itemsize], dtype=dtype)
    grid = head.get("grid_shape")
    n_tax = int(head["n_taxels"])
    grid_shape = (int(grid[0]), int(grid[1])) if grid and int(grid[0]) * int(grid[1]) == n_tax else None
    return SkinRecording(
        values=rec["values"],
        **{name: rec[name] for name in _TIMING},
        grid_shape=grid_shape,
        meta={**head, "partial": True, "torn_bytes": len(body) - k * dtype.itemsize},
    )


def save_with_fallback(
    rec: SkinRecording, path: str | os.PathLike, say=print, tail: SkinRecording | None = None
) -> tuple[Path, BaseException | None]:
    """Save to ``path`` (``tail`` as in :func:`save_recording`); on any failure save to a fallback file
    in the working directory.

    Returns (where it was saved, the error that made the first try fail or
    None). Raises only if the fallback fails too (then the partial file is
    all there is).
    """
    try:
        return save_recording(rec, path, replace=False, tail=tail), None
    except Exception as exc:  # any failure at the end must not lose the frames
        stamp = time.strftime("%Y%m%d-%H%M%S")
        fallback = free_name(Path.cwd() / f"{Path(path).stem or 'recording'}-recovered-{stamp}-{os.getpid()}.npz")
        saved = save_recording(rec, fallback, replace=False, tail=tail)
        n = rec.n_frames + (tail.n_frames if tail is not None else 0)
        say(f"could not write {path} ({type(exc).__name__}: {exc}); saved the {n} frames to {saved} instead")
        return saved, exc


def load_recording(path: str | os.PathLike) -> SkinRecording:
    """Read a recording written by :func:`save_recording` (``skin record``), or a partial one."""
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"skin recording not found: {path}")
    with open(path, "rb") as fh:
        start = fh.read(len(PARTIAL_MAGIC))
    if start == PARTIAL_MAGIC:
        try:
            return _load_partial(path, path.read_bytes())
        except RecordingError as exc:
            raise RecordingError(str(exc) if str(path) in str(exc) else f"{path}: {exc}") from None
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in _FIELDS if k not in z.files]
            if missing:
                raise RecordingError(f"{path}: not a sphri skin recording (missing {', '.join(missing)})")
            data = {k: z[k] for k in _FIELDS}
    except RecordingError:
        raise
    except (OSError, ValueError, EOFError) as exc:
        raise RecordingError(f"{path}: unreadable ({exc})") from None
    try:
        meta = json.loads(str(data["meta"]))
    except (json.JSONDecodeError, RecursionError) as exc:
        raise RecordingError(f"{path}: field meta is not JSON ({type(exc).__name__}: {exc})") from None
    if meta.get("format") != FORMAT:
        raise RecordingError(f"{path}: format {meta.get('format')!r}, this sphri reads {FORMAT!r}")
    values = data["values"]
    if values.dtype != np.float32 or values.ndim != 2:
        raise RecordingError(f"{path}: field values must be (F, N) float32, got {values.dtype} {values.shape}")
    if values.size and (not np.isfinite(values).all() or values.min() < 0 or values.max() > 1):
        raise RecordingError(f"{path}: field values must be finite and in [0, 1]")
    grid = data["grid_shape"]
    grid_shape = None if grid.size == 0 else (int(grid[0]), int(grid[1]))
    try:
        return SkinRecording(
            values=values,
            **{name: data[name] for name in _TIMING},
            grid_shape=grid_shape,
            meta=meta,
        )
    except RecordingError as exc:
        raise RecordingError(f"{path}: {exc}") from None
