"""``HandCapsules``: the tracked hand as capsule colliders -> :class:`HandModel`.

Sizes come from the YAML (``conf/hand/quest_capsules.yaml``, the Quest hand of
the reference study) or from a dataset's own ``hand_capsule_definition.json``
(``definition_path``), read by :func:`load_definition`.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sphri.config import ConfigError
from sphri.errors import read_json
from sphri.hand.schema import FINGERS, check_capsules
from sphri.types import HandModel

log = logging.getLogger(__name__)

_FINGER_WORDS = {f: f for f in FINGERS if f != "palm"}
_FINGER_WORDS.update({"wrist": "palm", "palm": "palm", "hand": "palm", "little": "pinky"})
_FINGER_RE = re.compile("|".join(sorted(_FINGER_WORDS, key=len, reverse=True)))


class HandDefinitionError(ValueError):
    """A hand capsule definition file is malformed; the message names file and entry."""


def finger_of(name: str) -> str | None:
    """Hand part named in a capsule name (``"index2"`` -> ``"index"``, ``"wrist1"`` -> ``"palm"``)."""
    m = _FINGER_RE.search(name.lower())
    return _FINGER_WORDS[m.group(0)] if m else None


def load_definition(path: str | Path) -> list[dict[str, Any]]:
    """Read a ``hand_capsule_definition.json`` into capsule specs (dicts).

    Each entry needs a name (``column_prefix`` or ``name``), ``radius_m``
    (> 0), ``height_m`` (>= 0, tip to tip), ``orientation`` (0/1/2 = local
    X/Y/Z) and ``center_offset_m`` (``{x, y, z}`` or a 3-list, metres); an
    optional ``finger`` overrides the one inferred from the name. Entries
    are sorted by ``capsule_index`` when every entry has one. Any count is
    allowed; names must be unique. Errors name the file and the entry.
    """
    path = Path(path)
    raw = read_json(path, HandDefinitionError, f"hand capsule definition not found: {path}")
    if not isinstance(raw, list) or not raw:
        raise HandDefinitionError(
            f"{path}: expected a non-empty JSON list of capsule entries, got {type(raw).__name__}"
        )
    seen: dict[str, int] = {}
    specs = [_capsule_spec(path, i, e, seen) for i, e in enumerate(raw)]
    return _sorted_by_index(path, specs)


def _entry_error(path: Path, i: int, entry: Any, msg: str) -> HandDefinitionError:
    """The error for entry ``i`` of the file at ``path``: the file, the entry (and its name if it has one), ``msg``."""
    nm = entry.get("column_prefix", entry.get("name")) if isinstance(entry, dict) else None
    label = f"entry {i}" + (f" ({nm!r})" if nm is not None else "")
    return HandDefinitionError(f"{path}: {label}: {msg}")


def _number(path: Path, i: int, e: dict, key: str) -> float:
    """Entry ``e``'s field ``key`` as a float; raises :class:`HandDefinitionError` when missing or not finite."""
    if key not in e:
        raise _entry_error(path, i, e, f"missing {key!r}")
    v = e[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise _entry_error(path, i, e, f"{key}={v!r} is not a finite number")
    return float(v)


def _center_offset(path: Path, i: int, e: dict) -> list[float]:
    """Entry ``e``'s ``center_offset_m`` (``{x, y, z}`` or a 3-list, default zeros) as 3 floats (metres)."""
    off = e.get("center_offset_m", [0.0, 0.0, 0.0])
    if isinstance(off, dict):
        if not all(k in off for k in "xyz"):
            raise _entry_error(path, i, e, f"center_offset_m={off!r} needs keys x, y, z")
        off = [off["x"], off["y"], off["z"]]
    if (
        not isinstance(off, list)
        or len(off) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in off)
    ):
        raise _entry_error(path, i, e, f"center_offset_m={off!r} must be 3 finite numbers (metres)")
    return [float(v) for v in off]


