"""Config schemas of the ``hand`` group."""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING

from sphri.config import ComponentSchema, require, require_range, setting, store
from sphri.inputs import input_path

#: Hand parts a capsule may belong to.
FINGERS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "pinky", "palm")


@dataclass
class HandSchema(ComponentSchema, group="hand"):
    """Base of the hand group's schemas."""


@dataclass
class CapsuleSpec:
    """One capsule collider attached to a tracked joint (Unity conventions)."""

    name: str = MISSING
    """Capsule name, also the pose columns' prefix (e.g. ``index2``)."""
    finger: str = MISSING
    """Hand part: thumb, index, middle, ring, pinky or palm."""
    radius_m: float = MISSING
    """Capsule radius (metres), > 0."""
    height_m: float = MISSING
    """Tip-to-tip length including both caps (metres), >= 0."""
    axis: int = 0
    """Joint-local axis of the capsule: 0 = X, 1 = Y, 2 = Z."""
    center_offset_m: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Capsule centre in the joint's local frame (metres), 3 values."""


def check_capsules(specs: list, key: str = "hand.capsules") -> None:
    """Range-check capsule entries (mappings or :class:`CapsuleSpec`).

    Raises :class:`sphri.config.ConfigError` naming ``key[i].field``.
    """
    names: dict[str, int] = {}
    for i, s in enumerate(specs):
        get = s.get if hasattr(s, "get") else lambda k, _s=s: getattr(_s, k)
        k = f"{key}[{i}]"
        name = get("name")
        require(isinstance(name, str) and name != "", f"{k}.name", name, "a non-empty string")
        require(name not in names, f"{k}.name", name, f"names must be unique (also entry {names.get(name)})")
        names[name] = i
        finger = get("finger")
        require(finger in FINGERS, f"{k}.finger", finger, f"allowed values: {list(FINGERS)}")
        require_range(f"{k}.radius_m", float(get("radius_m")), lo=0.0, lo_open=True)
        require_range(f"{k}.height_m", float(get("height_m")), lo=0.0)
        require(get("axis") in (0, 1, 2), f"{k}.axis", get("axis"), "0 (X), 1 (Y) or 2 (Z)")
        off = list(get("center_offset_m"))
        require(len(off) == 3, f"{k}.center_offset_m", off, "3 values (x, y, z) in metres")


@dataclass
class HandCapsulesSchema(HandSchema):
    """``hand=quest_capsules``: the tracked hand as capsule colliders."""

    _target_: str = "sphri.hand.capsules.HandCapsules"
    capsules: list[CapsuleSpec] = field(default_factory=list)
    """The capsules, in pose-column order (ignored when ``definition_path`` is set)."""
    definition_path: str | None = input_path(None)
    """A dataset's ``hand_capsule_definition.json`` to read instead of ``capsules``."""
    scale: float = setting(1.0, lo=0.0, lo_open=True)
    """Factor applied to every radius, height and offset (1 = as defined)."""

    def check(self) -> None:
        if self.definition_path is None:
            require(
                len(self.capsules) > 0,
                self.key("capsules"),
                self.capsules,
                "at least one capsule (or set hand.definition_path)",
            )
            check_capsules(self.capsules)


store(group="hand", name="quest_capsules_schema", node=HandCapsulesSchema)
