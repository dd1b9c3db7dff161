"""Trained-model files for live classification (``.sphrimodel``).

A file holds a fitted sklearn-like estimator (``predict_proba(x)`` with x
(n, L, N) float32), the :class:`~sphri.types.TaxelGeometry` it was trained
on, the window length L and frame rate, and the gesture labels. Layout::

    b"SPHRIMODEL1\\n"
    uint32 LE  length of the JSON header
    JSON       header: format, labels, window_length, frame_rate_hz,
               n_taxels, grid_shape, model, created, meta (readable
               without unpickling, e.g. by ``inspect_model``)
    32 bytes   BLAKE2b digest of the payload
    payload    pickle of {"estimator": ..., "geometry": ...}

The payload is a pickle: only load model files you trust. Files can also
live in MLflow: :func:`resolve_model_path` accepts ``runs:/<run_id>/<path>``
(or any MLflow artifact URI) and downloads it first.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import pickle
import struct
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sphri.types import GESTURES, TaxelGeometry

MAGIC = b"SPHRIMODEL1\n"
FORMAT = "sphri-model/1"
_DIGEST = 32


class ModelFileError(ValueError):
    """A model file is missing, corrupt or inconsistent (the message names it)."""


@dataclass
class ModelBundle:
    """A trained classifier ready for live use."""

    estimator: Any
    geometry: TaxelGeometry
    window_length: int
    """L: frames per window (from contact onset), as in training."""
    frame_rate_hz: float
    """Frame rate of the training data (Hz); live data should match it."""
    labels: tuple[str, ...] = GESTURES
    """Gesture of each class index the estimator predicts."""
    meta: dict[str, Any] = field(default_factory=dict)
    """Provenance: model name, pipeline overrides, training counts and accuracy."""

    @property
    def n_taxels(self) -> int:
        return self.geometry.n_taxels

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """(n, L, N) windows -> (n, n_labels) class probabilities (columns follow ``labels``)."""
        p = np.asarray(self.estimator.predict_proba(np.asarray(x, dtype=np.float32)))
        classes = getattr(self.estimator, "classes_", None)
        if classes is not None and p.shape[1] != len(self.labels):
            full = np.zeros((p.shape[0], len(self.labels)), dtype=np.float64)
            full[:, np.asarray(classes, dtype=np.int64)] = p
            return full
        return p

    def header(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "labels": list(self.labels),
            "window_length": int(self.window_length),
            "frame_rate_hz": float(self.frame_rate_hz),
            "n_taxels": int(self.n_taxels),
            "grid_shape": list(self.geometry.grid_shape) if self.geometry.grid_shape else None,
            "model": type(self.estimator).__name__,
            "created": self.meta.get("created") or _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "meta": self.meta,
        }


def save_model(bundle: ModelBundle, path: str | os.PathLike) -> Path:
    """Write ``bundle`` to ``path`` atomically."""
    if not hasattr(bundle.estimator, "predict_proba"):
        raise ModelFileError(f"{type(bundle.estimator).__name__} has no predict_proba; live classification needs it")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = json.dumps(bundle.header(), default=str).encode()
    payload = pickle.dumps({"estimator": bundle.estimator, "geometry": bundle.geometry}, protocol=5)
    blob = MAGIC + struct.pack("<I", len(header)) + header + hashlib.blake2b(payload, digest_size=_DIGEST).digest() + payload
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(blob)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def _split(path: Path) -> tuple[dict[str, Any], bytes, bytes]:
    if not path.is_file():
        raise ModelFileError(f"model file not found: {path}")
    blob = path.read_bytes()
    if not blob.startswith(MAGIC) or len(blob) < len(MAGIC) + 4:
        raise ModelFileError(f"{path}: not a sphri model file (make one with python -m sphri.hardware.train_export)")
    (n,) = struct.unpack_from("<I", blob, len(MAGIC))
    h0 = len(MAGIC) + 4
    if len(blob) < h0 + n + _DIGEST:
        raise ModelFileError(f"{path}: truncated")
    try:
        header = json.loads(blob[h0 : h0 + n])
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"{path}: header is not JSON ({exc})") from None
    if header.get("format") != FORMAT:
        raise ModelFileError(f"{path}: format {header.get('format')!r}, this sphri reads {FORMAT!r}")
    digest = blob[h0 + n : h0 + n + _DIGEST]
    return header, digest, blob[h0 + n + _DIGEST :]


def inspect_model(path: str | os.PathLike) -> dict[str, Any]:
    """The JSON header of a model file (no unpickling)."""
    return _split(Path(path))[0]


def load_model(path: str | os.PathLike) -> ModelBundle:
    """Read a model file written by :func:`save_model` (checks its digest and shapes)."""
    path = Path(path)
    header, digest, payload = _split(path)
    if hashlib.blake2b(payload, digest_size=_DIGEST).digest() != digest:
        raise ModelFileError(f"{path}: checksum mismatch (truncated or corrupted)")
    try:
        obj = pickle.loads(payload)
    except Exception as exc:  # unpickling can raise nearly anything
        raise ModelFileError(f"{path}: cannot unpickle the model ({type(exc).__name__}: {exc})") from None
    geometry = obj.get("geometry")
    if not isinstance(geometry, TaxelGeometry):
        raise ModelFileError(f"{path}: payload has no TaxelGeometry")
    if geometry.n_taxels != header["n_taxels"]:
        raise ModelFileError(f"{path}: header says {header['n_taxels']} taxels, geometry has {geometry.n_taxels}")
    return ModelBundle(
        estimator=obj["estimator"],
        geometry=geometry,
        window_length=int(header["window_length"]),
        frame_rate_hz=float(header["frame_rate_hz"]),
        labels=tuple(header["labels"]),
        meta=dict(header.get("meta") or {}),
    )


def resolve_model_path(spec: str, tracking_uri: str | None = None) -> Path:
    """A local file for ``spec``: a path, or an MLflow artifact URI (``runs:/...``) downloaded first."""
    if "://" in spec or spec.startswith("runs:/") or spec.startswith("models:/"):
        import mlflow

        try:
            local = mlflow.artifacts.download_artifacts(artifact_uri=spec, tracking_uri=tracking_uri)
        except Exception as exc:  # mlflow raises many types (missing run, no server)
            raise ModelFileError(f"cannot fetch model {spec!r} from MLflow ({tracking_uri or 'default tracking URI'}): {exc}") from None
        p = Path(local)
        if p.is_dir():
            found = sorted(p.rglob("*.sphrimodel"))
            if len(found) != 1:
                raise ModelFileError(f"{spec}: expected one .sphrimodel file in the artifact folder, found {len(found)}")
            p = found[0]
        return p
    return Path(spec)
