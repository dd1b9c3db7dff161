"""Trained-model files for live classification (``.sphrimodel``), without pickle.

A file holds a fitted model (sphri's ``model=rf`` or ``model=cnn_gru``, or any class that persists
itself, see :mod:`sphri.export.registry`), the :class:`~sphri.types.TaxelGeometry` it was trained on,
the window length L and frame rate, and the gesture labels. Layout::

    b"SPHRIMODEL3\\n"
    uint32 LE  length of the JSON header
    JSON       header: format, labels, window_length, frame_rate_hz,
               n_taxels, grid_shape, model, created, meta, geometry scalars
               and the model's own part (``estimator``: its NAME as ``kind``,
               its import path as ``class`` unless it is sphri's own, and
               what its ``save_state()`` wrote, e.g. ``params``)
    32 bytes   BLAKE2b digest over magic, header and payload
    32 bytes   HMAC-SHA256 over the same with the model key, or zeros
               (:mod:`sphri.integrity`)
    payload    an .npz (read with ``allow_pickle=False``) of arrays: taxel
               positions and chart coordinates, and the model's own arrays:
               the Random Forest's classes and scikit-learn forest as skops
               bytes (every type in it must be in its own list,
               :data:`sphri.models.rf.TRUSTED_TYPES`, the only list skops is
               given), the CNN-GRU's network as a torch state dict
               (``torch.load`` with ``weights_only=True``); see :mod:`sphri.models.persist`

This module knows no model: the header's ``kind`` picks the class in the registry and the class
reads its own state (``load_state``). A class that is not sphri's own is imported only from a
package listed in ``plugins`` (``skin live plugins=[labext]``).

The digests cover the header too: an edited label order or window length is
a checksum mismatch. With ``SPHRI_MODEL_KEY`` (or ``SPHRI_MODEL_KEY_FILE``)
set, :func:`save_model` signs the file and :func:`load_model` refuses a
file not signed with that key. A signed file read without a key configured
is refused too (its signature cannot be checked), unless the reader says so
(``allow_unverified=True``; ``skin live allow_unverified=true``). Nothing in a model file is unpickled, so a
crafted file cannot run code: the old pickle format (``SPHRIMODEL1``), the
previous format (``SPHRIMODEL2``, whose checksum left the header out),
any type outside a model's trusted list and any model class from a package
not listed in ``plugins`` are refused with an error naming the file. Files can also live in MLflow or on a
web server: :func:`resolve_model_path` fetches ``runs:/<run_id>/<path>`` (or
any artifact URI) only with ``allow_remote=True`` (``skin live
allow_remote=true``)."""

from __future__ import annotations

import datetime as _dt
import io
import json
import os
import struct
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sphri.export import registry
from sphri.fsutil import write_atomic
from sphri.integrity import DIGEST_SIZE, FROM_ENV, NO_KEY, keyed_digest, keyed_ok, load_key, plain_digest
from sphri.types import GESTURES, TaxelGeometry

MAGIC = b"SPHRIMODEL3\n"
OLD_MAGIC = b"SPHRIMODEL1\n"
#: The previous format: its checksum covered the payload only.
V2_MAGIC = b"SPHRIMODEL2\n"
FORMAT = "sphri-model/3"
_DIGEST = DIGEST_SIZE


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
            "created": self.meta.get("created") or _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "meta": self.meta,
        }


def _restore_estimator(path: Path, head: dict[str, Any], z: Any, geometry: TaxelGeometry, plugins) -> Any:
    """The model of a file's ``estimator`` header part and npz arrays: its class (from the registry, by
    ``kind``) reads its own state with ``load_state``."""
    try:
        cls = registry.model_class(head, plugins)
        return cls.load_state(head, z, geometry)
    except ModelFileError:
        raise
    except ValueError as exc:
        raise ModelFileError(f"{path}: {exc}") from None


