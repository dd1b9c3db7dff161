"""One link's mesh and what is derived from it: :class:`LinkGeometry`, built once per link by :func:`geometry_of`.

Face normals and areas, area-weighted surface samples, principal axes, the
trimesh mesh with its proximity tree and ray intersectors, and what the
layers above derive from the mesh (:meth:`LinkGeometry.derived`: the
coverage analysis' surface elements of :mod:`sphri.geometry.samples`, the
contact kernels' acceleration data) are computed on first use and kept on the link's geometry, so every stage that asks gets the
same arrays without recomputing them. The module-level functions
(:func:`face_normals`, :func:`sample_surface`, :func:`closest_points`, ...)
are the same answers for callers holding a :class:`~sphri.types.Link`.

trimesh (and Embree through ``embreex``) is imported by the methods that
use it: a cached run imports this module for its array helpers and never
pays trimesh's import.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from sphri.types import Link

if TYPE_CHECKING:
    import trimesh

log = logging.getLogger(__name__)

#: Triangles of at most this area (m^2) are numerically degenerate: never sampled.
DEGENERATE_AREA_M2 = 5e-15
#: Surface samples of at most this many points are kept per (n, seed) on the geometry (larger ones are drawn anew).
SAMPLE_CACHE_MAX_POINTS = 200_000
#: Entries of each per-link cache (samples, surface elements, derived structures): least recently used go first.
CACHE_ENTRIES = 8


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def triangle_normals_areas(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3) float64 unit normals by the right-hand rule (zero for degenerate faces) and (F,) areas in m^2.

    The one definition of face normals and areas: :class:`LinkGeometry` and
    mesh validation (``sphri.robots.validate``, on meshes that are not links yet) use it.
    """
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    c = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = np.linalg.norm(c, axis=1)
    unit = np.divide(c, n[:, None], out=np.zeros_like(c), where=n[:, None] > 0)
    return unit, 0.5 * n


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


class _Lru:
    """A small thread-safe LRU of derived values, built by a callable on a miss."""

    def __init__(self, size: int = CACHE_ENTRIES) -> None:
        self.size = size
        self.items: OrderedDict[Any, Any] = OrderedDict()
        self.lock = threading.Lock()

    def get(self, key: Any, build: Callable[[], Any]) -> Any:
        with self.lock:
            if key in self.items:
                self.items.move_to_end(key)
                return self.items[key]
        value = build()
        with self.lock:
            self.items[key] = value
            self.items.move_to_end(key)
            while len(self.items) > self.size:
                self.items.popitem(last=False)
        return value


