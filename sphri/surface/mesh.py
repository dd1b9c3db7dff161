"""``surface=mesh``: no 2-D chart; taxels live on the 3-D mesh surface.

The map only records the link's principal (long) axis, its extent along it
and its surface area, which layouts use to size a grid-equivalent count.
"""

from __future__ import annotations

from sphri.config import Configured
from sphri.geometry.link import check_link, geometry_of
from sphri.surface.schema import MeshSurfaceSchema
from sphri.types import Link, SurfaceMap


def fit_mesh(link: Link, n_samples: int = 20000, seed: int = 0) -> SurfaceMap:
    """Chart-less surface of ``link``: params ``long_axis``, ``length_m``, ``area_m2``, ``centroid``."""
    check_link(link)
    geom = geometry_of(link)
    centroid, _, axes = geom.axes(n_samples, seed)
    t = (geom.used_vertices - centroid) @ axes[0]
    return SurfaceMap(
        kind="mesh",
        has_uv=False,
        metres_per_u=0.0,
        metres_per_v=0.0,
        wrap_v=False,
        fit_residual_m=0.0,
        params={
            "long_axis": axes[0],
            "length_m": float(t.max() - t.min()),
            "area_m2": geom.area_m2,
            "centroid": centroid,
            "notes": (),
        },
    )


class MeshSurface(Configured):
    """``surface=mesh``: taxels on the 3-D surface, no (u, v)."""

    VERSION = "2"

    SCHEMA = MeshSurfaceSchema
    n_samples: int  # these two set from SCHEMA by Configured
    seed: int

    def fit(self, link: Link) -> SurfaceMap:
        """Record the link's long axis and area (no chart)."""
        return fit_mesh(link, self.n_samples, self.seed)
