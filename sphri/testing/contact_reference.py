"""Brute-force float64 reference for capsule-vs-mesh queries, and test sets.

:func:`reference_query` compares every capsule with every triangle in numpy,
with no culling, and is written for clarity rather than speed (about 10^4
capsule-triangle pairs per millisecond). It uses different formulas from the
compiled kernel so that agreement means something:

- point to triangle: project onto the plane, keep the projection when its
  barycentric coordinates (from the 2x2 Gram system) are all >= 0, else the
  nearest of the three point-to-edge distances;
- segment to segment: the unconstrained critical point when it lies in
  [0, 1]^2, else the nearest of the four endpoint-to-segment distances;
- segment to triangle: 0 when the segment crosses the interior, else the
  least of both endpoint-to-triangle and the three segment-to-edge distances.

Inside uses the same definitions as the kernel (:mod:`sphri.contact.mesh`):
``hull`` tests the segment's closest point against the hull's planes,
``winding`` sums the solid angle of every triangle.

:func:`random_capsules` makes the benchmark's hard set around a mesh, and
:func:`arm_stand_in` a parametric stand-in of the study's arm hull.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sphri.contact.mesh import DEGENERATE_REL


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def point_segment(p, a, b):
    """Squared distance and parameter of the closest point of segment ab to p (broadcast)."""
    ab = b - a
    den = _dot(ab, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(den > 0, _dot(p - a, ab) / np.where(den > 0, den, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    d = p - (a + t[..., None] * ab)
    return _dot(d, d), t


def solve_gram(g00, g01, g11, r0, r1, ok):
    """(x, y) solving the 2x2 symmetric system ``[[g00, g01], [g01, g11]] (x, y) = (r0, r1)`` by Cramer's rule
    where ``ok(det)`` holds (broadcast; garbage elsewhere, never a division by zero), and that mask."""
    det = g00 * g11 - g01 * g01
    good = ok(det)
    safe = np.where(good, det, 1.0)
    return (g11 * r0 - g01 * r1) / safe, (g00 * r1 - g01 * r0) / safe, good


def barycentric(p, a, b, c, degenerate):
    """Barycentric coordinates (..., 3) of p's projection on the plane of abc (NaN if degenerate)."""
    e0 = b - a
    e1 = c - a
    w = p - a
    g00, g01, g11 = _dot(e0, e0), _dot(e0, e1), _dot(e1, e1)
    r0, r1 = _dot(w, e0), _dot(w, e1)
    v, s, ok = solve_gram(g00, g01, g11, r0, r1, lambda det: (~degenerate) & (det > 0))
    out = np.stack([1.0 - v - s, v, s], axis=-1)
    return np.where(ok[..., None], out, np.nan)


def edge_weights(shape, ix, iy, t):
    """Barycentric coordinates (``shape``, last axis 3) of the points at ``t`` along the edge from vertex ``ix``
    to vertex ``iy``."""
    bw = np.zeros(shape)
    bw[..., ix] = 1.0 - t
    bw[..., iy] = t
    return bw


def point_triangle(p, a, b, c, degenerate):
    """Squared distance, closest point and barycentric coordinates of triangle abc to p."""
    bary = barycentric(p, a, b, c, degenerate)
    interior = (bary >= 0).all(axis=-1)  # NaN (degenerate) compares False
    proj = a + bary[..., 1:2] * (b - a) + bary[..., 2:3] * (c - a)
    dp = p - proj
    best = np.where(interior, _dot(dp, dp), np.inf)
    point = np.where(interior[..., None], proj, 0.0)
    bary = np.where(interior[..., None], bary, 0.0)
    # the three edges (a->b, b->c, c->a) with barycentric weights of their ends
    for x, y, ix, iy in ((a, b, 0, 1), (b, c, 1, 2), (c, a, 2, 0)):
        d2, t = point_segment(p, x, y)
        better = d2 < best
        best = np.where(better, d2, best)
        point = np.where(better[..., None], x + t[..., None] * (y - x), point)
        bary = np.where(better[..., None], edge_weights(bary.shape, ix, iy, t), bary)
    return best, point, bary