def seal_model(head_bytes: bytes, payload: bytes, key: bytes | None = None) -> bytes:
    """A model file's bytes: magic, header, its two digests (over magic, header and payload), payload."""
    return (
        MAGIC
        + struct.pack("<I", len(head_bytes))
        + head_bytes
        + plain_digest(MAGIC, head_bytes, payload)
        + keyed_digest(key, MAGIC, head_bytes, payload)
        + payload
    )


def save_model(bundle: ModelBundle, path: str | os.PathLike, key: Any = FROM_ENV) -> Path:
    """Write ``bundle`` to ``path`` atomically (JSON header + npz payload, no pickle), signed with ``key``
    (bytes, None, or the environment's model key, the default) and with the mode the umask gives."""
    if not hasattr(bundle.estimator, "predict_proba"):
        raise ModelFileError(f"{type(bundle.estimator).__name__} has no predict_proba; live classification needs it")
    path = Path(path)
    try:  # the model's own save_state() through the registry
        est_head, arrays = registry.state_of(bundle.estimator)
    except registry.NotExportable as exc:
        raise ModelFileError(str(exc)) from None
    g = bundle.geometry
    header = bundle.header()
    header["estimator"] = est_head
    header["geometry"] = {
        "wrap_v": bool(g.wrap_v),
        "metres_per_u": float(g.metres_per_u),
        "metres_per_v": float(g.metres_per_v),
        "has_uv": g.uv is not None,
    }
    arrays["position_m"] = np.asarray(g.position_m, dtype=np.float64)
    if g.uv is not None:
        arrays["uv"] = np.asarray(g.uv, dtype=np.float64)
    buf = io.BytesIO()
    np.savez(buf, allow_pickle=False, **arrays)  # state_of refused object arrays: nothing to pickle
    payload = buf.getvalue()
    head_bytes = json.dumps(header, default=str).encode()
    blob = seal_model(head_bytes, payload, load_key("model") if key is FROM_ENV else key)
    write_atomic(path, blob)
    return path


_EXPORT = "export it again with sphri export"


def _split(path: Path) -> tuple[dict[str, Any], bytes, bytes, bytes, bytes]:
    """(header, header bytes, plain digest, keyed digest, payload) of a model file."""
    if not path.is_file():
        raise ModelFileError(f"model file not found: {path}")
    blob = path.read_bytes()
    if blob.startswith(OLD_MAGIC):
        raise ModelFileError(
            f"{path}: an old pickle-based model file (SPHRIMODEL1); sphri no longer unpickles model files "
            f"(a crafted one could run code); {_EXPORT}"
        )
    if blob.startswith(V2_MAGIC):
        raise ModelFileError(
            f"{path}: a sphri-model/2 file, whose checksum does not cover its header (labels, window length); {_EXPORT}"
        )
    if not blob.startswith(MAGIC) or len(blob) < len(MAGIC) + 4:
        raise ModelFileError(f"{path}: not a sphri model file (make one with sphri export)")
    (n,) = struct.unpack_from("<I", blob, len(MAGIC))
    h0 = len(MAGIC) + 4
    if len(blob) < h0 + n + 2 * _DIGEST:
        raise ModelFileError(f"{path}: truncated")
    head_bytes = blob[h0 : h0 + n]
    try:
        header = json.loads(head_bytes)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise ModelFileError(f"{path}: header is not JSON ({type(exc).__name__}: {exc})") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        got = header.get("format") if isinstance(header, dict) else type(header).__name__
        raise ModelFileError(f"{path}: format {got!r}, this sphri reads {FORMAT!r}")
    d0 = h0 + n
    return header, head_bytes, blob[d0 : d0 + _DIGEST], blob[d0 + _DIGEST : d0 + 2 * _DIGEST], blob[d0 + 2 * _DIGEST :]


def inspect_model(path: str | os.PathLike) -> dict[str, Any]:
    """The JSON header of a model file (nothing else is read, nothing checked but its format)."""
    return _split(Path(path))[0]


