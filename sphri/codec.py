"""Values as arrays + JSON: the stage cache's format, with no pickle anywhere.

:func:`encode` turns a stage's output (a dataclass of :mod:`sphri.types`, or
tuples/lists/dicts of them) into ``(tree, arrays)``: ``tree`` is JSON, every
numpy array goes into ``arrays`` (stored in an ``.npz`` read with
``allow_pickle=False``). :func:`decode` rebuilds the value and checks it
against its contract: a dataclass is rebuilt only when its class is one of
the data types sphri stores (:func:`data_types`: the dataclasses of
:mod:`sphri.types`, the stage contracts and :data:`EXTRA_TYPES`; a name an
entry holds is looked up in that list, never imported) and the stored
fields are exactly the class's fields, fields annotated as arrays, strings
or numbers hold one, and a class that defines ``check_decoded()`` (e.g.
:class:`sphri.types.CVResult`: confusion matrices of the labels' size,
accuracies that match them) accepts the values.
Anything else raises :class:`DecodeError` (the cache logs it and recomputes).

One generic encoder/decoder for every dataclass of arrays, scalars, strings,
containers, ``pandas.DataFrame`` (column by column) and nested dataclasses,
rather than a codec per type: a new field or type in :mod:`sphri.types`
needs no code here. It is hand-written because the libraries that serialise
arbitrary Python objects (pickle, joblib, cloudpickle) execute code on load,
and the safe ones (json, npz, parquet) do not know dataclasses.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import math
import types
import typing
from typing import Any

import numpy as np
import pandas as pd

#: Data types of stage values outside :mod:`sphri.types` and the stage contracts (the scenario study's
#: stages), by ``module:qualname``: the only names besides those that :func:`decode` resolves.
EXTRA_TYPES = ("sphri.sessions.format:SessionDataset", "sphri.sessions.contact:BodyContacts")


class EncodeError(TypeError):
    """A value holds something that cannot be stored as arrays + JSON."""


class DecodeError(ValueError):
    """An entry does not decode into its contract (unknown class, wrong fields or types)."""


def _array(arr: np.ndarray, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    ref = f"a{len(arrays)}"
    if arr.dtype == object:
        flat = arr.ravel()
        if not all(isinstance(x, str) for x in flat):
            bad = next(type(x).__name__ for x in flat if not isinstance(x, str))
            raise EncodeError(f"object array holding {bad}: only strings can be stored")
        arrays[ref] = arr.astype(str) if arr.size else np.zeros(arr.shape, dtype="U1")
        return {"__nd__": ref, "object": True}
    if arr.dtype.hasobject or arr.dtype.kind == "V":
        raise EncodeError(f"array of dtype {arr.dtype} cannot be stored without pickle")
    arrays[ref] = arr
    return {"__nd__": ref}


def encode(value: Any, arrays: dict[str, np.ndarray] | None = None) -> tuple[Any, dict[str, np.ndarray]]:
    """``(tree, arrays)``: ``value`` as a JSON-able tree whose arrays are named in ``arrays``."""
    arrays = {} if arrays is None else arrays

    def enc(v: Any) -> Any:
        if v is None or isinstance(v, (bool, int, str)):
            return v
        if isinstance(v, float):
            return v if math.isfinite(v) else {"__float__": repr(v)}
        if isinstance(v, np.ndarray):
            return _array(v, arrays)
        if isinstance(v, np.generic):
            if v.dtype.hasobject:
                raise EncodeError(f"numpy object scalar {v!r}")
            return {"__np__": v.dtype.str, "v": enc(v.item())}
        if isinstance(v, tuple):
            return {"__tuple__": [enc(x) for x in v]}
        if isinstance(v, list):
            return [enc(x) for x in v]
        if isinstance(v, dict):
            return {"__dict__": [[enc(k), enc(x)] for k, x in v.items()]}
        if isinstance(v, pd.DataFrame):
            if not all(isinstance(c, str) for c in v.columns):
                raise EncodeError("DataFrame column names must be strings")
            if not isinstance(v.index, pd.RangeIndex) or v.index.start != 0 or v.index.step != 1:
                raise EncodeError("DataFrame must have a default RangeIndex (reset_index first)")
            return {"__df__": [[c, _array(v[c].to_numpy(), arrays), str(v[c].dtype)] for c in v.columns], "n": len(v)}
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return {"__dc__": _name(type(v)), "f": {f.name: enc(getattr(v, f.name)) for f in dataclasses.fields(v)}}
        raise EncodeError(f"cannot store a {type(v).__module__}.{type(v).__qualname__} as arrays + JSON")

    return enc(value), arrays


def _name(cls: type) -> str:
    return f"{cls.__module__}:{cls.__qualname__}"


@functools.cache
def data_types() -> dict[str, type]:
    """``{"module:qualname": class}`` of the dataclasses an entry may hold (besides :data:`EXTRA_TYPES`):
    those defined in :mod:`sphri.types` and every stage's contract."""
    import sphri.types
    from sphri.stages import STAGE_BY_NAME

    found: dict[str, type] = {}

    def add(c: Any) -> None:
        if isinstance(c, tuple):
            for x in c:
                add(x)
        elif isinstance(c, type) and dataclasses.is_dataclass(c):
            found[_name(c)] = c

    add(tuple(v for v in vars(sphri.types).values() if isinstance(v, type) and v.__module__ == "sphri.types"))
    for stage in STAGE_BY_NAME.values():
        add(stage.contract)
    return found


