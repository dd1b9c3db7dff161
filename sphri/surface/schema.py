"""Config schemas of the surface group (``conf/surface/*.yaml``).

Each dataclass is a component's typed config; ranges are field metadata
(:func:`sphri.config.setting`), checked at composition naming the full key
(``surface.n_samples``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from sphri.config import ComponentSchema, require, setting, store

AXIS_CHOICES = ("auto", "x", "y", "z")


@dataclass
class SurfaceSchema(ComponentSchema, group="surface"):
    """Base of the surface group's schemas."""


@dataclass
class CylinderSurfaceSchema(SurfaceSchema):
    """Fitted cylinder: u = h along the axis, v = a the angle (wraps)."""

    _target_: str = "sphri.surface.cylinder.CylinderSurface"
    HAS_CHART: ClassVar[bool] = True
    """A 2-D (u, v) chart (grid layouts and ``encoder=ellipse`` need one)."""
    axis: str = setting("auto", choices=AXIS_CHOICES)
    """Initial axis: ``auto`` (PCA candidates, best fit) or a link axis x|y|z."""
    refine_axis: bool = True
    """Refine the axis direction by least squares together with centre/radius."""
    seam: list[float] = field(default_factory=lambda: [1.0, 0.0, 0.0])
    """Link-frame direction where the angle a = 0 (projected off the axis)."""
    n_samples: int = setting(20000, lo=500, hi=5_000_000)
    """Area-weighted surface samples used by the fit."""
    seed: int = setting(0, lo=0)
    """Seed of the surface sampling (the fit is deterministic given it)."""
    warn_residual_mm: float = setting(6.0, lo=0.0, lo_open=True)
    """Log a warning when the RMS fit residual exceeds this (mm)."""

    def check(self) -> None:
        require(len(self.seam) == 3, self.key("seam"), self.seam, "must be 3 numbers (a link-frame direction)")
        require(sum(float(s) ** 2 for s in self.seam) > 0, self.key("seam"), self.seam, "must be non-zero")


@dataclass
class BoxSurfaceSchema(SurfaceSchema):
    """Oriented bounding box unfolded into a net (band around the long axis + caps)."""

    _target_: str = "sphri.surface.box.BoxSurface"
    HAS_CHART: ClassVar[bool] = True
    """A 2-D (u, v) chart (grid layouts and ``encoder=ellipse`` need one)."""
    n_samples: int = setting(20000, lo=500, hi=5_000_000)
    """Area-weighted surface samples used for the residual."""
    seed: int = setting(0, lo=0)
    """Seed of the surface sampling."""
    warn_residual_mm: float = setting(25.0, lo=0.0, lo_open=True)
    """Log a warning when the RMS distance from the mesh to the box exceeds this (mm)."""


@dataclass
class MeshSurfaceSchema(SurfaceSchema):
    """No 2-D chart: taxels live on the 3-D mesh surface."""

    _target_: str = "sphri.surface.mesh.MeshSurface"
    n_samples: int = setting(20000, lo=500, hi=5_000_000)
    """Area-weighted surface samples used for the principal (long) axis."""
    seed: int = setting(0, lo=0)
    """Seed of the surface sampling."""


store(group="surface", name="cylinder_schema", node=CylinderSurfaceSchema)
store(group="surface", name="box_schema", node=BoxSurfaceSchema)
store(group="surface", name="mesh_schema", node=MeshSurfaceSchema)