def _check_header(path: Path, header: dict[str, Any]) -> None:
    """Field types and ranges of a header, each error naming the file and field."""
    labels = header.get("labels")
    if (
        not isinstance(labels, list)
        or not labels
        or not all(isinstance(x, str) and x for x in labels)
        or len(set(labels)) != len(labels)
    ):
        raise ModelFileError(f"{path}: header field labels must be a list of distinct gesture names, got {labels!r}")
    checks = (
        ("window_length", int, 1, 100_000),
        ("n_taxels", int, 1, 1_000_000),
        ("frame_rate_hz", (int, float), 1e-3, 1e6),
    )
    for name, typ, lo, hi in checks:
        v = header.get(name)
        if isinstance(v, bool) or not isinstance(v, typ) or not lo <= v <= hi:
            raise ModelFileError(f"{path}: header field {name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
    grid = header.get("grid_shape")
    if grid is not None and not (
        isinstance(grid, list)
        and len(grid) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in grid)
    ):
        raise ModelFileError(
            f"{path}: header field grid_shape must be null or [H, W] (positive integers), got {grid!r}"
        )
    for name in ("geometry", "estimator"):
        if not isinstance(header.get(name), dict):
            raise ModelFileError(f"{path}: header field {name} must be an object, got {header.get(name)!r}")


def load_model(
    path: str | os.PathLike, key: Any = FROM_ENV, plugins: Sequence[str] = (), allow_unverified: bool = False
) -> ModelBundle:
    """Read a model file written by :func:`save_model` (checks its digests over header and payload, its
    header fields, types and shapes; no pickle). ``key``: the model key (bytes), None, or the environment's
    (default); with a key, a file not signed with it is refused. ``plugins``: packages whose model classes
    the file may name (:func:`sphri.export.registry.model_class`); sphri's own models need none.
    ``allow_unverified``: load a signed file although no key is configured (its signature unchecked)."""
    path = Path(path)
    header, payload = _verified_parts(path, key, allow_unverified)
    _check_header(path, header)
    geometry, estimator = _read_payload(path, header, payload, plugins)
    meta = header.get("meta") or {}
    if not isinstance(meta, dict):
        raise ModelFileError(f"{path}: header field meta must be an object, got {meta!r}")
    bundle = ModelBundle(
        estimator=estimator,
        geometry=geometry,
        window_length=int(header["window_length"]),
        frame_rate_hz=float(header["frame_rate_hz"]),
        labels=tuple(header["labels"]),
        meta=dict(meta),
    )
    _check_predicts(path, bundle)
    return bundle


def _verified_parts(path: Path, key: Any, allow_unverified: bool) -> tuple[dict[str, Any], bytes]:
    """``(header, payload)`` of the model file at ``path`` once its plain digest matches and its signature
    suits ``key`` (as :func:`load_model` takes it); :class:`ModelFileError` naming the file otherwise."""
    header, head_bytes, digest, keyed, payload = _split(path)
    if plain_digest(MAGIC, head_bytes, payload) != digest:
        raise ModelFileError(f"{path}: checksum mismatch over its header and payload (edited, truncated or corrupted)")
    key = load_key("model") if key is FROM_ENV else key
    if not keyed_ok(key, keyed, MAGIC, head_bytes, payload):
        why = "it was written without the key" if keyed == NO_KEY else "its HMAC does not match the key"
        raise ModelFileError(f"{path}: not signed with the configured model key (SPHRI_MODEL_KEY): {why}; refused")
    if key is None and keyed != NO_KEY and not allow_unverified:
        raise ModelFileError(
            f"{path}: signed with a model key, but no key is configured to check it (SPHRI_MODEL_KEY or "
            "SPHRI_MODEL_KEY_FILE); set the key, or allow_unverified=true to load it unchecked; refused"
        )
    return header, payload