class LinkGeometry:
    """A link's mesh (metres, link frame) and everything derived from it, each computed once on first use.

    Get it with :func:`geometry_of` (one per :class:`~sphri.types.Link`
    object, shared by every caller); the arrays it hands out are read-only.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, name: str = "link", watertight: bool = False) -> None:
        self.name = name
        self.watertight = bool(watertight)
        self.vertices = _frozen(np.array(vertices, dtype=np.float64))
        """(V, 3) float64 vertex positions."""
        self.faces = _frozen(np.array(faces, dtype=np.int64))
        """(F, 3) int64 vertex indices."""
        self._samples = _Lru()
        self._own = _Lru()  # axes and intersectors
        self._derived = _Lru()
        self._checked = False

    # ------------------------------------------------------------------ per face

    @cached_property
    def _normals_areas(self) -> tuple[np.ndarray, np.ndarray]:
        unit, area = triangle_normals_areas(self.vertices, self.faces)
        return _frozen(unit), _frozen(area)

    @property
    def face_normals(self) -> np.ndarray:
        """(F, 3) float64 unit normals from the winding (zero for degenerate faces)."""
        return self._normals_areas[0]

    @property
    def face_areas(self) -> np.ndarray:
        """(F,) float64 triangle areas in m^2."""
        return self._normals_areas[1]

    @cached_property
    def area_m2(self) -> float:
        """Total surface area (m^2)."""
        return float(self.face_areas.sum())

    def check(self) -> None:
        """Raise ``ValueError`` naming the link when its mesh is unusable (checked once)."""
        if self._checked:
            return
        v, f = self.vertices, self.faces
        if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 3:
            raise ValueError(f"link {self.name!r}: vertices must be (V>=3, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 1:
            raise ValueError(f"link {self.name!r}: faces must be (F>=1, 3), got {f.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"link {self.name!r}: vertices contain NaN or inf")
        if f.min() < 0 or f.max() >= v.shape[0]:
            raise ValueError(f"link {self.name!r}: face indices out of range [0, {v.shape[0]})")
        if self.face_areas.sum() <= 0:
            raise ValueError(f"link {self.name!r}: mesh has zero surface area")
        self._checked = True

    # ------------------------------------------------------------------ samples and axes

    def sample(self, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """Area-weighted uniform samples of the surface: ``points (n, 3)`` metres, ``face (n,)`` int64 triangle.

        Deterministic given ``seed``; degenerate triangles
        (:data:`DEGENERATE_AREA_M2`) are never drawn. Each call returns fresh
        (writable) arrays; draws of up to :data:`SAMPLE_CACHE_MAX_POINTS` are
        kept on the geometry.
        """
        if n > SAMPLE_CACHE_MAX_POINTS:
            return self._draw(n, seed)
        pts, face = self._samples.get((int(n), int(seed)), lambda: tuple(_frozen(a) for a in self._draw(n, seed)))
        return pts.copy(), face.copy()

    def _draw(self, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
        areas = self.face_areas
        areas = np.where(areas > DEGENERATE_AREA_M2, areas, 0.0)
        total = areas.sum()
        if total <= 0:
            raise ValueError(f"link {self.name!r}: mesh has zero surface area")
        rng = np.random.default_rng(seed)
        face = rng.choice(areas.size, size=n, p=areas / total)
        r1 = np.sqrt(rng.random(n))
        r2 = rng.random(n)
        tri = self.vertices[self.faces[face]]
        pts = (1 - r1)[:, None] * tri[:, 0] + (r1 * (1 - r2))[:, None] * tri[:, 1] + (r1 * r2)[:, None] * tri[:, 2]
        return pts, face.astype(np.int64)

    def axes(self, n: int = 20000, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`principal_axes` of ``n`` surface samples drawn with ``seed``: centroid, eigenvalues, axes (rows)."""

        def build() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            pts, _ = self.sample(n, seed)
            return tuple(_frozen(a) for a in principal_axes(pts))  # type: ignore[return-value]

        c, w, a = self._own.get(("axes", int(n), int(seed)), build)
        return c.copy(), w.copy(), a.copy()

    @cached_property
    def used_vertices(self) -> np.ndarray:
        """(U, 3) float64 the vertices some face uses (in index order)."""
        return _frozen(self.vertices[np.unique(self.faces)])

    # ------------------------------------------------------------------ search structures

    @cached_property
    def trimesh(self) -> trimesh.Trimesh:
        """The mesh as a ``trimesh.Trimesh`` with the same face order (no processing); its proximity tree and
        ray scene are built by trimesh on first use and kept with it."""
        import trimesh

        return trimesh.Trimesh(vertices=self.vertices.copy(), faces=self.faces.copy(), process=False, validate=False)

    def intersector(self, engine: str = "embree") -> Any:
        """A ray intersector of the mesh: ``"embree"`` (float32, ``embreex``) or ``"triangle"`` (numpy float64)."""

        def build() -> Any:
            if engine == "embree":
                from trimesh.ray.ray_pyembree import RayMeshIntersector

                return RayMeshIntersector(self.trimesh, scale_to_box=True)
            if engine == "triangle":
                from trimesh.ray.ray_triangle import RayMeshIntersector as Triangle

                return Triangle(self.trimesh)
            raise ValueError(f"engine={engine!r} is invalid: allowed values: ['embree', 'triangle']")

        return self._own.get(("intersector", engine), build)

    def derived(self, key: Any, build: Callable[[], Any]) -> Any:
        """A value a higher layer derives from this mesh (e.g. contact acceleration data), built once per ``key``."""
        return self._derived.get(key, build)

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest surface point, its distance (m) and triangle for each of (K, 3) points."""
        import trimesh

        cp, dist, tri = trimesh.proximity.closest_point(self.trimesh, np.asarray(points, dtype=np.float64))
        return cp, dist, tri.astype(np.int64)

    def project_along(
        self, points: np.ndarray, directions: np.ndarray, max_dist_m: float, use_embree: bool = True
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
        caster = self.trimesh.ray if use_embree else self.intersector("triangle")
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
            miss = ~hit
            cp, _, tri = self.closest_points(points[miss])
            pos[miss] = cp
            face[miss] = tri
        return pos, face, hit


_GEOMETRIES: dict[int, tuple[weakref.ref, LinkGeometry]] = {}
_BY_CONTENT = _Lru(16)
_LOCK = threading.Lock()


def _forget(key: int) -> None:
    with _LOCK:
        _GEOMETRIES.pop(key, None)


def _content_key(vertices: np.ndarray, faces: np.ndarray, name: str, watertight: bool) -> tuple:
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    h = hashlib.blake2b(digest_size=16)
    h.update(v.tobytes())
    h.update(f.tobytes())
    return (h.hexdigest(), v.shape, f.shape, name, bool(watertight))


def geometry_of_arrays(
    vertices: np.ndarray, faces: np.ndarray, name: str = "mesh", watertight: bool = False
) -> LinkGeometry:
    """The :class:`LinkGeometry` of a mesh given as arrays, shared by content (the bytes of the mesh, its name
    and closedness; the 16 most recently used are kept): one hash per call."""
    v, f = np.asarray(vertices), np.asarray(faces)
    return _BY_CONTENT.get(_content_key(v, f, name, watertight), lambda: LinkGeometry(v, f, name, watertight))


def geometry_of(link: Link) -> LinkGeometry:
    """The :class:`LinkGeometry` of ``link``: built on the first call, the same object for every later one while
    ``link`` lives (links are immutable), and for a link with the same mesh, name and closedness built since
    (e.g. the robot loaded again by the next job of a sweep; see :func:`geometry_of_arrays`)."""
    key = id(link)
    with _LOCK:
        hit = _GEOMETRIES.get(key)
        if hit is not None and hit[0]() is link:
            return hit[1]
    v, f = np.asarray(link.vertices), np.asarray(link.faces)
    if v.ndim == 2 and f.ndim == 2:
        geom = geometry_of_arrays(v, f, link.name, link.watertight)
    else:  # malformed: not shared, check() names the problem
        geom = LinkGeometry(v, f, name=link.name, watertight=link.watertight)
    with _LOCK:
        hit = _GEOMETRIES.get(key)
        if hit is not None and hit[0]() is link:
            return hit[1]
        _GEOMETRIES[key] = (weakref.ref(link, lambda _ref: _forget(key)), geom)
    return geom


# ---------------------------------------------------------------------- the same answers for a Link


def check_link(link: Link) -> None:
    """Raise ``ValueError`` naming the link when its mesh is unusable (:meth:`LinkGeometry.check`)."""
    geometry_of(link).check()


def face_areas(link: Link) -> np.ndarray:
    """(F,) float64 triangle areas in m^2 (read-only, shared: :attr:`LinkGeometry.face_areas`)."""
    return geometry_of(link).face_areas


def face_normals(link: Link) -> np.ndarray:
    """(F, 3) float64 unit normals from the winding, zero for degenerate faces (read-only, shared)."""
    return geometry_of(link).face_normals


def sample_surface(link: Link, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted uniform samples of the surface: the one surface sampler (:meth:`LinkGeometry.sample`)."""
    return geometry_of(link).sample(n, seed)


def to_trimesh(link: Link) -> trimesh.Trimesh:
    """The link as a ``trimesh.Trimesh`` with the same face order (no processing; shared, do not modify)."""
    return geometry_of(link).trimesh


def project_along(
    link: Link, points: np.ndarray, directions: np.ndarray, max_dist_m: float, use_embree: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`LinkGeometry.project_along` of ``link``."""
    return geometry_of(link).project_along(points, directions, max_dist_m, use_embree)


def closest_points(link: Link, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest surface point, its distance (m) and triangle for each of (K, 3) points."""
    return geometry_of(link).closest_points(points)


def link_from_trimesh(mesh: trimesh.Trimesh, name: str = "link") -> Link:
    """A :class:`~sphri.types.Link` from a trimesh mesh (metres, link frame), for tests and scripts."""
    return Link(
        name=name,
        vertices=np.asarray(mesh.vertices, dtype=np.float64),
        faces=np.asarray(mesh.faces, dtype=np.int64),
        watertight=bool(mesh.is_watertight),
    )
