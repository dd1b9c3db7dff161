"""The registry of models that persist themselves in model files (``.sphrimodel``), by their ``NAME``.

A model class is exportable when it has

- ``NAME``: a short string (``"rf"``), the key it is registered and stored under;
- ``predict_proba(x)``: (n, L, N) windows -> (n, n_classes), and ``classes_`` after ``fit``;
- ``save_state(self) -> (head, arrays)``: a JSON-able dict (its hyperparameters under ``"params"``
  and whatever else it needs) and a dict of plain numpy arrays (no object arrays: the payload is read
  with ``allow_pickle=False``). Bytes of another safe format go in as ``uint8`` arrays;
- ``load_state(cls, head, arrays, geometry)`` (a classmethod): the fitted model back. It raises
  ``ValueError`` with one line saying what is wrong; the model file adds its path.

sphri's own models (``rf``, ``cnn_gru``) are registered here by name (imported only when a file of that
kind is read). Any other class, a plugin's included, needs no registration step and no edit in sphri:
:func:`state_of` stores its ``NAME`` and import path, and :func:`model_class` imports that class back only
from a package the caller trusts (``plugins=[labext]``, as for the pipeline's own ``_target_`` check in
:func:`sphri.config.check_target`) or one registered in this process with :func:`register`. A file naming
anything else is refused before any import, so a crafted header cannot make sphri import a module.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable
from typing import Any, TypeVar

import numpy as np

#: sphri's own exportable models: NAME -> "module:Class" (imported on first use).
BUILTIN: dict[str, str] = {
    "rf": "sphri.models.rf:RandomForest",
    "cnn_gru": "sphri.models.cnn_gru:CnnGru",
}
_REGISTERED: dict[str, type[Any]] = {}

#: What an exportable model class must have (see the module docstring).
PROTOCOL = ("NAME", "predict_proba", "save_state", "load_state")
#: Payload arrays the model file itself stores beside a model's own arrays.
RESERVED_ARRAYS = frozenset({"position_m", "uv"})


#: A class (a model class or any other, for :func:`register`'s decorator use).
_C = TypeVar("_C", bound=type)


class NotExportable(TypeError):
    """A model class that lacks part of :data:`PROTOCOL` (the message names what is missing)."""


def missing(cls: type) -> list[str]:
    """The parts of :data:`PROTOCOL` that ``cls`` lacks (an empty list: it is exportable)."""
    gone = [name for name in PROTOCOL if not hasattr(cls, name)]
    name = getattr(cls, "NAME", None)
    if "NAME" not in gone and not (isinstance(name, str) and name.strip()):
        gone.append("NAME (a non-empty string)")
    return gone


def class_path(cls: type) -> str:
    """``"module:QualName"`` of ``cls``."""
    return f"{cls.__module__}:{cls.__qualname__}"


def register(cls: _C) -> _C:
    """Register an exportable model class under its ``NAME`` (usable as a class decorator). A plugin only
    needs this to load files in a process that imported it without listing its package in ``plugins``."""
    gone = missing(cls)
    if gone:
        raise NotExportable(f"{cls.__qualname__} cannot be registered as a model: it lacks {', '.join(gone)}")
    name: str = getattr(cls, "NAME", "")  # a non-empty string: missing() checked it
    if name in BUILTIN and class_path(cls) != BUILTIN[name]:
        raise NotExportable(f"model name {name!r} of {class_path(cls)} is sphri's own ({BUILTIN[name]})")
    _REGISTERED[name] = cls
    return cls


def names() -> list[str]:
    """Every registered model name (sphri's own first)."""
    return list(BUILTIN) + [n for n in _REGISTERED if n not in BUILTIN]


def _import(path: str) -> Any:
    module, _, qual = path.partition(":")
    obj: Any = importlib.import_module(module)
    for part in qual.split("."):
        obj = getattr(obj, part)
    return obj


def state_of(estimator: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(header part, arrays) of a fitted model: its ``save_state()`` plus its ``NAME`` (``kind``) and,
    for a class that is not sphri's own, its import path (``class``). Raises :class:`NotExportable`."""
    cls = type(estimator)
    gone = missing(cls)
    if gone:
        raise NotExportable(
            f"{cls.__name__} cannot be saved in a model file: it lacks {', '.join(gone)} (a model persists "
            "itself with save_state()/load_state(), see sphri.export.registry; model files hold no pickles)"
        )
    head, arrays = estimator.save_state()
    if not isinstance(head, dict) or not isinstance(arrays, dict):
        raise NotExportable(f"{cls.__name__}.save_state() must return (dict, dict of arrays)")
    clash = sorted(RESERVED_ARRAYS & set(arrays))
    if clash:
        raise NotExportable(f"{cls.__name__}.save_state(): array names {clash} are the model file's own")
    out_arrays = {}
    for k, v in arrays.items():
        a = np.asarray(v)
        if a.dtype == object:
            raise NotExportable(f"{cls.__name__}.save_state(): array {k!r} holds Python objects (not storable)")
        out_arrays[str(k)] = a
    out_head = {**head, "kind": cls.NAME}
    if BUILTIN.get(cls.NAME) != class_path(cls):
        out_head["class"] = class_path(cls)
    return out_head, out_arrays


def model_class(head: dict[str, Any], plugins: Iterable[str] = ()) -> type[Any]:
    """The class a model file's ``estimator`` header names. sphri's own by ``kind``; any other only if
    registered in this process or if its top-level package is in ``plugins``. Raises ``ValueError``."""
    kind = head.get("kind")
    if not isinstance(kind, str):
        raise ValueError(f"estimator kind must be a model name, got {kind!r}")
    if kind in BUILTIN:
        return _import(BUILTIN[kind])
    path = head.get("class")
    if kind in _REGISTERED and (path is None or path == class_path(_REGISTERED[kind])):
        return _REGISTERED[kind]
    if not isinstance(path, str) or ":" not in path:
        raise ValueError(f"unknown estimator kind {kind!r} (this sphri reads {', '.join(names())})")
    package = path.split(".", 1)[0].split(":", 1)[0]
    plugins = [str(p) for p in plugins]
    if package not in plugins:
        raise ValueError(
            f"the model {kind!r} is {path} from package {package!r}, which is not listed in plugins "
            f"(add plugins=[{package}] if you trust it)"
        )
    try:
        cls = _import(path)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"the model class {path} cannot be imported ({type(exc).__name__}: {exc})") from None
    if not isinstance(cls, type) or getattr(cls, "NAME", None) != kind or missing(cls):
        raise ValueError(f"{path} is not an exportable model named {kind!r} (see sphri.export.registry)")
    return cls
