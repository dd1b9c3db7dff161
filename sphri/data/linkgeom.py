"""Where on a link the synthetic hand may touch: surface samples, axes and local frames.

:class:`LinkSurface` takes the link's samples, normals and areas from its
geometry (:func:`sphri.geometry.geometry_of`: area-weighted, fixed seed so
it never depends on the data seed), finds its principal axes (the
long axis is the direction of largest spread) and answers the generator's
questions: sample a touch point near a preferred place, give the local frame
there (outward normal, the long axis in the tangent plane), project points
onto the surface and measure the surface's height along a slide.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sphri.geometry.link import DEGENERATE_AREA_M2, geometry_of, principal_axes
from sphri.types import Link


class LinkSurface:
    """Surface samples of one link with their outward normals (metres, link frame).

    On a mesh that is not watertight (the study's convex hulls) the faces'
    winding is trusted only where the normal points away from the centroid;
    samples on inward-facing faces are left out.
    """

    def __init__(self, link: Link, n_samples: int = 20000, seed: int = 12345):
        v = np.asarray(link.vertices)
        f = np.asarray(link.faces)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise ValueError(f"link {link.name!r}: needs (V, 3) vertices and (F, 3) faces, got {v.shape}, {f.shape}")
        geom = geometry_of(link)
        v, f = geom.vertices, geom.faces
        unit, area = geom.face_normals, geom.face_areas
        usable = area > DEGENERATE_AREA_M2
        if not usable.any():
            from sphri.robots.validate import MeshError

            raise MeshError(
                f"link {link.name!r}: no usable outward surface to place hands on "
                "(0 non-degenerate faces); a link needs a 3-D surface"
            )
        pts, face = geom.sample(n_samples, seed)
        nrm = unit[face]
        if link.watertight and np.einsum("ij,ij->i", v[f[usable, 0]], unit[usable]) @ area[usable] < 0:
            nrm = -nrm  # wound inwards: the signed volume is negative
        self.area_m2 = float(area[usable].sum())
        self.centroid = pts.mean(axis=0)
        if not link.watertight:
            keep = np.einsum("ij,ij->i", nrm, pts - self.centroid) > 0
            pts, nrm = pts[keep], nrm[keep]
        self.name = link.name
        self.points = pts
        self.normals = nrm
        if len(pts) < 3 or not np.isfinite(pts).all():
            from sphri.robots.validate import MeshError

            raise MeshError(
                f"link {link.name!r}: no usable outward surface to place hands on "
                f"({int(usable.sum())} non-degenerate face(s)); a link needs a 3-D surface"
            )
        # principal axes of the surface samples: long axis first, right-handed
        _, _, axes = principal_axes(pts, centre=self.centroid)
        axes[2] = np.cross(axes[0], axes[1])
        d = pts - self.centroid
        self.axes = axes
        self.long_axis = axes[0]
        self.axial = d @ axes[0]
        self.axial_range = (float(self.axial.min()), float(self.axial.max()))
        self.angle = np.arctan2(d @ axes[2], d @ axes[1])
        radial = d - self.axial[:, None] * axes[0]
        self.radius = np.linalg.norm(radial, axis=1)
        self.tree = cKDTree(pts)
        """KD-tree of :attr:`points` (the outward samples kept here)."""

    @property
    def length_m(self) -> float:
        """Extent of the link along its long axis (metres)."""
        return self.axial_range[1] - self.axial_range[0]

    def preference(self, axial_frac: float, axial_sd: float, angle: float, angle_kappa: float) -> np.ndarray:
        """(S,) log-weights of the samples for a preferred place.

        ``axial_frac`` in [0, 1] along the long axis with SD ``axial_sd``
        (fraction of the length); ``angle`` (radians) around the long axis
        with von Mises concentration ``angle_kappa``. End caps (normal within
        50 degrees of the long axis) get weight 0.
        """
        lo, hi = self.axial_range
        frac = (self.axial - lo) / (hi - lo)
        logw = -0.5 * ((frac - axial_frac) / max(axial_sd, 1e-3)) ** 2 + angle_kappa * (
            np.cos(self.angle - angle) - 1.0
        )
        side = np.abs(self.normals @ self.long_axis) < 0.64
        return np.where(side, logw, -np.inf) if side.any() else logw

    def sampler(self, logw: np.ndarray) -> PlaceSampler:
        """A fast sampler of touch points with log-weights ``logw`` (:meth:`preference`)."""
        return PlaceSampler(self, logw)

    def frame_at(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(point, normal n, t1 (long axis in the tangent plane), t2 = n x t1) at sample ``i``."""
        p, n = self.points[i], self.normals[i]
        a = self.long_axis - (self.long_axis @ n) * n
        if np.linalg.norm(a) < 1e-6:
            a = self.axes[1] - (self.axes[1] @ n) * n
        t1 = a / np.linalg.norm(a)
        t2 = np.array([n[1] * t1[2] - n[2] * t1[1], n[2] * t1[0] - n[0] * t1[2], n[0] * t1[1] - n[1] * t1[0]])
        return p, n, t1, t2

    def project(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest surface samples to points ``q`` (..., 3): (points, normals)."""
        _, idx = self.tree.query(q)
        return self.points[idx], self.normals[idx]

    def height_profile(self, p: np.ndarray, n: np.ndarray, direction: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Surface height along ``n`` (metres, relative to ``p``) under ``p + s * direction`` for offsets ``s`` (K,)."""
        q = p[None, :] + np.asarray(s)[:, None] * direction[None, :]
        pts, _ = self.project(q)
        return (pts - p[None, :]) @ n


class PlaceSampler:
    """Draws sample indices with fixed weights, keeping a margin from the ends of the long axis.

    The samples are sorted by their axial coordinate once, so every draw is
    two binary searches whatever the margin.
    """

    def __init__(self, surface: LinkSurface, logw: np.ndarray):
        self.surface = surface
        self.order = np.argsort(surface.axial, kind="stable")
        self.axial = surface.axial[self.order]
        lw = np.asarray(logw, dtype=np.float64)[self.order]
        if not np.isfinite(lw).any():
            lw = np.zeros_like(lw)
        w = np.exp(lw - lw[np.isfinite(lw)].max())
        self.cdf = np.concatenate([[0.0], np.cumsum(w)])

    def draw(self, rng: np.random.Generator, margin_m: float = 0.0) -> int:
        """Index (into the surface's samples) of a point drawn by weight, never closer than
        ``margin_m`` to either end of the long axis (unless nothing else has weight)."""
        lo, hi = self.surface.axial_range
        i0 = int(np.searchsorted(self.axial, lo + margin_m, side="right"))
        i1 = int(np.searchsorted(self.axial, hi - margin_m, side="left"))
        if i1 <= i0 or self.cdf[i1] - self.cdf[i0] <= 0:
            i0, i1 = 0, len(self.axial)
        u = self.cdf[i0] + rng.random() * (self.cdf[i1] - self.cdf[i0])
        k = int(np.clip(np.searchsorted(self.cdf, u, side="right") - 1, i0, i1 - 1))
        return int(self.order[k])