def _resolve_class(name: str) -> type:
    found = data_types().get(name)
    if found is not None:
        return found
    if name not in EXTRA_TYPES:
        raise DecodeError(f"class {name!r} is not a data type sphri stores")
    module, _, qual = name.partition(":")  # a name of the list above, not of the entry
    obj = getattr(importlib.import_module(module), qual)
    if not (isinstance(obj, type) and dataclasses.is_dataclass(obj)):  # pragma: no cover - the list is ours
        raise DecodeError(f"{name!r} is not a dataclass")
    return obj


_SIMPLE = {np.ndarray: np.ndarray, str: str, bool: bool, float: (float, int), int: int}


def _check_field(cls: type, name: str, hint: Any, value: Any) -> None:
    """Shallow check of a field against its annotation (arrays, str, numbers; Optional of these)."""
    options = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    allowed: list[type] = []
    for opt in options:
        if opt is type(None):
            allowed.append(type(None))
        elif opt in _SIMPLE:
            want = _SIMPLE[opt]
            allowed.extend(want if isinstance(want, tuple) else (want,))
        else:
            return  # containers and nested types: checked by their own decoding
    if not isinstance(value, tuple(allowed)):
        raise DecodeError(f"{cls.__qualname__}.{name}: expected {hint}, got {type(value).__name__}")


def decode(tree: Any, arrays: Any) -> Any:
    """Inverse of :func:`encode`; ``arrays`` maps names to arrays (an opened ``npz``)."""

    def arr(node: dict) -> np.ndarray:
        ref = node["__nd__"]
        if not isinstance(ref, str) or ref not in arrays:
            raise DecodeError(f"array {ref!r} missing from the entry")
        a = np.asarray(arrays[ref])
        return a.astype(object) if node.get("object") else a

    def dec(node: Any) -> Any:
        if node is None or isinstance(node, (bool, str, int, float)):
            return node
        if isinstance(node, list):
            return [dec(x) for x in node]
        if not isinstance(node, dict):
            raise DecodeError(f"unexpected JSON node {type(node).__name__}")
        if "__nd__" in node:
            return arr(node)
        if "__float__" in node:
            return float(node["__float__"])
        if "__np__" in node:
            return np.dtype(node["__np__"]).type(dec(node["v"]))
        if "__tuple__" in node:
            return tuple(dec(x) for x in node["__tuple__"])
        if "__dict__" in node:
            return {_hashable(dec(k)): dec(v) for k, v in node["__dict__"]}
        if "__df__" in node:
            df = pd.DataFrame(index=pd.RangeIndex(int(node["n"])))
            for c, ref, dtype in node["__df__"]:
                values = arr(ref)
                col = pd.Series(values, dtype=object if values.dtype == object else None)
                if str(col.dtype) != dtype:
                    col = col.astype(dtype)
                df[str(c)] = col
            if len(df) != int(node["n"]):
                raise DecodeError("DataFrame length mismatch")
            return df
        if "__dc__" in node:
            cls = _resolve_class(str(node["__dc__"]))
            stored = node.get("f")
            if not isinstance(stored, dict):
                raise DecodeError(f"{cls.__qualname__}: no fields")
            fields = {f.name: f for f in dataclasses.fields(cls)}
            if set(stored) != set(fields):
                missing, extra = sorted(set(fields) - set(stored)), sorted(set(stored) - set(fields))
                raise DecodeError(
                    f"{cls.__qualname__}: fields differ from the contract (missing {missing}, unknown {extra})"
                )
            decoded = {k: dec(v) for k, v in stored.items()}
            try:
                hints = typing.get_type_hints(cls)
            except Exception:  # an annotation that cannot be evaluated: skip the shallow checks
                hints = {}
            for k, v in decoded.items():
                if k in hints:
                    _check_field(cls, k, hints[k], v)
            obj = cls(**{k: v for k, v in decoded.items() if fields[k].init})
            for k, f in fields.items():
                if not f.init:
                    object.__setattr__(obj, k, decoded[k])
            check = getattr(obj, "check_decoded", None)
            if callable(check):  # the class's own consistency rules (ValueError naming the field)
                check()
            return obj
        raise DecodeError(f"unknown JSON node with keys {sorted(node)[:5]}")

    try:
        return dec(tree)
    except DecodeError:
        raise
    except (KeyError, TypeError, ValueError, OverflowError, RecursionError) as exc:
        raise DecodeError(f"malformed entry ({type(exc).__name__}: {exc})") from None
    except SystemExit as exc:  # a value's own code asking to exit is a bad entry, not the end of the run
        raise DecodeError(f"decoding raised SystemExit({exc.code!r})") from None


def _hashable(k: Any) -> Any:
    if isinstance(k, list):
        return tuple(_hashable(x) for x in k)
    return k


def check_contract(value: Any, contract: Any, where: str) -> None:
    """Raise :class:`DecodeError` unless ``value`` matches ``contract``.

    ``contract``: a type (``isinstance``), a tuple of contracts (a tuple value
    with one item per contract), or ``None`` (anything).
    """
    if contract is None:
        return
    if isinstance(contract, tuple):
        if not isinstance(value, tuple) or len(value) != len(contract):
            raise DecodeError(f"{where}: expected a tuple of {len(contract)}, got {type(value).__name__}")
        for i, (v, c) in enumerate(zip(value, contract)):
            check_contract(v, c, f"{where}[{i}]")
        return
    if not isinstance(value, contract):
        raise DecodeError(f"{where}: expected {contract.__qualname__}, got {type(value).__qualname__}")