def _capsule_spec(path: Path, i: int, e: Any, seen: dict[str, int]) -> dict[str, Any]:
    """Entry ``i`` of the file, checked, as a capsule spec (sizes in metres; ``_index``: its ``capsule_index``
    or None). ``seen`` maps the names read so far to their entries; this one's is added."""
    if not isinstance(e, dict):
        raise _entry_error(path, i, e, f"expected an object, got {type(e).__name__}")
    name = e.get("column_prefix", e.get("name"))
    if not isinstance(name, str) or not name:
        raise _entry_error(path, i, e, "missing capsule name ('column_prefix' or 'name')")
    if name in seen:
        raise _entry_error(path, i, e, f"duplicate name {name!r} (also entry {seen[name]})")
    seen[name] = i
    radius = _number(path, i, e, "radius_m")
    if radius <= 0:
        raise _entry_error(path, i, e, f"radius_m={radius} must be > 0")
    height = _number(path, i, e, "height_m")
    if height < 0:
        raise _entry_error(path, i, e, f"height_m={height} must be >= 0")
    orient = _number(path, i, e, "orientation")
    if orient not in (0.0, 1.0, 2.0):
        raise _entry_error(path, i, e, f"orientation={e['orientation']!r} must be 0 (X), 1 (Y) or 2 (Z)")
    offset = _center_offset(path, i, e)
    finger = e.get("finger", finger_of(name))
    if finger not in FINGERS:
        raise _entry_error(path, i, e, f'cannot tell the finger of {name!r}; add "finger": one of {list(FINGERS)}')
    return dict(
        name=name,
        finger=finger,
        radius_m=radius,
        height_m=height,
        axis=int(orient),
        center_offset_m=offset,
        _index=e.get("capsule_index"),
    )


def _sorted_by_index(path: Path, specs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``specs`` without their ``_index``, sorted by it when every one is an int (they must then be unique)."""
    idx = [s.pop("_index") for s in specs]
    if all(isinstance(k, int) and not isinstance(k, bool) for k in idx):
        if len(set(idx)) != len(idx):
            raise HandDefinitionError(f"{path}: capsule_index values are not unique: {idx}")
        specs = [s for _, s in sorted(zip(idx, specs), key=lambda t: t[0])]
    return specs


def _as_dict(spec: Any) -> dict[str, Any]:
    if isinstance(spec, Mapping) or hasattr(spec, "items"):
        return {k: spec[k] for k in ("name", "finger", "radius_m", "height_m", "axis", "center_offset_m")}
    return {k: getattr(spec, k) for k in ("name", "finger", "radius_m", "height_m", "axis", "center_offset_m")}


class HandCapsules:
    """The tracked hand as capsule colliders (``hand=quest_capsules``).

    ``capsules``: specs (``CapsuleSpec`` or mappings with name, finger,
    radius_m, height_m, axis, center_offset_m), in the order of the poses'
    capsule axis. ``definition_path``: read a dataset's
    ``hand_capsule_definition.json`` instead. ``scale``: multiplies every
    radius, height and offset.
    """

    VERSION = "1"

    def __init__(self, capsules: Sequence[Any] = (), definition_path: str | None = None, scale: float = 1.0):
        self.capsules = [_as_dict(s) for s in capsules]
        self.definition_path = definition_path
        self.scale = float(scale)
        if not self.scale > 0:
            raise ConfigError(f"hand.scale={scale!r} is invalid: must be > 0")
        if definition_path is None:
            if not self.capsules:
                raise ConfigError("hand.capsules=[] is invalid: at least one capsule (or set hand.definition_path)")
            check_capsules(self.capsules)

    def build(self) -> HandModel:
        """The :class:`HandModel` (C capsules, float64 metres)."""
        if self.definition_path is not None:
            specs = load_definition(self.definition_path)
            log.info("hand: %d capsules from %s", len(specs), self.definition_path)
        else:
            specs = self.capsules
        s = self.scale
        return HandModel(
            names=tuple(str(c["name"]) for c in specs),
            fingers=tuple(str(c["finger"]) for c in specs),
            radius_m=np.array([c["radius_m"] for c in specs], dtype=np.float64) * s,
            height_m=np.array([c["height_m"] for c in specs], dtype=np.float64) * s,
            axis=np.array([c["axis"] for c in specs], dtype=np.int64),
            center_offset_m=np.array([list(c["center_offset_m"]) for c in specs], dtype=np.float64).reshape(-1, 3) * s,
        )
