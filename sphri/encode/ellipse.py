"""``encoder=ellipse``: the paper's encoder.

Each contact patch (a disc of ``patch_radius_m`` on the touched triangle's
plane) becomes an ellipse in the (u, v) chart through the local Jacobian of
the map and is rasterized onto the layout's H x W grid, wrapping in v (see
:mod:`sphri.encode.raster`). Binary by default (uint8): a taxel is on when at
least ``threshold`` of its cell is covered, and the taxel holding a patch
centre is always on. ``binary: false`` gives the covered fraction (float32).
"""

from __future__ import annotations

import numpy as np

from sphri.config import Configured
from sphri.encode.common import check_frame_index, make_frames, select_rows
from sphri.encode.schema import EllipseEncoderSchema
from sphri.layout.common import row_offsets
from sphri.types import Contacts, Frames, Layout, Link, SurfaceMap


def check_contact_rows(contacts: Contacts, rows: np.ndarray, who: str) -> None:
    """Raise naming the field when the selected contact rows hold NaN or bad radii."""
    for name in ("point_m", "normal", "patch_radius_m"):
        a = np.asarray(getattr(contacts, name))[rows]
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{who}: contacts.{name} holds NaN or inf in the requested frames")
    if rows.size and np.asarray(contacts.patch_radius_m)[rows].min() < 0:
        raise ValueError(f"{who}: contacts.patch_radius_m must be >= 0")


def require_chart_grid(layout: Layout, surface: SurfaceMap, who: str) -> tuple[int, int]:
    """The layout's (H, W) when it is a grid on a 2-D chart; a clear error otherwise."""
    if layout.grid_shape is None or layout.uv is None or not surface.has_uv:
        raise ValueError(
            f"{who} needs a grid layout on a 2-D chart (layout=grid|hex with surface=cylinder|box); "
            f"got layout kind {layout.kind!r} (grid_shape={layout.grid_shape}) on surface kind {surface.kind!r}"
        )
    h, w = layout.grid_shape
    if h * w != layout.n_taxels:
        raise ValueError(f"{who}: layout grid_shape {layout.grid_shape} does not match its {layout.n_taxels} taxels")
    return h, w


def encode_grid(
    contacts: Contacts,
    surface: SurfaceMap,
    layout: Layout,
    frame_index: np.ndarray,
    binary: bool,
    threshold: float,
    subsamples: int,
    who: str,
) -> Frames:
    """Chart-raster encoding of the frames ``frame_index`` (shared with ``coverage``)."""
    from sphri.encode.raster import patch_ellipses, rasterize  # numba: loaded where frames are encoded

    h, w = require_chart_grid(layout, surface, who)
    if layout.uv is None:
        raise AssertionError(f"{who}: require_chart_grid passed a layout without uv")  # it refuses one
    fi = check_frame_index(contacts, frame_index, who)
    rows, start = select_rows(contacts, fi)
    check_contact_rows(contacts, rows, who)
    cu, cv, qa, qb, qc = patch_ellipses(
        surface,
        np.asarray(contacts.point_m, dtype=np.float64)[rows],
        np.asarray(contacts.normal, dtype=np.float64)[rows],
        np.asarray(contacts.patch_radius_m, dtype=np.float64)[rows],
        (h, w),
    )
    values = rasterize(
        start, cu, cv, qa, qb, qc, (h, w), row_offsets(layout.uv, (h, w)), surface.wrap_v, subsamples, binary, threshold
    )
    return make_frames(values, layout, surface)


class EllipseEncoder(Configured):
    """``encoder=ellipse``: contact patches as chart ellipses on the taxel grid."""

    VERSION = "1"

    SCHEMA = EllipseEncoderSchema
    binary: bool  # these three set from SCHEMA by Configured
    threshold: float
    subsamples: int

    def encode(
        self, contacts: Contacts, link: Link, surface: SurfaceMap, layout: Layout, frame_index: np.ndarray
    ) -> Frames:
        """Readings (M, H*W) for the M global frames in ``frame_index``."""
        return encode_grid(
            contacts, surface, layout, frame_index, self.binary, self.threshold, self.subsamples, "encoder=ellipse"
        )
