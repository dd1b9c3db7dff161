"""Ray casting on link meshes: Embree (float32, fast) refined in float64.

Rays are the right tool for projecting points onto a mesh along a direction
and for parity inside tests of closed meshes; the exact contact kernel
needs neither (its distances must hold to 1e-9 m, beyond float32). Embree
(``embreex`` through trimesh) finds the first triangle a ray hits; the hit
is then recomputed in float64 on that triangle (Moller-Trumbore), so hit
points are exact for the triangle Embree chose. Near shared edges Embree
may choose a neighbour of the triangle float64 would choose; the hit point
is the same to float32 precision. ``engine="triangle"`` uses trimesh's pure
numpy ``ray_triangle`` instead (slow, float64 throughout): the tests check
the two against each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from sphri.geometry.link import geometry_of_arrays

#: Directions (unit, irrational components) of the parity rays of :func:`inside_by_rays`.
PARITY_DIRECTIONS = np.array(
    [
        [0.5773502691896258, 0.5773502691896257, 0.5773502691896259],
        [-0.2672612419124244, 0.5345224838248488, -0.8017837257372732],
        [0.8728715609439696, -0.2182178902359924, -0.4364357804719848],
    ]
)

ENGINES: tuple[str, ...] = ("auto", "embree", "triangle")


@dataclass
class RayHits:
    """First hits of N rays (float64, world frame)."""

    triangle: np.ndarray
    """(N,) int64 face row hit first, -1 for a miss."""
    distance: np.ndarray
    """(N,) float64 distance along the (unit) ray direction, inf for a miss."""
    point: np.ndarray
    """(N, 3) float64 hit point (NaN for a miss)."""
    barycentric: np.ndarray
    """(N, 3) float64 barycentric coordinates of the hit in its triangle."""


def has_embree() -> bool:
    """Whether trimesh can use Embree (the ``embreex`` package)."""
    return bool(getattr(trimesh.ray, "has_embree", False))


def _intersector(vertices: np.ndarray, faces: np.ndarray, engine: str):
    """The mesh's intersector for ``engine``, kept on its geometry (:func:`sphri.geometry.link.geometry_of_arrays`)."""
    if engine not in ENGINES:
        raise ValueError(f"engine={engine!r} is invalid: allowed values: {list(ENGINES)}")
    if engine == "auto":
        engine = "embree" if has_embree() else "triangle"
    if engine == "embree" and not has_embree():
        raise RuntimeError("engine='embree' needs the embreex package (pip install embreex)")
    return geometry_of_arrays(vertices, faces).intersector(engine)


def _unit(d: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(d, axis=1, keepdims=True)
    if not (n > 0).all():
        raise ValueError("ray directions must be non-zero")
    return d / n


def ray_triangle_f64(origins, directions, a, b, c):
    """Float64 Moller-Trumbore of ray i with triangle (a[i], b[i], c[i]).

    Returns ``(t, bary)``: distance along the unit direction and barycentric
    coordinates of the hit in the triangle's plane (t = NaN when parallel).
    """
    e1 = b - a
    e2 = c - a
    p = np.cross(directions, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = origins - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", directions, q) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
    t = np.where(det != 0, t, np.nan)
    return t, np.stack([1.0 - u - v, u, v], axis=1)


def first_hits(vertices, faces, origins, directions, engine: str = "auto") -> RayHits:
    """First triangle hit by each ray, refined in float64 (see the module docstring).

    ``origins`` (N, 3) metres; ``directions`` (N, 3), normalized here.
    This is also how to project points onto a mesh along directions.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = _unit(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
    n = o.shape[0]
    tri = np.full(n, -1, dtype=np.int64)
    dist = np.full(n, np.inf)
    point = np.full((n, 3), np.nan)
    bary = np.full((n, 3), np.nan)
    if n == 0:
        return RayHits(tri, dist, point, bary)
    rmi = _intersector(v, f, engine)
    idx_tri, idx_ray = rmi.intersects_id(o, d, multiple_hits=False)[:2]
    idx_tri = np.asarray(idx_tri, dtype=np.int64)
    idx_ray = np.asarray(idx_ray, dtype=np.int64)
    if idx_ray.size:
        t, bc = ray_triangle_f64(o[idx_ray], d[idx_ray], v[f[idx_tri, 0]], v[f[idx_tri, 1]], v[f[idx_tri, 2]])
        tri[idx_ray] = idx_tri
        dist[idx_ray] = t
        point[idx_ray] = o[idx_ray] + t[:, None] * d[idx_ray]
        bary[idx_ray] = bc
    return RayHits(tri, dist, point, bary)


def inside_by_rays(vertices, faces, points, engine: str = "auto") -> np.ndarray:
    """(P,) bool: majority vote of crossing parity along :data:`PARITY_DIRECTIONS`.

    Meaningful for closed meshes only (an open mesh leaks); used to
    cross-check the ``hull`` and ``winding`` inside definitions.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rmi = _intersector(v, f, engine)
    votes = np.zeros(pts.shape[0], dtype=np.int64)
    for d in PARITY_DIRECTIONS:
        dirs = np.broadcast_to(d, pts.shape).copy()
        idx_tri, idx_ray = rmi.intersects_id(pts, dirs, multiple_hits=True)[:2]
        counts = np.bincount(np.asarray(idx_ray, dtype=np.int64), minlength=pts.shape[0])
        votes += counts % 2
    return votes >= 2
