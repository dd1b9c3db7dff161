"""The paper's surface: a cylinder fitted to the link, u = h along it, v = a around.

Fit: area-weighted surface samples; candidate axes from PCA (or a fixed link
axis); per candidate a least-squares circle (centre, radius) on the samples
whose normals are not along the axis, optionally refining the axis direction;
the candidate with the smallest RMS distance to the closed finite cylinder
wins (so short, disc-like links get their axis right). The axial extent is the
mesh's own extent along the axis. Poor fits are logged with their residual in
mm.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from sphri.config import Configured
from sphri.geometry.link import check_link, geometry_of
from sphri.surface.charts import primitive_distance
from sphri.surface.schema import CylinderSurfaceSchema
from sphri.types import Link, SurfaceMap

log = logging.getLogger(__name__)

_LINK_AXES = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}
_MAX_FIT_POINTS = 4000


def _basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``axis`` to an orthonormal frame."""
    helper = np.array([1.0, 0, 0]) if abs(axis[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def _circle_fit(xy: np.ndarray) -> tuple[float, float, float]:
    """Algebraic (Kasa) circle fit: centre (cx, cy) and radius, metres."""
    a = np.column_stack([xy, np.ones(len(xy))])
    b = -(xy**2).sum(axis=1)
    (d, e, f), *_ = np.linalg.lstsq(a, b, rcond=None)
    cx, cy = -d / 2, -e / 2
    r2 = cx * cx + cy * cy - f
    return float(cx), float(cy), float(np.sqrt(max(r2, 1e-12)))


def _fit_for_axis(
    pts: np.ndarray, nrm: np.ndarray, axis0: np.ndarray, refine: bool
) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares cylinder around an initial axis: (point on axis, axis, radius)."""
    lateral = np.abs(nrm @ axis0) < 0.7
    # a short (disc-like) link has few side points for its true axis, yet enough to fit its circle:
    # falling back to every point there fits a huge circle to the flat faces instead
    use = pts[lateral] if lateral.sum() >= max(30, 0.01 * len(pts)) else pts
    if len(use) > _MAX_FIT_POINTS:
        use = use[np.linspace(0, len(use) - 1, _MAX_FIT_POINTS).astype(int)]
    m = use.mean(axis=0)
    e1, e2 = _basis(axis0)
    rel = use - m
    cx, cy, r = _circle_fit(np.column_stack([rel @ e1, rel @ e2]))
    if not refine:
        return m + cx * e1 + cy * e2, axis0, r

    def unpack(x):
        a = axis0 + x[0] * e1 + x[1] * e2
        a = a / np.linalg.norm(a)
        return m + x[2] * e1 + x[3] * e2, a, x[4]

    def resid(x):
        c, a, rr = unpack(x)
        w = use - c
        radial = w - np.outer(w @ a, a)
        return np.linalg.norm(radial, axis=1) - rr

    sol = least_squares(resid, np.array([0.0, 0.0, cx, cy, r]), method="lm", max_nfev=200)
    c, a, rr = unpack(sol.x)
    if not np.all(np.isfinite(sol.x)) or rr <= 0 or abs(a @ axis0) < 0.9:
        return m + cx * e1 + cy * e2, axis0, r  # refinement diverged: keep the PCA axis
    return c, a, float(rr)


def fit_cylinder(
    link: Link,
    axis: str = "auto",
    refine_axis: bool = True,
    seam: tuple[float, float, float] | list[float] = (1.0, 0.0, 0.0),
    n_samples: int = 20000,
    seed: int = 0,
    warn_residual_mm: float = 6.0,
) -> SurfaceMap:
    """Fit a cylinder to ``link`` and return its chart (see module docstring)."""
    check_link(link)
    geom = geometry_of(link)
    pts, face = geom.sample(n_samples, seed)
    nrm = geom.face_normals[face]
    centroid, eig, pca = geom.axes(n_samples, seed)
    notes: list[str] = []
    if axis == "auto":
        candidates = [pca[0], pca[1], pca[2]]
    else:
        candidates = [_LINK_AXES[axis]]
    used_vertices = geom.used_vertices

    fits = []
    for a0 in candidates:
        c, a, r = _fit_for_axis(pts, nrm, a0, refine_axis)
        if a[np.argmax(np.abs(a))] < 0:
            a = -a
        t = (used_vertices - c) @ a
        params = _params(c, a, r, float(t.min()), float(t.max()), seam)
        sm = SurfaceMap("cylinder", True, 1.0, 1.0, True, 0.0, params)
        res = float(np.sqrt(np.mean(primitive_distance(sm, pts) ** 2)))
        fits.append((res, params))
    best = 0
    for i in range(1, len(fits)):
        if fits[i][0] < 0.8 * fits[best][0]:
            best = i
    residual, params = fits[best]
    if axis == "auto" and best != 0:
        notes.append(f"axis is PCA component {best} (not the largest-variance one): a short, disc-like link")
    if eig[2] > 0 and eig[0] / eig[2] < 1.3:
        notes.append(
            f"link {link.name!r} is nearly spherical (PCA variances {np.round(eig * 1e6, 2).tolist()} mm^2): "
            "the cylinder axis is ill-defined"
        )
    length = params["u_max"] - params["u_min"]
    if length <= 1e-6:
        raise ValueError(f"link {link.name!r}: zero extent along the fitted cylinder axis")
    if length < params["radius"]:
        notes.append(f"short link: length {length * 1e3:.1f} mm < radius {params['radius'] * 1e3:.1f} mm")
    if residual * 1e3 > warn_residual_mm:
        notes.append(
            f"poor cylinder fit: RMS residual {residual * 1e3:.2f} mm > surface.warn_residual_mm={warn_residual_mm:g}; "
            "taxel pitches and areas on this link are approximate: for a link that is not a tube use "
            "surface=box (flat faces) or surface=mesh with layout=random|density (no chart)"
        )
    for n in notes:
        log.warning("surface.cylinder on link %r: %s", link.name, n)
    params["notes"] = tuple(notes)
    params["pca_variance_m2"] = eig
    return SurfaceMap(
        kind="cylinder",
        has_uv=True,
        metres_per_u=float(length),
        metres_per_v=float(2.0 * np.pi * params["radius"]),
        wrap_v=True,
        fit_residual_m=residual,
        params=params,
    )


def _params(c: np.ndarray, a: np.ndarray, r: float, t0: float, t1: float, seam) -> dict[str, Any]:
    # Origin on the axis at the middle of the extent; u_min/u_max relative to it.
    mid = 0.5 * (t0 + t1)
    origin = c + mid * a
    ref = None
    for cand in (np.asarray(seam, dtype=np.float64), np.array([1.0, 0, 0]), np.array([0, 1.0, 0])):
        cand = cand / np.linalg.norm(cand)
        perp = cand - (cand @ a) * a
        if np.linalg.norm(perp) > 0.1:
            ref = perp / np.linalg.norm(perp)
            break
    assert ref is not None
    return {
        "origin": origin,
        "axis": a,
        "radius": float(r),
        "u_min": float(t0 - mid),
        "u_max": float(t1 - mid),
        "ref": ref,
        "binormal": np.cross(a, ref),
    }


class CylinderSurface(Configured):
    """``surface=cylinder``: the paper's fitted cylinder, (u, v) = (h, a)."""

    VERSION = "2"

    SCHEMA = CylinderSurfaceSchema
    axis: str  # these six set from SCHEMA by Configured
    refine_axis: bool
    seam: list[float]
    n_samples: int
    seed: int
    warn_residual_mm: float

    def configured(self) -> None:
        self.seam = [float(s) for s in self.seam]

    def fit(self, link: Link) -> SurfaceMap:
        """Fit the cylinder to ``link`` (metres, link frame) -> its chart."""
        return fit_cylinder(
            link, self.axis, self.refine_axis, self.seam, self.n_samples, self.seed, self.warn_residual_mm
        )
