"""``surface=box``: the link's oriented bounding box, unfolded into a net.

For flat-ish links such as a torso. The box axes are sorted by extent
(a0 longest). The four faces around a0 form a band (u along a0, v around it,
wrapping); the two end caps hang above and below the +a2 face, so the net is
``U = e0 + 2 e2`` metres tall and ``P = 2 (e1 + e2)`` metres around, one
metric scale in each direction. Chart cells outside every face are void
(``charts.from_uv(..., return_valid=True)``). A mesh point maps to the face
it projects onto (largest normalized box coordinate).
"""

from __future__ import annotations

import logging

import numpy as np
import trimesh

from sphri.config import Configured
from sphri.geometry.link import check_link, sample_surface
from sphri.surface.charts import primitive_distance
from sphri.surface.schema import BoxSurfaceSchema
from sphri.types import Link, SurfaceMap

log = logging.getLogger(__name__)


def fit_box(link: Link, n_samples: int = 20000, seed: int = 0, warn_residual_mm: float = 25.0) -> SurfaceMap:
    """Fit the minimum-volume oriented bounding box of ``link`` -> its chart."""
    check_link(link)
    used = np.asarray(link.vertices, dtype=np.float64)[np.unique(np.asarray(link.faces))]
    to_origin, _ = trimesh.bounds.oriented_bounds(used)
    rot = np.asarray(to_origin[:3, :3], dtype=np.float64)  # rows: box axes in link frame
    local = used @ rot.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    ext = hi - lo
    order = np.argsort(ext)[::-1]
    rot, ext = rot[order], ext[order]
    centre = (0.5 * (lo + hi))[order] @ rot
    for i in range(2):  # deterministic signs: largest component positive
        if rot[i][np.argmax(np.abs(rot[i]))] < 0:
            rot[i] = -rot[i]
    rot[2] = np.cross(rot[0], rot[1])  # right-handed
    if ext[2] <= 1e-9:
        ext = ext.copy()
        ext[2] = 1e-9
        log.warning("surface.box on link %r: the mesh is flat; box thickness set to 1 nm", link.name)
    if ext[0] <= 1e-6:
        raise ValueError(f"link {link.name!r}: zero extent for surface=box")
    e0, e1, e2 = ext
    params = {
        "centre": centre,
        "rotation": rot,
        "extents": ext,
        "U": float(e0 + 2 * e2),
        "P": float(2 * (e1 + e2)),
    }
    sm = SurfaceMap("box", True, params["U"], params["P"], True, 0.0, params)
    pts, _ = sample_surface(link, n_samples, seed)
    residual = float(np.sqrt(np.mean(primitive_distance(sm, pts) ** 2)))
    notes = []
    if residual * 1e3 > warn_residual_mm:
        notes.append(
            f"poor box fit: RMS residual {residual * 1e3:.2f} mm > surface.warn_residual_mm={warn_residual_mm:g}"
        )
        log.warning("surface.box on link %r: %s", link.name, notes[-1])
    params["notes"] = tuple(notes)
    return SurfaceMap(
        kind="box",
        has_uv=True,
        metres_per_u=params["U"],
        metres_per_v=params["P"],
        wrap_v=True,
        fit_residual_m=residual,
        params=params,
    )


class BoxSurface(Configured):
    """``surface=box``: oriented bounding box net (band around the long axis + caps)."""

    VERSION = "1"

    SCHEMA = BoxSurfaceSchema
    n_samples: int  # these three set from SCHEMA by Configured
    seed: int
    warn_residual_mm: float

    def fit(self, link: Link) -> SurfaceMap:
        """Fit the box to ``link`` -> its chart."""
        return fit_box(link, self.n_samples, self.seed, self.warn_residual_mm)
