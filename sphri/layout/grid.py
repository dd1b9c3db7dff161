"""Regular chart grids: ``layout=grid`` (the paper's) and ``layout=hex``.

``res`` taxels along the link's long axis (grid); the count around follows
from the chart's circumference so taxels are square unless ``layout.aspect``
says otherwise. Hex lattices are equilateral with the square grid's area per
taxel, so both have about the same taxel count at a ``res`` (the hex has
about 1.075 ``res`` rows; see :func:`sphri.layout.common.grid_dims`). Taxel
centres are chart-cell centres moved onto the mesh along the primitive's
normal (Embree rays); each taxel's area is the mesh area that maps into its
cell.
"""

from __future__ import annotations

import logging

import numpy as np

from sphri.config import Configured
from sphri.layout.common import (
    grid_cell_areas,
    grid_dims,
    grid_uv,
    project_chart_points,
)
from sphri.layout.schema import GridLayoutSchema, HexLayoutSchema, check_res
from sphri.types import Layout, Link, SurfaceMap

log = logging.getLogger(__name__)


def build_grid(
    link: Link, surface: SurfaceMap, res: int, aspect: float = 1.0, hex_rows: bool = False, seed: int = 0
) -> Layout:
    """A (hex) grid layout of ``res`` rows along the link (see module docstring)."""
    name = "layout.hex" if hex_rows else "layout.grid"
    res = check_res(res, name)
    if not surface.has_uv:
        raise ValueError(
            f"{name} needs a surface with a 2-D chart; surface kind {surface.kind!r} has none "
            "(use surface=cylinder|box, or layout=random|density|file)"
        )
    h, w = grid_dims(surface, res, aspect, hex_rows)
    uv = grid_uv(h, w, hex_rows)
    pos, nrm, valid = project_chart_points(link, surface, uv)
    offsets = np.where(np.arange(h) % 2 == 1, 0.5, 0.0) if hex_rows else np.zeros(h)
    area = grid_cell_areas(link, surface, (h, w), offsets, seed)
    area[~valid] = 0.0
    if not valid.all():
        log.info(
            "%s on link %r: %d of %d cells lie outside every chart face (area 0)",
            name,
            link.name,
            (~valid).sum(),
            h * w,
        )
    return Layout(
        kind="hex" if hex_rows else "grid",
        position_m=pos,
        normal=nrm,
        area_m2=area,
        uv=uv,
        grid_shape=(h, w),
        pitch_u_m=float(surface.metres_per_u / h),
        pitch_v_m=float(surface.metres_per_v / w),
    )


class GridLayout(Configured):
    """``layout=grid``: H x W taxels on the chart, row-major (u, v)."""

    VERSION = "1"

    SCHEMA = GridLayoutSchema
    aspect: float  # these two set from SCHEMA by Configured
    seed: int

    def build(self, link: Link, surface: SurfaceMap, res: int) -> Layout:
        """Taxels of a ``res``-row grid on ``link`` through ``surface``'s chart."""
        return build_grid(link, surface, res, self.aspect, hex_rows=False, seed=self.seed)


class HexLayout(Configured):
    """``layout=hex``: a triangular lattice (odd rows shifted half a taxel around), the grid's taxel count."""

    VERSION = "2"

    SCHEMA = HexLayoutSchema
    aspect: float  # these two set from SCHEMA by Configured
    seed: int

    def build(self, link: Link, surface: SurfaceMap, res: int) -> Layout:
        """An equilateral lattice on ``link`` with the ``res`` grid's area per taxel."""
        return build_grid(link, surface, res, self.aspect, hex_rows=True, seed=self.seed)
