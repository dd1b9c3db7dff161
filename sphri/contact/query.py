"""Exact capsule-vs-mesh queries on plain arrays: :func:`capsule_mesh_query`.

A capsule is a segment p0-p1 with a radius. Its *distance* to a link is the
least Euclidean distance between the segment and the union of the link's
triangles (degenerate triangles count as their edges). It is *inside* when
the segment's closest point lies in the interior of the link's solid (the
``hull`` / ``winding`` definitions are in :mod:`sphri.contact.mesh`); a
segment that touches or crosses the surface has distance 0 and is not
inside. It is *in contact* when ``distance < radius`` or inside.

Culling cascade (per capsule, compiled): the capsule's box (segment box
grown by ``radius + margin``) against the link's box; the exact distance to
a seed triangle (nearest to the midpoint's cell of a coarse grid); a search
down the triangle BVH bounded by the best distance so far, skipping boxes,
triangle planes and edge side-planes that are farther; exact
segment-triangle distances for what is left. A capsule with no surface
within ``radius + margin`` is clipped to the hull's planes: wholly outside
means far (distance reported as inf); otherwise the search goes on without
a bound, because an inside capsule needs its distance whatever it is.

Exactness: every distance below ``radius + margin``, and every distance of a
capsule reaching into the hull, is the exact float64 segment-to-triangle
distance (computed relative to the mesh's box centre, so offsets of 1000 m
keep full precision). Tests compare it with the brute-force reference
(:mod:`sphri.testing.contact_reference`) to 1e-12 m on random and adversarial sets.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from sphri.contact import _kernels
from sphri.contact.mesh import MODE_CODE, MeshAccel, prepare_mesh


@dataclass
class ContactQuery:
    """Result of :func:`capsule_mesh_query` for N capsules (world frame, metres).

    Fields after ``triangle`` are filled where ``triangle >= 0`` (the surface
    lies within radius + margin, or the capsule reaches into the hull) and
    are NaN elsewhere.
    """

    distance: np.ndarray
    """(N,) float64 segment-to-surface distance; exact below radius + margin
    or when the segment reaches into the hull, else inf."""
    inside: np.ndarray
    """(N,) bool: the segment's closest point lies inside the solid (distance > 0)."""
    in_contact: np.ndarray
    """(N,) bool: distance < radius or inside."""
    triangle: np.ndarray
    """(N,) int64 row of ``faces`` holding the closest surface point, -1 if none."""
    segment_t: np.ndarray
    """(N,) float64 parameter in [0, 1] of the closest segment point (p0 + t (p1 - p0))."""
    point: np.ndarray
    """(N, 3) float64 closest point on the surface."""
    barycentric: np.ndarray
    """(N, 3) float64 barycentric coordinates of ``point`` in ``triangle``."""
    segment_point: np.ndarray
    """(N, 3) float64 closest point on the segment."""
    normal: np.ndarray
    """(N, 3) float64 outward unit normal of ``triangle`` (for a degenerate
    triangle: the unit vector from ``point`` towards the segment, reversed
    when inside; zero when the distance is 0)."""
    patch_radius: np.ndarray
    """(N,) float64 radius of the circle where the sphere of ``radius`` at
    ``segment_point`` meets the triangle's plane; ``radius`` when inside with
    distance >= radius (the sphere lies wholly in the solid); 0 when the
    sphere does not reach the plane."""
    depth: np.ndarray
    """(N,) float64 radius - distance outside, radius + distance inside."""


def _as_points(x, name: str, n: int | None = None) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} has {a.shape[0]} rows but p0 has {n}")
    a = np.ascontiguousarray(a, dtype=np.float64)
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a).all(axis=1)).ravel()
        raise ValueError(f"{name} holds NaN/inf at rows {bad[:5].tolist()} ({bad.size} rows)")
    return a


