"""Trained-model files for live classification (``.sphrimodel``), without pickle.

A file holds a fitted sphri estimator (``model=rf`` or ``model=cnn_gru``),
the :class:`~sphri.types.TaxelGeometry` it was trained on, the window length
L and frame rate, and the gesture labels. Layout::

    b"SPHRIMODEL2\\n"
    uint32 LE  length of the JSON header
    JSON       header: format, labels, window_length, frame_rate_hz,
               n_taxels, grid_shape, model, created, meta, geometry scalars
               and the estimator's kind and hyperparameters
    32 bytes   BLAKE2b digest of the payload
    payload    an .npz (read with ``allow_pickle=False``) of arrays: taxel
               positions and chart coordinates, classes, and the fitted part
               of the estimator: the Random Forest's scikit-learn forest as
               skops bytes (loaded with an explicit trusted-type list,
               :data:`TRUSTED_TYPES`), the CNN-GRU's network as a torch state
               dict (``torch.load(weights_only=True)``)

Nothing in a model file is unpickled, so a crafted file cannot run code: the
old pickle format (``SPHRIMODEL1``) and any type outside the trusted list are
refused with an error naming the file. Files can also live in MLflow or on a
web server: :func:`resolve_model_path` fetches ``runs:/<run_id>/<path>`` (or
any artifact URI) only with ``allow_remote=True`` (``skin live
allow_remote=true``).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import io
import json
import os
import struct
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sphri.types import GESTURES, TaxelGeometry

MAGIC = b"SPHRIMODEL2\n"
OLD_MAGIC = b"SPHRIMODEL1\n"
FORMAT = "sphri-model/2"
_DIGEST = 32

#: Types a Random Forest's skops payload may hold beyond skops' own defaults
#: (numpy arrays, builtins): anything else is refused before loading.
TRUSTED_TYPES = (
    "sklearn.ensemble._forest.RandomForestClassifier",
    "sklearn.tree._classes.DecisionTreeClassifier",
    "sklearn.tree._tree.Tree",
)


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


def _estimator_state(estimator: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(JSON header part, arrays) of a fitted sphri estimator; no pickle anywhere."""
    from sphri.models.cnn_gru import CnnGru
    from sphri.models.rf import RandomForest

    name = type(estimator).__name__
    head: dict[str, Any] = {}
    arrays: dict[str, np.ndarray] = {}
    if isinstance(estimator, (RandomForest, CnnGru)):
        params = {k: (list(v) if isinstance(v, tuple) else v)
                  for k, v in estimator.get_params(deep=False).items() if k != "geometry"}
        head = {"kind": estimator.NAME, "params": params}
        arrays = {"classes": np.asarray(estimator.classes_)}
    if isinstance(estimator, RandomForest):
        import skops.io as sio

        arrays["forest_skops"] = np.frombuffer(sio.dumps(estimator.forest_), dtype=np.uint8)
        return head, arrays
    if isinstance(estimator, CnnGru):
        import torch

        buf = io.BytesIO()
        torch.save({k: v.detach().cpu() for k, v in estimator.net_.state_dict().items()}, buf)
        arrays["state_dict"] = np.frombuffer(buf.getvalue(), dtype=np.uint8)
        head["precision_"] = getattr(estimator, "precision_", "float32")
        return head, arrays
    raise ModelFileError(
        f"{name} cannot be saved in a model file: only sphri's model=rf and model=cnn_gru are stored "
        "(as parameters and arrays; model files hold no pickles)"
    )


def _restore_estimator(path: Path, head: dict[str, Any], z: Any, geometry: TaxelGeometry) -> Any:
    """The estimator of a model file from its header part and npz arrays (see :func:`_estimator_state`)."""
    kind = head.get("kind")
    params = dict(head.get("params") or {})
    classes = z["classes"]
    if kind == "rf":
        import skops.io as sio

        from sphri.models.features import FEATURE_NAMES
        from sphri.models.rf import RandomForest

        data = z["forest_skops"].tobytes()
        try:
            untrusted = [t for t in sio.get_untrusted_types(data=data) if t not in TRUSTED_TYPES]
        except Exception as exc:  # skops raises several types on a damaged archive
            raise ModelFileError(f"{path}: the forest payload is unreadable ({type(exc).__name__}: {exc})") from None
        if untrusted:
            raise ModelFileError(f"{path}: the forest payload holds untrusted types {untrusted}; refused (not loaded)")
        model = RandomForest(**params, geometry=geometry)
        model.forest_ = sio.loads(data, trusted=list(TRUSTED_TYPES))
        model.classes_ = model.forest_.classes_
        model.n_features_in_ = len(FEATURE_NAMES)
        model.feature_names_ = FEATURE_NAMES
        return model
    if kind == "cnn_gru":
        import torch

        from sphri.models.cnn_gru import CnnGru, CnnGruNet

        model = CnnGru(**params, geometry=geometry)
        try:
            state = torch.load(io.BytesIO(z["state_dict"].tobytes()), map_location="cpu", weights_only=True)
        except Exception as exc:  # torch's weights-only unpickler refuses anything but tensors
            raise ModelFileError(f"{path}: the network weights are not a plain state dict ({type(exc).__name__}: {exc})") from None
        grid, wrap = model._layout(geometry.n_taxels)
        net = CnnGruNet(geometry.n_taxels, grid, wrap, [int(c) for c in model.channels], [int(s) for s in model.strides],
                        int(model.embed_size), int(model.hidden), len(classes))
        try:
            net.load_state_dict(state)
        except (RuntimeError, KeyError) as exc:
            raise ModelFileError(f"{path}: the network weights do not fit the saved hyperparameters ({exc})") from None
        net.eval()
        model.net_ = net
        model.classes_ = classes
        model.precision_ = head.get("precision_", "float32")
        return model
    raise ModelFileError(f"{path}: unknown estimator kind {kind!r} (this sphri reads rf and cnn_gru)")


