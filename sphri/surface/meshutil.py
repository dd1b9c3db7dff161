"""Mesh helpers shared by surfaces, layouts and encoders.

Validation of a :class:`~sphri.types.Link`, area-weighted surface sampling,
face normals, and projection of points onto the mesh along a direction (rays,
Embree via ``embreex`` when available) with a closest-point fallback.
trimesh is imported by the functions that use it (a cached run imports this
module for its array helpers and never pays trimesh's import).
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from sphri.types import Link

if TYPE_CHECKING:
    import trimesh

log = logging.getLogger(__name__)


def check_link(link: Link) -> None:
    """Raise ``ValueError`` naming the link when its mesh is unusable."""
    v = np.asarray(link.vertices)
    f = np.asarray(link.faces)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
        raise ValueError(f"link {link.name!r}: vertices must be (V>=3, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 1:
        raise ValueError(f"link {link.name!r}: faces must be (F>=1, 3), got {f.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"link {link.name!r}: vertices contain NaN or inf")
    if f.min() < 0 or f.max() >= v.shape[0]:
        raise ValueError(f"link {link.name!r}: face indices out of range [0, {v.shape[0]})")
    if face_areas(link).sum() <= 0:
        raise ValueError(f"link {link.name!r}: mesh has zero surface area")


def to_trimesh(link: Link) -> trimesh.Trimesh:
    """The link as a ``trimesh.Trimesh`` with the same face order (no processing)."""
    import trimesh

    return trimesh.Trimesh(
        vertices=np.asarray(link.vertices, dtype=np.float64),
        faces=np.asarray(link.faces, dtype=np.int64),
        process=False,
        validate=False,
    )


def triangle_normals_areas(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3) float64 unit normals by the right-hand rule (zero for degenerate faces) and (F,) areas in m^2.

    The one definition of face normals and areas: :func:`face_normals`,
    :func:`face_areas` and mesh validation (``sphri.robots.validate``) use it.
    """
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    c = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = np.linalg.norm(c, axis=1)
    unit = np.divide(c, n[:, None], out=np.zeros_like(c), where=n[:, None] > 0)
    return unit, 0.5 * n


def face_areas(link: Link) -> np.ndarray:
    """(F,) float64 triangle areas in m^2."""
    return triangle_normals_areas(link.vertices, link.faces)[1]


def face_normals(link: Link) -> np.ndarray:
    """(F, 3) float64 unit normals from the winding (zero for degenerate faces)."""
    return triangle_normals_areas(link.vertices, link.faces)[0]


#: Triangles of at most this area (m^2) are numerically degenerate: never sampled.
DEGENERATE_AREA_M2 = 5e-15


def sample_surface(link: Link, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted uniform samples of the surface: the one surface sampler (surfaces, layouts, data).

    Returns ``points (n, 3)`` metres and ``face (n,)`` int64 triangle index.
    Deterministic given ``seed``. Degenerate triangles
    (:data:`DEGENERATE_AREA_M2`) are never drawn.
    """
    areas = face_areas(link)
    areas = np.where(areas > DEGENERATE_AREA_M2, areas, 0.0)
    total = areas.sum()
    if total <= 0:
        raise ValueError(f"link {link.name!r}: mesh has zero surface area")
    rng = np.random.default_rng(seed)
    face = rng.choice(areas.size, size=n, p=areas / total)
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    tri = np.asarray(link.vertices, dtype=np.float64)[np.asarray(link.faces)[face]]
    pts = (1 - r1)[:, None] * tri[:, 0] + (r1 * (1 - r2))[:, None] * tri[:, 1] + (r1 * r2)[:, None] * tri[:, 2]
    return pts, face.astype(np.int64)


def principal_axes(points: np.ndarray, centre: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centroid (3,), eigenvalues (3,) descending (m^2) and axes (3, 3) as rows (largest component positive).

    ``centre``: the point the spread is measured about (default: the points' mean).
    """
    c = points.mean(axis=0) if centre is None else np.asarray(centre, dtype=np.float64)
    d = points - c
    cov = d.T @ d / len(d)
    w, vecs = np.linalg.eigh(cov)
    order = np.argsort(w)[::-1]
    axes = vecs[:, order].T.copy()
    for i in range(3):  # deterministic sign: largest component positive
        if axes[i][np.argmax(np.abs(axes[i]))] < 0:
            axes[i] = -axes[i]
    return c, w[order], axes


def project_along(
    link: Link,
    points: np.ndarray,
    directions: np.ndarray,
    max_dist_m: float,
    use_embree: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Move each point onto the mesh along the line through it with ``directions``.

    Rays are cast both ways from every point; the hit nearest to the point
    (within ``max_dist_m``) wins. Points whose line misses the mesh fall back
    to the closest surface point. Returns ``position (K, 3)``, ``face (K,)``
    and ``hit (K,) bool`` (False = closest-point fallback).
    """
    points = np.asarray(points, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    k = points.shape[0]
    mesh = to_trimesh(link)
    if use_embree:
        caster = mesh.ray
    else:
        from trimesh.ray.ray_triangle import RayMeshIntersector

        caster = RayMeshIntersector(mesh)
    best = np.full(k, np.inf)
    pos = points.copy()
    face = np.full(k, -1, dtype=np.int64)
    for sign in (1.0, -1.0):
        origins = points - sign * d * max_dist_m
        dirs = sign * d
        loc, ray, tri = caster.intersects_location(origins, dirs, multiple_hits=True)
        if len(ray) == 0:
            continue
        dist = np.linalg.norm(loc - points[ray], axis=1)
        ok = dist <= max_dist_m
        loc, ray, tri, dist = loc[ok], ray[ok], tri[ok], dist[ok]
        order = np.lexsort((dist, ray))
        loc, ray, tri, dist = loc[order], ray[order], tri[order], dist[order]
        first = np.unique(ray, return_index=True)[1]
        r, dd = ray[first], dist[first]
        better = dd < best[r]
        r = r[better]
        best[r] = dd[better]
        pos[r] = loc[first][better]
        face[r] = tri[first][better]
    hit = np.isfinite(best)
    if not hit.all():
        import trimesh

        miss = ~hit
        cp, _, tri = trimesh.proximity.closest_point(mesh, points[miss])
        pos[miss] = cp
        face[miss] = tri
    return pos, face, hit


def closest_points(link: Link, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest surface point, its distance (m) and triangle for each of (K, 3) points."""
    import trimesh

    mesh = to_trimesh(link)
    cp, dist, tri = trimesh.proximity.closest_point(mesh, np.asarray(points, dtype=np.float64))
    return cp, dist, tri.astype(np.int64)


def link_from_trimesh(mesh: trimesh.Trimesh, name: str = "link") -> Link:
    """A :class:`~sphri.types.Link` from a trimesh mesh (metres, link frame), for tests and scripts."""
    return Link(
        name=name,
        vertices=np.asarray(mesh.vertices, dtype=np.float64),
        faces=np.asarray(mesh.faces, dtype=np.int64),
        watertight=bool(mesh.is_watertight),
    )
