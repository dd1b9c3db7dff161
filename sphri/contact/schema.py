"""Config schemas of the ``contact`` group (``contact=exact`` / ``contact=spheres``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import require_choice, require_range, runtime_setting, store

#: Inside definitions a component may ask for (see :mod:`sphri.contact.mesh`).
INSIDE_CHOICES: tuple[str, ...] = ("auto", "hull", "winding")


@dataclass
class ExactContactSchema:
    """``contact=exact``: exact capsule-vs-mesh distance, inside test and contact patch."""

    _target_: str = "sphri.contact.exact.ExactContact"
    margin_m: float = 0.0
    """Metres added to every capsule radius (0 = contact means touching)."""
    inside: str = "auto"
    """Solid used for inside: auto, hull (convex hull of the link) or winding (winding number)."""
    chunk_frames: int = runtime_setting(20000)
    """Frames processed at once (bounds memory: ~1 kB per frame and capsule row)."""

    def __post_init__(self) -> None:
        require_range("contact.margin_m", self.margin_m, lo=0.0, hi=1.0)
        require_choice("contact.inside", self.inside, INSIDE_CHOICES)
        require_range("contact.chunk_frames", self.chunk_frames, lo=1)


@dataclass
class SphereContactSchema:
    """``contact=spheres``: the paper's approximation, each capsule as k spheres."""

    _target_: str = "sphri.contact.spheres.SphereContact"
    k: int = 5
    """Spheres per capsule, centred evenly along its segment (ends included when k > 1)."""
    margin_m: float = 0.0
    """Metres added to every capsule radius (0 = contact means touching)."""
    chunk_frames: int = runtime_setting(20000)
    """Frames processed at once (bounds memory)."""

    def __post_init__(self) -> None:
        require_range("contact.k", self.k, lo=1, hi=1000)
        require_range("contact.margin_m", self.margin_m, lo=0.0, hi=1.0)
        require_range("contact.chunk_frames", self.chunk_frames, lo=1)


store(group="contact", name="exact_schema", node=ExactContactSchema)
store(group="contact", name="spheres_schema", node=SphereContactSchema)
