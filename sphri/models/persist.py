"""Safe building blocks for a model's ``save_state()`` / ``load_state()`` (no pickle anywhere).

A model file (:mod:`sphri.export.model_file`) stores a model as a JSON header part and plain numpy
arrays; a model's fitted objects go in as bytes of a format that cannot run code when read:

- scikit-learn objects as skops archives, loaded only if every type their schema names is in the
  model's own trusted list (:func:`skops_array` / :func:`skops_load`);
- torch modules as a state dict of tensors, read with ``torch.load(weights_only=True)``
  (:func:`torch_state_array` / :func:`torch_state_load`).

The load functions raise ``ValueError`` with one line saying what is wrong (the model file adds its path).
"""

from __future__ import annotations

import importlib.abc
import io
import json
import sys
import zipfile
from collections.abc import Iterable
from typing import Any

import numpy as np

#: Plain containers and numbers a skops payload may hold besides a model's own trusted types.
PLAIN_TYPES = frozenset(
    [f"builtins.{t}" for t in ("dict", "list", "tuple", "str", "int", "float", "bool", "NoneType")]
    + ["numpy.ndarray", "numpy.bool_", "numpy.bool"]
    + [f"numpy.{k}{b}" for k in ("int", "uint") for b in (8, 16, 32, 64)]
    + [f"numpy.float{b}" for b in (16, 32, 64)]
)


def params_of(estimator: Any) -> dict[str, Any]:
    """A scikit-learn-style estimator's constructor parameters as JSON (tuples as lists), without ``geometry``."""
    return {
        k: (list(v) if isinstance(v, tuple) else v)
        for k, v in estimator.get_params(deep=False).items()
        if k != "geometry"
    }


def bytes_array(data: bytes) -> np.ndarray:
    """``data`` as a uint8 array (how bytes travel in the npz payload)."""
    return np.frombuffer(data, dtype=np.uint8)


#: The one package scikit-learn's ``all_estimators`` imports that imports torch (its array-API adapter).
_SKLEARN_TORCH_ADAPTER = "sklearn.externals.array_api_compat.torch"


class _SkipPackage(importlib.abc.MetaPathFinder):
    """A finder that refuses to import one module (an ImportError, which ``pkgutil.walk_packages`` skips)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> None:
        if fullname == self.name:
            raise ImportError(f"{fullname} is not needed to read or write a skops archive")
        return None


def skops_io() -> Any:
    """``skops.io``, imported without torch. Importing it lists scikit-learn's estimators (its default
    trusted types), which walks every scikit-learn package, among them the array-API adapter for torch,
    which imports torch: a Random Forest's model file then imported torch to be written or read. That one
    package (it holds no estimator) is skipped while skops is imported, unless torch is loaded already
    (what it saves a fresh process loading a model file: docs/BENCHMARKS.md). skops' list of trusted
    scikit-learn types is the same either way (a test)."""
    if "skops.io" in sys.modules or "torch" in sys.modules:
        import skops.io

        return skops.io
    finder = _SkipPackage(_SKLEARN_TORCH_ADAPTER)
    sys.meta_path.insert(0, finder)
    try:
        import skops.io
    finally:
        sys.meta_path.remove(finder)
    return skops.io


def skops_array(obj: Any) -> np.ndarray:
    """A scikit-learn object as a skops archive in a uint8 array."""
    return bytes_array(skops_io().dumps(obj))


def skops_types(data: bytes, what: str = "payload") -> set[str]:
    """Every ``module.Class`` named in a skops archive's schema (read as JSON; nothing is imported)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            schema = json.loads(zf.read("schema.json"))
    except (zipfile.BadZipFile, KeyError, OSError, ValueError, RecursionError) as exc:
        raise ValueError(f"the {what} is unreadable ({type(exc).__name__}: {exc})") from None
    found: set[str] = set()
    stack = [schema]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            if "__class__" in node or "__module__" in node:
                found.add(f"{node.get('__module__')}.{node.get('__class__')}")
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    return found


def skops_load(array: np.ndarray, trusted: Iterable[str], expect: type, what: str = "payload") -> Any:
    """The object of a skops archive, if every type it names is in ``trusted`` or :data:`PLAIN_TYPES` (that
    list, not skops' defaults, is the only one skops is given) and the object is exactly an ``expect``."""
    sio = skops_io()
    data = np.asarray(array).tobytes()
    found = skops_types(data, what)
    untrusted = sorted(found - set(trusted) - PLAIN_TYPES)
    if untrusted:
        raise ValueError(f"the {what} holds untrusted types {untrusted} (outside sphri's list); refused (not loaded)")
    try:
        obj = sio.loads(data, trusted=sorted(found))
    except Exception as exc:  # skops raises several types on a damaged archive
        raise ValueError(f"the {what} is unreadable ({type(exc).__name__}: {exc})") from None
    if type(obj) is not expect:
        raise ValueError(f"the {what} holds a {type(obj).__name__}, not a {expect.__name__}")
    return obj


def torch_state_array(module: Any) -> np.ndarray:
    """A torch module's state dict (tensors on the CPU) as ``torch.save`` bytes in a uint8 array."""
    import torch

    buf = io.BytesIO()
    torch.save({k: v.detach().cpu() for k, v in module.state_dict().items()}, buf)
    return bytes_array(buf.getvalue())


def torch_state_load(array: np.ndarray, module: Any) -> Any:
    """Load a state dict saved by :func:`torch_state_array` into ``module`` (weights only: tensors, no objects)."""
    import torch

    try:
        state = torch.load(io.BytesIO(np.asarray(array).tobytes()), map_location="cpu", weights_only=True)
    except Exception as exc:  # torch's weights-only unpickler refuses anything but tensors
        raise ValueError(f"the network weights are not a plain state dict ({type(exc).__name__}: {exc})") from None
    try:
        module.load_state_dict(state)
    except (RuntimeError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"the network weights do not fit the saved hyperparameters ({exc})") from None
    return module