def save_model(bundle: ModelBundle, path: str | os.PathLike) -> Path:
    """Write ``bundle`` to ``path`` atomically (JSON header + npz payload, no pickle)."""
    if not hasattr(bundle.estimator, "predict_proba"):
        raise ModelFileError(f"{type(bundle.estimator).__name__} has no predict_proba; live classification needs it")
    path = Path(path)
    est_head, arrays = _estimator_state(bundle.estimator)
    g = bundle.geometry
    header = bundle.header()
    header["estimator"] = est_head
    header["geometry"] = {"wrap_v": bool(g.wrap_v), "metres_per_u": float(g.metres_per_u),
                          "metres_per_v": float(g.metres_per_v), "has_uv": g.uv is not None}
    arrays["position_m"] = np.asarray(g.position_m, dtype=np.float64)
    if g.uv is not None:
        arrays["uv"] = np.asarray(g.uv, dtype=np.float64)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    payload = buf.getvalue()
    head_bytes = json.dumps(header, default=str).encode()
    blob = MAGIC + struct.pack("<I", len(head_bytes)) + head_bytes + hashlib.blake2b(payload, digest_size=_DIGEST).digest() + payload
    path.parent.mkdir(parents=True, exist_ok=True)
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
    if blob.startswith(OLD_MAGIC):
        raise ModelFileError(
            f"{path}: an old pickle-based model file (SPHRIMODEL1); sphri no longer unpickles model files "
            "(a crafted one could run code). Export it again with python -m sphri.hardware.train_export"
        )
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
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        got = header.get("format") if isinstance(header, dict) else header
        raise ModelFileError(f"{path}: format {got!r}, this sphri reads {FORMAT!r}")
    digest = blob[h0 + n : h0 + n + _DIGEST]
    return header, digest, blob[h0 + n + _DIGEST :]


def inspect_model(path: str | os.PathLike) -> dict[str, Any]:
    """The JSON header of a model file (nothing else is read)."""
    return _split(Path(path))[0]


def load_model(path: str | os.PathLike) -> ModelBundle:
    """Read a model file written by :func:`save_model` (checks its digest, types and shapes; no pickle)."""
    path = Path(path)
    header, digest, payload = _split(path)
    if hashlib.blake2b(payload, digest_size=_DIGEST).digest() != digest:
        raise ModelFileError(f"{path}: checksum mismatch (truncated or corrupted)")
    try:
        geo_head = header["geometry"]
        with np.load(io.BytesIO(payload), allow_pickle=False) as z:
            geometry = TaxelGeometry(
                grid_shape=tuple(int(v) for v in header["grid_shape"]) if header.get("grid_shape") else None,
                uv=z["uv"] if geo_head.get("has_uv") else None,
                position_m=z["position_m"],
                wrap_v=bool(geo_head["wrap_v"]),
                metres_per_u=float(geo_head["metres_per_u"]),
                metres_per_v=float(geo_head["metres_per_v"]),
            )
            if geometry.n_taxels != header["n_taxels"]:
                raise ModelFileError(f"{path}: header says {header['n_taxels']} taxels, geometry has {geometry.n_taxels}")
            estimator = _restore_estimator(path, header["estimator"], z, geometry)
    except ModelFileError:
        raise
    except (KeyError, TypeError, ValueError, OSError) as exc:  # a field missing or of the wrong kind
        raise ModelFileError(f"{path}: malformed model file ({type(exc).__name__}: {exc})") from None
    return ModelBundle(
        estimator=estimator,
        geometry=geometry,
        window_length=int(header["window_length"]),
        frame_rate_hz=float(header["frame_rate_hz"]),
        labels=tuple(header["labels"]),
        meta=dict(header.get("meta") or {}),
    )


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
            raise ModelFileError(f"cannot fetch model {spec!r} from MLflow ({tracking_uri or 'default tracking URI'}): {exc}") from None
        finally:
            mlflow.set_tracking_uri(before)
        p = Path(local)
        if p.is_dir():
            found = sorted(p.rglob("*.sphrimodel"))
            if len(found) != 1:
                raise ModelFileError(f"{spec}: expected one .sphrimodel file in the artifact folder, found {len(found)}")
            p = found[0]
        return p
    return Path(spec)
