"""Config schemas of the ``contact`` group (``contact=exact`` / ``contact=spheres``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import ComponentSchema, setting, store

#: Inside definitions a component may ask for (see :mod:`sphri.contact.mesh`).
INSIDE_CHOICES: tuple[str, ...] = ("auto", "hull", "winding")


@dataclass
class ContactSchema(ComponentSchema, group="contact"):
    """Base of the contact group's schemas."""


@dataclass
class ExactContactSchema(ContactSchema):
    """``contact=exact``: exact capsule-vs-mesh distance, inside test and contact patch."""

    _target_: str = "sphri.contact.exact.ExactContact"
    margin_m: float = setting(0.0, lo=0.0, hi=1.0)
    """Metres added to every capsule radius (0 = contact means touching)."""
    inside: str = setting("auto", choices=INSIDE_CHOICES)
    """Solid used for inside: auto, hull (convex hull of the link) or winding (winding number)."""
    chunk_frames: int = setting(20000, runtime=True, lo=1)
    """Frames processed at once (bounds memory: ~1 kB per frame and capsule row)."""


@dataclass
class SphereContactSchema(ContactSchema):
    """``contact=spheres``: the paper's approximation, each capsule as k spheres."""

    _target_: str = "sphri.contact.spheres.SphereContact"
    k: int = setting(5, lo=1, hi=1000)
    """Spheres per capsule, centred evenly along its segment (ends included when k > 1)."""
    margin_m: float = setting(0.0, lo=0.0, hi=1.0)
    """Metres added to every capsule radius (0 = contact means touching)."""
    chunk_frames: int = setting(20000, runtime=True, lo=1)
    """Frames processed at once (bounds memory)."""


store(group="contact", name="exact_schema", node=ExactContactSchema)
store(group="contact", name="spheres_schema", node=SphereContactSchema)