def segment_segment(p0, p1, q0, q1):
    """Squared distance between segments p0p1 and q0q1 and the parameters (s, t)."""
    u = p1 - p0
    v = q1 - q0
    w = p0 - q0
    a, b, c = _dot(u, u), _dot(u, v), _dot(v, v)
    d, e = _dot(u, w), _dot(v, w)
    # the critical point of |w + s u - t v|^2: [[a, -b], [-b, c]] (s, t) = (-d, e)
    s, t, ok = solve_gram(a, -b, c, -d, e, lambda det: det > 1e-14 * np.maximum(a * c, 1e-300))
    interior = ok & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    diff = w + s[..., None] * u - t[..., None] * v
    best = np.where(interior, _dot(diff, diff), np.inf)
    bs = np.where(interior, s, 0.0)
    bt = np.where(interior, t, 0.0)
    # boundary of the parameter square: each endpoint against the other segment
    cands = (
        (p0, q0, q1, False, 0.0),
        (p1, q0, q1, False, 1.0),
        (q0, p0, p1, True, 0.0),
        (q1, p0, p1, True, 1.0),
    )
    for point, x, y, on_p, fixed in cands:
        d2, tt = point_segment(point, x, y)
        better = d2 < best
        best = np.where(better, d2, best)
        if on_p:  # the point is an end of q; tt runs along p
            bs = np.where(better, tt, bs)
            bt = np.where(better, fixed, bt)
        else:
            bs = np.where(better, fixed, bs)
            bt = np.where(better, tt, bt)
    return best, bs, bt


def segment_triangle(p0, p1, a, b, c, degenerate):
    """Squared distance, segment parameter, closest point and barycentric coordinates."""
    n = np.cross(b - a, c - a)
    nn = np.sqrt(_dot(n, n))
    n = n / np.where(nn > 0, nn, 1.0)[..., None]
    s0 = _dot(p0 - a, n)
    s1 = _dot(p1 - a, n)
    cross = (~degenerate) & (s0 * s1 < 0)
    tc = np.where(cross, s0 / np.where(cross, s0 - s1, 1.0), 0.0)
    x = p0 + tc[..., None] * (p1 - p0)
    bx = barycentric(x, a, b, c, degenerate)
    # the crossing point lies in the plane: it is in the triangle iff its coordinates are >= 0
    hit = cross & (bx >= 0).all(axis=-1)
    best = np.where(hit, 0.0, np.inf)
    tbest = np.where(hit, tc, 0.0)
    point = np.where(hit[..., None], x, 0.0)
    bary = np.where(hit[..., None], bx, 0.0)
    for end, tt in ((p0, 0.0), (p1, 1.0)):
        d2, q, bc = point_triangle(end, a, b, c, degenerate)
        better = (~hit) & (d2 < best)
        best = np.where(better, d2, best)
        tbest = np.where(better, tt, tbest)
        point = np.where(better[..., None], q, point)
        bary = np.where(better[..., None], bc, bary)
    for x0, x1, ix, iy in ((a, b, 0, 1), (b, c, 1, 2), (c, a, 2, 0)):
        d2, s, t = segment_segment(p0, p1, x0, x1)
        better = (~hit) & (d2 < best)
        best = np.where(better, d2, best)
        tbest = np.where(better, s, tbest)
        point = np.where(better[..., None], x0 + t[..., None] * (x1 - x0), point)
        bary = np.where(better[..., None], edge_weights(bary.shape, ix, iy, t), bary)
    return best, tbest, point, bary


