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
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sphri.types import Frames

#: Format version written in ``meta["format"]``.
FORMAT = "sphri-skin-recording/1"
_FIELDS = ("values", "host_time_s", "device_time_us", "seq", "segment", "grid_shape", "meta")


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
        for name in ("host_time_s", "device_time_us", "seq", "segment"):
            arr = np.asarray(getattr(self, name), dtype=np.float64 if name == "host_time_s" else np.int64)
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


def save_recording(rec: SkinRecording, path: str | os.PathLike) -> Path:
    """Write ``rec`` to ``path`` (.npz) atomically (temp file + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"format": FORMAT, **rec.meta}
    grid = np.asarray(rec.grid_shape if rec.grid_shape is not None else (), dtype=np.int64)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez_compressed(
                fh,
                values=rec.values,
                host_time_s=rec.host_time_s,
                device_time_us=rec.device_time_us,
                seq=rec.seq,
                segment=rec.segment,
                grid_shape=grid,
                meta=np.asarray(json.dumps(meta, default=str)),
            )
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def load_recording(path: str | os.PathLike) -> SkinRecording:
    """Read a recording written by :func:`save_recording` (``skin record``)."""
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"skin recording not found: {path}")
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
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: field meta is not JSON ({exc})") from None
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
            host_time_s=data["host_time_s"],
            device_time_us=data["device_time_us"],
            seq=data["seq"],
            segment=data["segment"],
            grid_shape=grid_shape,
            meta=meta,
        )
    except RecordingError as exc:
        raise RecordingError(f"{path}: {exc}") from None