def check_capsules(p0, p1, radius) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate and convert capsule arrays: (N, 3), (N, 3), (N,) (or scalar) to float64."""
    p0 = _as_points(p0, "p0")
    p1 = _as_points(p1, "p1", p0.shape[0])
    r = np.asarray(radius, dtype=np.float64)
    if r.ndim == 0:
        r = np.full(p0.shape[0], float(r))
    if r.shape != (p0.shape[0],):
        raise ValueError(f"radius must be a scalar or have shape ({p0.shape[0]},), got {r.shape}")
    ok = np.isfinite(r) & (r >= 0)
    if not ok.all():
        bad = np.argwhere(~ok).ravel()
        raise ValueError(f"radius must be finite and >= 0 (metres); bad at rows {bad[:5].tolist()}")
    return p0, p1, np.ascontiguousarray(r)


def _check_margin(margin: float) -> float:
    margin = float(margin)
    if not np.isfinite(margin) or margin < 0:
        raise ValueError(f"margin={margin!r} is invalid: must be finite and >= 0 (metres)")
    return margin


@dataclass
class SearchRecord:
    """Raw per-capsule result of the compiled search (before :func:`finish`).

    ``d2`` squared distance (inf where nothing lies within radius + margin),
    ``inside``, ``tri`` (BVH order, -1: none); ``t``, ``q`` (local frame) and
    ``bary`` are defined only where ``tri >= 0``.
    """

    d2: np.ndarray
    inside: np.ndarray
    tri: np.ndarray
    t: np.ndarray
    q: np.ndarray
    bary: np.ndarray

    @classmethod
    def empty(cls, n: int) -> SearchRecord:
        return cls(
            np.empty(n),
            np.empty(n, dtype=np.bool_),
            np.empty(n, dtype=np.int64),
            np.empty(n),
            np.empty((n, 3)),
            np.empty((n, 3)),
        )

    def head(self, n: int) -> SearchRecord:
        """Views of the first n rows (buffers are reused across chunks)."""
        return self.take(slice(n))

    def take(self, rows: np.ndarray | slice) -> SearchRecord:
        return SearchRecord(*(getattr(self, f.name)[rows] for f in fields(self)))

    def in_contact(self, radius: np.ndarray) -> np.ndarray:
        """(n,) bool: distance < radius or inside."""
        return self.inside | (self.d2 < radius * radius)


def search(
    mesh: MeshAccel,
    p0: np.ndarray,
    p1: np.ndarray,
    radius: np.ndarray,
    margin: float = 0.0,
    spheres: int = 0,
    record: SearchRecord | None = None,
) -> SearchRecord:
    """The compiled search on checked float64 arrays (world frame); see :class:`SearchRecord`.

    ``spheres = k > 0`` answers the paper's approximation instead (each
    capsule as k spheres of its radius along its segment; nothing inside).
    ``record`` (at least n rows) is filled instead of new arrays.
    """
    n = p0.shape[0]
    rec = SearchRecord.empty(n) if record is None else record.head(n)
    if n == 0:
        return rec
    margin = _check_margin(margin)
    out = (rec.d2, rec.inside, rec.tri, rec.t, rec.q, rec.bary)
    if spheres > 0:
        _kernels.query_spheres(p0, p1, radius, margin, int(spheres), *mesh.kernel_arrays, mesh.shift, *out)
    else:
        _kernels.query_capsules(
            p0, p1, radius, margin, MODE_CODE[mesh.inside_mode], *mesh.kernel_arrays, mesh.shift, *out
        )
    return rec


def finish(mesh: MeshAccel, p0: np.ndarray, p1: np.ndarray, radius: np.ndarray, rec: SearchRecord) -> ContactQuery:
    """Every output field of the rows in ``rec`` (world frame); copies, ``rec`` is untouched."""
    n = p0.shape[0]
    res = ContactQuery(
        distance=rec.d2.copy(),
        inside=rec.inside.copy(),
        in_contact=np.empty(n, dtype=np.bool_),
        triangle=rec.tri.copy(),
        segment_t=rec.t.copy(),
        point=rec.q.copy(),
        barycentric=rec.bary.copy(),
        segment_point=np.empty((n, 3)),
        normal=np.empty((n, 3)),
        patch_radius=np.empty(n),
        depth=np.empty(n),
    )
    if n:
        out = (getattr(res, f.name) for f in fields(res))  # the output arrays in field order: the kernel's order
        _kernels.finish_rows(p0, p1, radius, mesh.tri, mesh.tri_deg, mesh.tri_normal, mesh.tri_id, mesh.shift, *out)
    return res


def query_prepared(
    mesh: MeshAccel, p0: np.ndarray, p1: np.ndarray, radius: np.ndarray, margin: float = 0.0, spheres: int = 0
) -> ContactQuery:
    """:func:`capsule_mesh_query` on a prepared mesh and checked float64 arrays (see :func:`search`)."""
    return finish(mesh, p0, p1, radius, search(mesh, p0, p1, radius, margin, spheres))


def capsule_mesh_query(
    vertices: np.ndarray,
    faces: np.ndarray,
    p0: np.ndarray,
    p1: np.ndarray,
    radius: np.ndarray | float,
    margin: float = 0.0,
    *,
    inside: str = "auto",
) -> ContactQuery:
    """Exact distance, inside flag and closest points of N capsules to a mesh.

    Parameters
    ----------
    vertices : (V, 3) float, metres.
    faces : (F, 3) int, counter-clockwise seen from outside (only
        ``inside="winding"`` depends on the winding).
    p0, p1 : (N, 3) segment ends, metres (float32 accepted; computed in float64).
    radius : (N,) or scalar capsule radii, metres (>= 0).
    margin : extra metres beyond each radius within which distances and
        closest points are still reported exactly (contact itself is
        ``distance < radius`` or inside).
    inside : "auto", "hull", "winding" or "none" (see :mod:`sphri.contact.mesh`).

    Returns
    -------
    :class:`ContactQuery`: (N,) ``distance``, ``inside``, ``in_contact``, and
    the closest triangle, point, barycentric coordinates, segment point,
    normal, patch radius and depth.

    The mesh's acceleration data is cached (keyed by its bytes), so repeated
    calls on the same link pay one hash. Example::

        q = capsule_mesh_query(v, f, p0, p1, 0.01)
        q.in_contact.sum(), q.distance[q.in_contact]
    """
    margin = _check_margin(margin)
    mesh = prepare_mesh(vertices, faces, inside=inside)
    p0, p1, r = check_capsules(p0, p1, radius)
    return query_prepared(mesh, p0, p1, r, margin)


def sphere_mesh_query(vertices, faces, p0, p1, radius, k: int = 5, margin: float = 0.0) -> ContactQuery:
    """The paper's approximation on arrays: each capsule as ``k`` spheres (see ``query_spheres``).

    Same result type as :func:`capsule_mesh_query`; ``inside`` is always
    False and ``distance`` is the least sphere-centre-to-surface distance.
    """
    if int(k) < 1:
        raise ValueError(f"k={k!r} is invalid: must be >= 1 spheres per capsule")
    mesh = prepare_mesh(vertices, faces, inside="none")
    p0, p1, r = check_capsules(p0, p1, radius)
    return query_prepared(mesh, p0, p1, r, margin, spheres=int(k))


def winding_number(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(P,) generalized winding number of the mesh at ``points`` (P, 3), hierarchical.

    1 inside and 0 outside a closed outward-wound mesh; fractional near holes.
    """
    mesh = prepare_mesh(vertices, faces, inside="winding")
    pts = _as_points(points, "points") - mesh.shift
    out = np.empty(pts.shape[0])
    # a flat mesh resolves to mode "none" and has no closures: the kernel then sums every triangle
    _kernels.winding_numbers(
        pts, mesh.tri, mesh.nodes_box, mesh.nodes_int, mesh.closure, mesh.close_u, mesh.close_v, out
    )
    return out
