"""Config schemas of the surface group (``conf/surface/*.yaml``).

Each dataclass is a component's typed config; ``__post_init__`` checks value
ranges and names the full key (``surface.n_samples``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from sphri.config import require, require_choice, require_range, store

AXIS_CHOICES = ("auto", "x", "y", "z")


def _check_common(group_key: str, n_samples: int, seed: int, warn_residual_mm: float) -> None:
    require_range(f"{group_key}.n_samples", n_samples, lo=500, hi=5_000_000)
    require_range(f"{group_key}.seed", seed, lo=0)
    require_range(f"{group_key}.warn_residual_mm", warn_residual_mm, lo=0.0, lo_open=True)


@dataclass
class CylinderSurfaceSchema:
    """Fitted cylinder: u = h along the axis, v = a the angle (wraps)."""

    _target_: str = "sphri.surface.cylinder.CylinderSurface"
    HAS_CHART: ClassVar[bool] = True
    """A 2-D (u, v) chart (grid layouts and ``encoder=ellipse`` need one)."""
    axis: str = "auto"
    """Initial axis: ``auto`` (PCA candidates, best fit) or a link axis x|y|z."""
    refine_axis: bool = True
    """Refine the axis direction by least squares together with centre/radius."""
    seam: list[float] = field(default_factory=lambda: [1.0, 0.0, 0.0])
    """Link-frame direction where the angle a = 0 (projected off the axis)."""
    n_samples: int = 20000
    """Area-weighted surface samples used by the fit."""
    seed: int = 0
    """Seed of the surface sampling (the fit is deterministic given it)."""
    warn_residual_mm: float = 6.0
    """Log a warning when the RMS fit residual exceeds this (mm)."""

    def __post_init__(self) -> None:
        require_choice("surface.axis", self.axis, AXIS_CHOICES)
        require(len(self.seam) == 3, "surface.seam", self.seam, "must be 3 numbers (a link-frame direction)")
        require(sum(float(s) ** 2 for s in self.seam) > 0, "surface.seam", self.seam, "must be non-zero")
        _check_common("surface", self.n_samples, self.seed, self.warn_residual_mm)


@dataclass
class BoxSurfaceSchema:
    """Oriented bounding box unfolded into a net (band around the long axis + caps)."""

    _target_: str = "sphri.surface.box.BoxSurface"
    HAS_CHART: ClassVar[bool] = True
    """A 2-D (u, v) chart (grid layouts and ``encoder=ellipse`` need one)."""
    n_samples: int = 20000
    """Area-weighted surface samples used for the residual."""
    seed: int = 0
    """Seed of the surface sampling."""
    warn_residual_mm: float = 25.0
    """Log a warning when the RMS distance from the mesh to the box exceeds this (mm)."""

    def __post_init__(self) -> None:
        _check_common("surface", self.n_samples, self.seed, self.warn_residual_mm)


@dataclass
class MeshSurfaceSchema:
    """No 2-D chart: taxels live on the 3-D mesh surface."""

    _target_: str = "sphri.surface.mesh.MeshSurface"
    n_samples: int = 20000
    """Area-weighted surface samples used for the principal (long) axis."""
    seed: int = 0
    """Seed of the surface sampling."""

    def __post_init__(self) -> None:
        require_range("surface.n_samples", self.n_samples, lo=500, hi=5_000_000)
        require_range("surface.seed", self.seed, lo=0)


store(group="surface", name="cylinder_schema", node=CylinderSurfaceSchema)
store(group="surface", name="box_schema", node=BoxSurfaceSchema)
store(group="surface", name="mesh_schema", node=MeshSurfaceSchema)