def _read_payload(
    path: Path, header: dict[str, Any], payload: bytes, plugins: Sequence[str]
) -> tuple[TaxelGeometry, Any]:
    """``(geometry, estimator)`` from a checked ``header`` and the npz ``payload`` bytes; any missing or
    ill-typed field is a :class:`ModelFileError` naming the file."""
    try:
        geo_head = header["geometry"]
        with np.load(io.BytesIO(payload), allow_pickle=False) as z:
            geometry = TaxelGeometry(
                grid_shape=(header["grid_shape"][0], header["grid_shape"][1]) if header.get("grid_shape") else None,
                uv=z["uv"] if geo_head.get("has_uv") else None,
                position_m=z["position_m"],
                wrap_v=bool(geo_head["wrap_v"]),
                metres_per_u=float(geo_head["metres_per_u"]),
                metres_per_v=float(geo_head["metres_per_v"]),
            )
            if geometry.n_taxels != header["n_taxels"]:
                raise ModelFileError(
                    f"{path}: header says {header['n_taxels']} taxels, geometry has {geometry.n_taxels}"
                )
            from sphri.adjacency import metric_coords

            metric_coords(geometry)  # grid shape, chart and positions agree (ValueError naming the field)
            estimator = _restore_estimator(path, header["estimator"], z, geometry, plugins)
        classes = np.asarray(getattr(estimator, "classes_", []))
        if classes.size and (
            classes.dtype.kind not in "iu" or classes.min() < 0 or classes.max() >= len(header["labels"])
        ):
            raise ModelFileError(
                f"{path}: the estimator predicts classes {classes.tolist()} but the header names "
                f"{len(header['labels'])} labels"
            )
    except ModelFileError:
        raise
    except (
        KeyError,
        TypeError,
        ValueError,
        OSError,
        AttributeError,
        EOFError,
        OverflowError,
        IndexError,
        zipfile.BadZipFile,
    ) as exc:  # a field missing or of the wrong kind
        raise ModelFileError(f"{path}: malformed model file ({type(exc).__name__}: {exc})") from None
    return geometry, estimator


def _check_predicts(path: Path, bundle: ModelBundle) -> None:
    """Refuse (:class:`ModelFileError`) a model that cannot give finite probabilities for a blank window.

    A header signed with the key may still carry estimator parameters of the wrong kind (an empty
    threshold): one prediction now, so it fails here, in one line, not mid-session."""
    try:
        p = bundle.predict_proba(np.zeros((1, bundle.window_length, bundle.n_taxels), dtype=np.float32))
        if p.shape != (1, len(bundle.labels)) or not np.all(np.isfinite(p)):
            raise ValueError(f"probabilities of shape {p.shape} for {len(bundle.labels)} labels")
    except Exception as exc:  # noqa: BLE001 - whatever the estimator raises, the file is at fault
        raise ModelFileError(f"{path}: the model does not predict ({type(exc).__name__}: {exc})") from None


def is_remote(spec: str) -> bool:
    """True for an MLflow artifact URI or any ``scheme://`` address (fetched, not a local file)."""
    return "://" in spec or spec.startswith(("runs:/", "models:/"))


def resolve_model_path(spec: str, tracking_uri: str | None = None, allow_remote: bool = False) -> Path:
    """A local file for ``spec``: a path, or (only with ``allow_remote``) an MLflow artifact URI downloaded first."""
    if is_remote(spec):
        if not allow_remote:
            raise ModelFileError(
                f"model={spec} is remote; sphri fetches model files only when asked: add allow_remote=true "
                "(or download it yourself and pass the local path)"
            )
        import mlflow

        before = mlflow.get_tracking_uri()
        try:
            if tracking_uri:  # MLflow 3 resolves a run's logged model through the global tracking URI
                mlflow.set_tracking_uri(tracking_uri)
            local = mlflow.artifacts.download_artifacts(artifact_uri=spec, tracking_uri=tracking_uri)
        except Exception as exc:  # mlflow raises many types (missing run, no server)
            raise ModelFileError(
                f"cannot fetch model {spec!r} from MLflow ({tracking_uri or 'default tracking URI'}): {exc}"
            ) from None
        finally:
            mlflow.set_tracking_uri(before)
        p = Path(local)
        if p.is_dir():
            found = sorted(p.rglob("*.sphrimodel"))
            if len(found) != 1:
                raise ModelFileError(
                    f"{spec}: expected one .sphrimodel file in the artifact folder, found {len(found)}"
                )
            p = found[0]
        return p
    return Path(spec)
