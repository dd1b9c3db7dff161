"""``encoder=coverage``: the fraction of each taxel's area covered by contact (float32).

Grid layouts on a chart use the ellipse raster in coverage mode (union of the
patches' chart ellipses, exact along v). Any other layout (random, density,
file, or no chart) represents each taxel by ``samples_per_taxel`` points on
the disc of its area in its tangent plane; a point is covered when it lies
within a patch's radius of the patch centre and the taxel faces the patch's
side of the link. Readings are the covered fraction of those points.
"""

from __future__ import annotations

import numpy as np

from sphri.config import Configured
from sphri.encode.common import check_frame_index, make_frames, select_rows, tangent_basis
from sphri.encode.ellipse import check_contact_rows, encode_grid
from sphri.encode.schema import CoverageEncoderSchema
from sphri.encode.spatial import VoxelHash, coverage_kernel, sunflower_disc, voxel_size
from sphri.layout.common import nn_spacing
from sphri.types import Contacts, Frames, Layout, Link, SurfaceMap


def taxel_samples(layout: Layout, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, n, 3) points on each taxel's disc (radius sqrt(area/pi)) and the radii (N,) in metres."""
    r = np.sqrt(np.maximum(np.asarray(layout.area_m2, dtype=np.float64), 0.0) / np.pi)
    e1, e2 = tangent_basis(np.asarray(layout.normal, dtype=np.float64))
    disc = sunflower_disc(n)
    pts = layout.position_m[:, None, :] + r[:, None, None] * (
        disc[None, :, 0, None] * e1[:, None, :] + disc[None, :, 1, None] * e2[:, None, :]
    )
    return pts, r


def encode_3d_coverage(
    contacts: Contacts, surface: SurfaceMap, layout: Layout, frame_index: np.ndarray, samples_per_taxel: int, who: str
) -> Frames:
    """Coverage readings (M, N) float32 on any layout, from 3-D taxel discs."""
    fi = check_frame_index(contacts, frame_index, who)
    rows, start = select_rows(contacts, fi)
    check_contact_rows(contacts, rows, who)
    m, n = len(fi), layout.n_taxels
    out = np.zeros((m, n), dtype=np.float32)
    if rows.size == 0 or n == 0:
        return make_frames(out, layout, surface)
    pts, r = taxel_samples(layout, samples_per_taxel)
    spacing = float(np.median(nn_spacing(layout.position_m))) if n > 1 else 0.01
    vh = VoxelHash(layout.position_m, voxel_size(layout.position_m, spacing))
    coverage_kernel(
        start,
        np.ascontiguousarray(np.asarray(contacts.point_m, dtype=np.float64)[rows]),
        np.ascontiguousarray(np.asarray(contacts.normal, dtype=np.float64)[rows]),
        np.ascontiguousarray(np.asarray(contacts.patch_radius_m, dtype=np.float64)[rows]),
        np.ascontiguousarray(layout.position_m, dtype=np.float64),
        np.ascontiguousarray(layout.normal, dtype=np.float64),
        r,
        np.ascontiguousarray(pts),
        vh.origin,
        vh.cell_m,
        vh.dims,
        vh.start,
        vh.order,
        out,
        int(min(max(1, m // 256), 64)),
    )
    return make_frames(out, layout, surface)


class CoverageEncoder(Configured):
    """``encoder=coverage``: covered fraction of each taxel (float32), any layout."""

    VERSION = "1"

    SCHEMA = CoverageEncoderSchema
    subsamples: int  # these two set from SCHEMA by Configured
    samples_per_taxel: int

    def encode(
        self, contacts: Contacts, link: Link, surface: SurfaceMap, layout: Layout, frame_index: np.ndarray
    ) -> Frames:
        """Readings (M, N) float32 in [0, 1] for the M global frames in ``frame_index``."""
        who = "encoder=coverage"
        if layout.grid_shape is not None and layout.uv is not None and surface.has_uv:
            return encode_grid(contacts, surface, layout, frame_index, False, 0.5, self.subsamples, who)
        return encode_3d_coverage(contacts, surface, layout, frame_index, self.samples_per_taxel, who)