def hull_planes(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(H, 3) outward normals and (H,) offsets of the vertices' convex hull (qhull)."""
    from scipy.spatial import ConvexHull

    eq = ConvexHull(vertices).equations
    return eq[:, :3], -eq[:, 3]


def winding_direct(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(P,) generalized winding number: the sum of every triangle's solid angle / 4 pi."""
    tri = vertices[faces]
    out = np.empty(points.shape[0])
    for s in range(0, points.shape[0], 256):
        q = points[s : s + 256, None, None, :]
        r = tri[None] - q  # (P, F, 3, 3)
        a, b, c = r[..., 0, :], r[..., 1, :], r[..., 2, :]
        la, lb, lc = (np.sqrt(_dot(x, x)) for x in (a, b, c))
        num = _dot(a, np.cross(b, c))
        den = la * lb * lc + _dot(a, b) * lc + _dot(b, c) * la + _dot(c, a) * lb
        out[s : s + 256] = (2.0 * np.arctan2(num, den)).sum(axis=1) / (4.0 * np.pi)
    return out


@dataclass
class ReferenceResult:
    """Brute-force answer for N capsules (every field exact, no culling)."""

    distance: np.ndarray
    """(N,) float64 metres."""
    inside: np.ndarray
    in_contact: np.ndarray
    triangle: np.ndarray
    point: np.ndarray
    segment_t: np.ndarray
    barycentric: np.ndarray


def reference_query(vertices, faces, p0, p1, radius, inside: str = "hull", chunk: int = 512) -> ReferenceResult:
    """Exact answer by comparing every capsule with every triangle (numpy, float64).

    ``inside`` is "hull", "winding" or "none" (resolve "auto" with
    ``prepare_mesh(v, f).inside_mode``). Coordinates are taken relative to
    the mesh's bounding-box centre, as in the kernel, so large offsets keep
    their precision.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    v = v - centre
    p0 = np.asarray(p0, dtype=np.float64) - centre
    p1 = np.asarray(p1, dtype=np.float64) - centre
    r = np.broadcast_to(np.asarray(radius, dtype=np.float64), (p0.shape[0],))
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cr = np.cross(b - a, c - a)
    longest2 = np.max(np.stack([_dot(b - a, b - a), _dot(c - b, c - b), _dot(a - c, a - c)]), axis=0)
    degenerate = np.sqrt(_dot(cr, cr)) <= DEGENERATE_REL * longest2
    n = p0.shape[0]
    dist = np.empty(n)
    tri = np.empty(n, dtype=np.int64)
    tpar = np.empty(n)
    point = np.empty((n, 3))
    bary = np.empty((n, 3))
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        d2, t, q, bc = segment_triangle(p0[s:e, None, :], p1[s:e, None, :], a[None], b[None], c[None], degenerate[None])
        j = np.argmin(d2, axis=1)
        rows = np.arange(e - s)
        dist[s:e] = np.sqrt(d2[rows, j])
        tri[s:e] = j
        tpar[s:e] = t[rows, j]
        point[s:e] = q[rows, j]
        bary[s:e] = bc[rows, j]
    seg = p0 + tpar[:, None] * (p1 - p0)
    ins = np.zeros(n, dtype=bool)
    if inside in ("hull", "winding"):
        hn, hd = hull_planes(v)
        in_hull = (seg @ hn.T - hd < 0).all(axis=1) & (dist > 0)
        ins = in_hull.copy()
        if inside == "winding" and in_hull.any():
            ins[in_hull] = winding_direct(v, f, seg[in_hull]) >= 0.5
    elif inside != "none":
        raise ValueError(f"inside={inside!r} is invalid: use 'hull', 'winding' or 'none'")
    return ReferenceResult(
        distance=dist,
        inside=ins,
        in_contact=(dist < r) | ins,
        triangle=tri,
        point=point + centre,
        segment_t=tpar,
        barycentric=bary,
    )


# --------------------------------------------------------------------------- test sets


def arm_stand_in(n_around: int = 24, open_faces: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A convex stand-in of the study's arm hull: vertices (V, 3) m, faces (F, 3).

    An elliptic prism with tapered, capped ends, 7.2 x 9.3 cm across and
    24.1 cm along z (from -0.483 to -0.242 m, like the real hull), wound
    outward; ``open_faces`` side faces are left out so that, like the real
    Unity hull, it is not watertight.
    """
    ang = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    rx, ry = 0.036, 0.0465
    rings = []
    for z, s in ((-0.483, 0.6), (-0.465, 1.0), (-0.260, 1.0), (-0.242, 0.7)):
        rings.append(np.stack([s * rx * np.cos(ang), s * ry * np.sin(ang), np.full(n_around, z)], axis=1))
    v = np.concatenate(rings + [np.array([[0.0, 0.0, -0.483], [0.0, 0.0, -0.242]])])
    faces = []
    for k in range(3):
        for i in range(n_around):
            j = (i + 1) % n_around
            a, b = k * n_around + i, k * n_around + j
            c, d = (k + 1) * n_around + i, (k + 1) * n_around + j
            faces += [(a, b, d), (a, d, c)]
    lo_c, hi_c = 4 * n_around, 4 * n_around + 1
    for i in range(n_around):
        j = (i + 1) % n_around
        faces.append((lo_c, j, i))
        faces.append((hi_c, 3 * n_around + i, 3 * n_around + j))
    f = np.array(faces, dtype=np.int64)
    if open_faces:
        drop = np.arange(2 * n_around, 2 * n_around + 2 * open_faces)  # middle band
        f = np.delete(f, drop, axis=0)
    return v, f


def _random_unit(rng, n):
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def random_capsules(
    vertices: np.ndarray,
    faces: np.ndarray,
    n: int,
    seed: int = 0,
    near_fraction: float = 0.30,
    inside_fraction: float = 0.01,
    radius_m: tuple[float, float] = (0.01, 0.025),
    height_m: tuple[float, float] = (0.05, 0.09),
    pad_m: float = 0.15,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The benchmark's hard set: ``(p0, p1, radius, kind)`` for n capsules.

    Radii and tip-to-tip heights are uniform in the given ranges (segment
    length = height - 2 radius). ``kind`` is 0 far (centre uniform in the
    mesh box grown by ``pad_m``, any orientation), 1 near (centre within
    -1..2 radii of a surface point chosen by area, so many cross the
    surface) and 2 fully inside (the whole capsule at least its radius
    inside every hull plane).
    """
    rng = np.random.default_rng(seed)
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    r = rng.uniform(*radius_m, size=n)
    h = rng.uniform(*height_m, size=n)
    half = 0.5 * np.maximum(h - 2 * r, 0.0)
    axis = _random_unit(rng, n)
    kind = np.zeros(n, dtype=np.int8)
    n_in = int(round(inside_fraction * n))
    n_near = int(round(near_fraction * n))
    kind[:n_in] = 2
    kind[n_in : n_in + n_near] = 1
    rng.shuffle(kind)
    centre = np.empty((n, 3))
    lo, hi = v.min(axis=0), v.max(axis=0)
    far = kind == 0
    centre[far] = rng.uniform(lo - pad_m, hi + pad_m, size=(int(far.sum()), 3))
    # near: a point on the surface, offset along the face normal
    tri = v[f]
    cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(cr, axis=1)
    near = np.nonzero(kind == 1)[0]
    j = rng.choice(len(f), size=near.size, p=area / area.sum())
    w = rng.dirichlet(np.ones(3), size=near.size)
    surf = np.einsum("ij,ijk->ik", w, tri[j])
    nrm = cr[j] / area[j, None]
    off = rng.uniform(-1.0, 2.0, size=near.size) * r[near]
    centre[near] = surf + off[:, None] * nrm
    # inside: rejection sampling against the hull planes, inset by radius + half length
    ins = np.nonzero(kind == 2)[0]
    if ins.size:
        hn, hd = hull_planes(v)
        todo = ins
        for _ in range(1000):
            if todo.size == 0:
                break
            cand = rng.uniform(lo, hi, size=(todo.size, 3))
            c0 = cand - half[todo, None] * axis[todo]
            c1 = cand + half[todo, None] * axis[todo]
            slack = np.minimum(hd - c0 @ hn.T, hd - c1 @ hn.T).min(axis=1) - r[todo]
            ok = slack > 1e-4
            centre[todo[ok]] = cand[ok]
            # shorten and thin the ones that do not fit (thin hulls cannot hold every capsule)
            half[todo[~ok]] *= 0.97
            r[todo[~ok]] = np.maximum(r[todo[~ok]] * 0.99, radius_m[0] * 0.25)
            todo = todo[~ok]
        if todo.size:
            raise ValueError(f"could not place {todo.size} capsules inside the hull; is the mesh too thin?")
    p0 = centre - half[:, None] * axis
    p1 = centre + half[:, None] * axis
    return p0, p1, r, kind


def compare(fast, ref, radius, tol_m: float = 1e-9) -> dict[str, int | float]:
    """Disagreements of a query result with the reference (counts and max error).

    Distances are compared where either is below radius (the band the fast
    kernel must get exactly); inside flags where the reference distance
    exceeds ``tol_m`` (on the surface, inside is a coin flip and harmless:
    depth is the radius either way).
    """
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), ref.distance.shape)
    band = (ref.distance < radius) | ref.inside
    err = np.abs(np.where(band, fast.distance - ref.distance, 0.0))
    clear = ref.distance > tol_m
    return {
        "contact_disagreements": int((fast.in_contact != ref.in_contact).sum()),
        "inside_disagreements": int(((fast.inside != ref.inside) & clear).sum()),
        "missed_inside": int((ref.inside & ~fast.inside & clear).sum()),
        "distance_over_tol": int((err > tol_m).sum()),
        "max_distance_error_m": float(err.max()) if err.size else 0.0,
    }
