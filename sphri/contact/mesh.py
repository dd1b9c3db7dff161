"""Per-link acceleration data for the contact kernels (built once, cached).

:func:`prepare_mesh` turns a link's vertices (V, 3) and faces (F, 3) into a
:class:`MeshAccel`: the mesh recentred on its bounding-box centre (the
kernels work in that local frame so that coordinates offset by 1000 m keep
full float64 precision), per-triangle vertices and unit normals, a bounding
volume hierarchy over triangles, the planes of the vertices' convex hull
(culling, and the solid for ``inside="hull"``) and, for
``inside="winding"``, the boundary-edge closures that make the generalized
winding number hierarchical.

Inside modes (what "the capsule is inside the link's solid" means):

``hull``
    The solid is the convex hull of the link's vertices. Exact for convex
    links whether or not the mesh is closed (the study's Unity hulls miss
    ~5 % of their surface area).
``winding``
    The solid is where the generalized winding number of the (outward
    wound) faces is at least 1/2, intersected with the convex hull. Exact
    for closed meshes of any shape; degrades gracefully across holes.
``auto``
    ``hull`` when every face lies on the boundary of the vertices' convex
    hull, up to :data:`CONVEX_TOL_M` (the mesh is a possibly open, nearly
    convex surface), else ``winding``.
``none``
    Nothing is inside (the paper's sphere approximation).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from sphri.geometry.link import geometry_of_arrays

#: Inside modes accepted by :func:`prepare_mesh` (see the module docstring).
INSIDE_MODES: tuple[str, ...] = ("auto", "hull", "winding", "none")

#: Kernel codes of the resolved inside modes.
MODE_CODE: dict[str, int] = {"none": 0, "hull": 1, "winding": 2}

#: Triangles with twice their area below this fraction of their longest edge
#: squared are degenerate (a segment or a point): their height is below
#: 1e-12 of their length, so treating them as their three edges changes no
#: distance by more than that.
DEGENERATE_REL = 1e-12

#: ``inside="auto"`` takes the hull as the solid when every face lies within
#: ``min(CONVEX_TOL_M, CONVEX_REL_TOL * bounding-box diagonal)`` of the hull's
#: boundary. The study's Unity hulls have shallow dents (faces up to 1.9 mm
#: below the hull of their vertices); a dent shallower than a capsule's
#: radius cannot change a contact decision (a point in it is closer to the
#: surface than the dent is deep), only the inside flag of a capsule in it.
CONVEX_TOL_M = 0.005
CONVEX_REL_TOL = 0.02

#: Most triangles in one BVH leaf.
LEAF_SIZE = 4

#: Cells of the seed grid: GRID_CELLS_PER_FACE per face, within
#: [GRID_CELLS_MIN, GRID_CELLS]; its padding around the mesh box (fraction of
#: the largest extent).
GRID_CELLS = 32768
GRID_CELLS_MIN = 4096
GRID_CELLS_PER_FACE = 64
GRID_PAD = 0.25


@dataclass(frozen=True, eq=False)
class MeshAccel:
    """A link mesh ready for the contact kernels (local frame = world - ``shift``).

    Triangles are in BVH order; ``tri_id`` maps them back to rows of the
    input ``faces``. Packed arrays (what the kernels read):

    - ``tri`` (F, 24) float64: vertices a, b, c (0:9), geometric unit normal
      (9:12, right-hand rule, zero when degenerate), the in-plane outward
      normals of the edges a->b, b->c, c->a (12:21) and their offsets (21:24);
    - ``nodes_box`` (M, 6) float64 BVH boxes (lo, hi); ``nodes_int`` (M, 4)
      int64: left child (-1 for a leaf), right child, first triangle, count;
    - ``hull`` (H, 4) float64 planes n, d of the vertices' convex hull
      (inside iff n @ x < d), H = 0 when the vertices span no volume;
    - ``closure`` (M, 2) int64 first/count of each node's boundary edges in
      ``close_u``/``close_v`` (K, 3) (first -1: none), for winding numbers;
    - ``grid``/``grid_dim``/``grid_seed``: a coarse grid over the padded box
      giving each cell's nearest triangle (the search's first candidate).
    """

    shift: np.ndarray
    """(3,) float64 world position of the local origin (bounding-box centre), metres."""
    n_vertices: int
    n_faces: int
    inside_mode: str
    """Resolved inside mode: "hull", "winding" or "none"."""
    convex: bool
    """Every face lies on the convex hull's boundary (within the ``auto`` tolerance)."""
    box: np.ndarray
    """(6,) float64 local bounding box (lo, hi), metres."""
    sphere_radius: float
    """Radius (metres) of the bounding sphere centred on the local origin."""
    tri: np.ndarray
    tri_deg: np.ndarray
    """(F,) bool degenerate (zero-area) triangles, treated as their edges."""
    tri_normal: np.ndarray
    """(F, 3) float64 outward unit normal reported in results (zeros when degenerate)."""
    tri_plane: np.ndarray
    """(F,) int64 hull plane nearest to each triangle's centroid (tried first)."""
    tri_id: np.ndarray
    """(F,) int64 row of the triangle in the input faces."""
    nodes_box: np.ndarray
    nodes_int: np.ndarray
    hull: np.ndarray
    closure: np.ndarray
    close_u: np.ndarray
    close_v: np.ndarray
    grid: np.ndarray
    """(4,) float64 seed grid: local origin x, y, z and 1 / cell size (1/m)."""
    grid_dim: np.ndarray
    """(3,) int64 seed grid cells along x, y, z."""
    grid_seed: np.ndarray
    """(nx * ny * nz,) int64 triangle (BVH order) nearest to each cell centre:
    the first one the search tests, so that its bound is tight from the start."""
    notes: tuple[str, ...] = field(default=())

    @cached_property
    def kernel_arrays(self) -> tuple:
        """The arrays the compiled kernels take, in their order (see ``_kernels``)."""
        return (
            self.box,
            self.tri,
            self.tri_deg,
            self.tri_plane,
            self.nodes_box,
            self.nodes_int,
            self.hull,
            self.closure,
            self.close_u,
            self.close_v,
            self.grid,
            self.grid_dim,
            self.grid_seed,
        )


def _as_mesh_arrays(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] == 0:
        raise ValueError(f"vertices must have shape (V, 3) with V >= 1, got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] == 0:
        raise ValueError(f"faces must have shape (F, 3) with F >= 1, got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.issubdtype(f.dtype, np.floating) or not np.all(f == np.round(f)):
            raise ValueError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
    v = v.astype(np.float64)
    f = f.astype(np.int64)
    if not np.isfinite(v).all():
        bad = np.argwhere(~np.isfinite(v).all(axis=1)).ravel()
        raise ValueError(f"vertices hold NaN/inf at rows {bad[:5].tolist()} ({bad.size} rows)")
    if f.min() < 0 or f.max() >= v.shape[0]:
        raise ValueError(f"faces index vertices out of range [0, {v.shape[0]}): min {f.min()}, max {f.max()}")
    return v, f


def _build_bvh(lo: np.ndarray, hi: np.ndarray):
    """Median-split BVH over boxes (lo, hi) (F, 3); nodes in depth-first order."""
    cen = 0.5 * (lo + hi)
    order = np.arange(lo.shape[0], dtype=np.int64)
    node_lo: list[np.ndarray] = []
    node_hi: list[np.ndarray] = []
    left: list[int] = []
    right: list[int] = []
    start: list[int] = []
    count: list[int] = []

    def new_node(idx: np.ndarray, first: int) -> int:
        k = len(node_lo)
        node_lo.append(lo[idx].min(axis=0))
        node_hi.append(hi[idx].max(axis=0))
        left.append(-1)
        right.append(-1)
        start.append(first)
        count.append(idx.size)
        return k

    # iterative: (node index, slice of `order`)
    root = new_node(order, 0)
    stack = [(root, 0, order.size)]
    while stack:
        k, s, e = stack.pop()
        if e - s <= LEAF_SIZE:
            continue
        idx = order[s:e]
        c = cen[idx]
        ext = c.max(axis=0) - c.min(axis=0)
        axis = int(np.argmax(ext))
        if ext[axis] <= 0.0:  # all centroids coincide: split by position in the list
            srt = np.arange(idx.size)
        else:
            srt = np.argsort(c[:, axis], kind="stable")
        order[s:e] = idx[srt]
        m = s + (e - s) // 2
        kl = new_node(order[s:m], s)
        kr = new_node(order[m:e], m)
        left[k], right[k] = kl, kr
        stack.append((kr, m, e))
        stack.append((kl, s, m))
    return (
        order,
        np.array(node_lo, dtype=np.float64).reshape(-1, 3),
        np.array(node_hi, dtype=np.float64).reshape(-1, 3),
        np.array(left, dtype=np.int64),
        np.array(right, dtype=np.int64),
        np.array(start, dtype=np.int64),
        np.array(count, dtype=np.int64),
    )


def _hull_planes(v: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique outward planes (n, d) of the convex hull of ``v`` and its vertex indices.

    Returns empty arrays when the points span no volume (flat or tiny meshes).
    """
    from scipy.spatial import ConvexHull, QhullError

    empty = (np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=np.int64))
    if v.shape[0] < 4:
        return empty
    try:
        hull = ConvexHull(v)
    except (QhullError, ValueError):
        return empty
    if hull.volume <= (1e-9 * scale) ** 3:
        return empty
    eq = hull.equations  # n @ x + offset <= 0 inside
    n = eq[:, :3]
    d = -eq[:, 3]
    key = np.round(np.concatenate([n, d[:, None] / scale], axis=1), 9)
    _, first = np.unique(key, axis=0, return_index=True)
    first = np.sort(first)
    return n[first].copy(), d[first].copy(), np.asarray(hull.vertices, dtype=np.int64)


def _is_convex_surface(v, f, hull_n, hull_d, tol) -> bool:
    """True when every face lies within ``tol`` of the hull's boundary.

    Checked at each face's corners, edge midpoints, centroid and three inner
    points (the depth below a convex boundary is concave along a face, so
    these bound it well for faces much smaller than the hull).
    """
    w = np.array(
        [
            [1, 0, 0],
            [0, 1, 0],
            [0, 0, 1],
            [0.5, 0.5, 0],
            [0, 0.5, 0.5],
            [0.5, 0, 0.5],
            [1 / 3, 1 / 3, 1 / 3],
            [2 / 3, 1 / 6, 1 / 6],
            [1 / 6, 2 / 3, 1 / 6],
            [1 / 6, 1 / 6, 2 / 3],
        ]
    )
    chunk = max(1, 2_000_000 // (w.shape[0] * max(1, hull_n.shape[0])))
    for s in range(0, f.shape[0], chunk):
        pts = np.einsum("kj,fjd->fkd", w, v[f[s : s + chunk]]).reshape(-1, 3)
        depth = (pts @ hull_n.T - hull_d).max(axis=1)  # <= 0 inside; -depth = distance to the boundary
        if (depth < -tol).any():
            return False
    return True


def _closures(tri_v: np.ndarray, node_start, node_count, local_v: np.ndarray):
    """Oriented boundary edges of each BVH node's triangles (Jacobson et al. 2013).

    ``tri_v`` (F, 3) vertex indices (duplicate positions merged) in BVH order.
    A node far from a query point contributes the solid angle of the fan
    from its box centre over its boundary edges instead of its triangles; a
    node keeps a closure only when it has fewer boundary edges than triangles.
    """
    m = node_start.shape[0]
    close_start = np.full(m, -1, dtype=np.int64)
    close_count = np.zeros(m, dtype=np.int64)
    us, vs = [], []
    total = 0
    for k in range(m):
        s, c = int(node_start[k]), int(node_count[k])
        if c <= LEAF_SIZE:
            continue
        fk = tri_v[s : s + c]
        e = np.concatenate([fk[:, [0, 1]], fk[:, [1, 2]], fk[:, [2, 0]]])
        sign = np.where(e[:, 0] < e[:, 1], 1, -1)
        key = np.sort(e, axis=1)
        uniq, inv = np.unique(key, axis=0, return_inverse=True)
        net = np.zeros(uniq.shape[0], dtype=np.int64)
        np.add.at(net, inv.ravel(), sign)
        nz = np.nonzero(net)[0]
        reps = np.abs(net[nz])
        if reps.sum() >= c:
            continue
        a = np.where(net[nz] > 0, uniq[nz, 0], uniq[nz, 1])
        b = np.where(net[nz] > 0, uniq[nz, 1], uniq[nz, 0])
        a = np.repeat(a, reps)
        b = np.repeat(b, reps)
        close_start[k] = total
        close_count[k] = a.size
        us.append(local_v[a])
        vs.append(local_v[b])
        total += a.size
    cu = np.concatenate(us) if us else np.zeros((0, 3))
    cv = np.concatenate(vs) if vs else np.zeros((0, 3))
    return close_start, close_count, cu, cv


def _seed_grid(lo, hi, tri, deg, nodes_box, nodes_int):
    """A coarse grid over the padded box holding each cell centre's nearest triangle."""
    from sphri.contact import _kernels

    ext = hi - lo
    pad = GRID_PAD * float(ext.max()) + 1e-6
    lo = lo - pad
    ext = ext + 2 * pad
    cells = min(GRID_CELLS, max(GRID_CELLS_MIN, GRID_CELLS_PER_FACE * tri.shape[0]))
    cell = max(float(np.prod(ext) / cells) ** (1.0 / 3.0), float(ext.max()) / 64.0)
    dim = np.maximum(np.ceil(ext / cell).astype(np.int64), 1)
    axes = [lo[k] + (np.arange(dim[k]) + 0.5) * cell for k in range(3)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    seed = np.empty(centres.shape[0], dtype=np.int64)
    _kernels.nearest_triangles(np.ascontiguousarray(centres), tri, deg, nodes_box, nodes_int, seed)
    return np.array([lo[0], lo[1], lo[2], 1.0 / cell]), dim, seed


@dataclass
class _Faces:
    """Per-face geometry of a mesh in local coordinates (metres): the corners ``t`` (F, 3, 3) and ``a``, ``b``,
    ``c`` (F, 3), the unit normal ``geo_n`` (zeros when degenerate), the edges' in-plane outward unit normals
    ``side`` (F, 3, 3) and offsets ``side_off`` (F, 3; +inf when degenerate), and ``deg`` (F,) bool."""

    t: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    geo_n: np.ndarray
    side: np.ndarray
    side_off: np.ndarray
    deg: np.ndarray


def _faces(lv: np.ndarray, f: np.ndarray, notes: list[str]) -> _Faces:
    """The :class:`_Faces` of local vertices ``lv`` (V, 3) m and faces ``f`` (F, 3); degenerate faces are noted."""
    t = lv[f]
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    cr = np.cross(b - a, c - a)
    area2 = np.linalg.norm(cr, axis=1)
    edges = np.stack([b - a, c - b, a - c], axis=1)  # (F, 3 edges, 3)
    longest2 = (edges**2).sum(axis=2).max(axis=1)
    deg = area2 <= DEGENERATE_REL * longest2
    safe = np.where(deg, 1.0, area2)
    geo_n = np.where(deg[:, None], 0.0, cr / safe[:, None])
    # in-plane outward normals of the edges (triangle behind each), unit length
    side = np.cross(edges, geo_n[:, None, :])
    sl = np.linalg.norm(side, axis=2)
    side = np.where((sl > 0)[..., None], side / np.where(sl > 0, sl, 1.0)[..., None], 0.0)
    starts = np.stack([a, b, c], axis=1)
    side_off = np.einsum("fkd,fkd->fk", side, starts)
    # degenerate triangles: no side bound (offset +inf keeps every point "behind")
    side_off[deg] = np.inf
    if deg.any():
        notes.append(f"{int(deg.sum())} degenerate faces are treated as their edges")
    return _Faces(t, a, b, c, geo_n, side, side_off, deg)


@dataclass
class _Inside:
    """How a mesh's inside is decided: its hull planes (unit normals ``hull_n`` (P, 3), offsets ``hull_d`` (P,)
    m, vertex rows ``hull_vi``), whether the surface is convex, and the mode (hull, winding or none)."""

    hull_n: np.ndarray
    hull_d: np.ndarray
    hull_vi: np.ndarray
    convex: bool
    mode: str


def _inside_test(lv: np.ndarray, f: np.ndarray, scale: float, inside: str, notes: list[str]) -> _Inside:
    """The :class:`_Inside` of local vertices ``lv`` (m), faces ``f``, mesh size ``scale`` (m) and the asked
    ``inside`` mode (``auto``: hull when convex, else winding)."""
    hull_n, hull_d, hull_vi = _hull_planes(lv, scale)
    tol = min(CONVEX_TOL_M, CONVEX_REL_TOL * scale)
    convex = bool(hull_n.shape[0] > 0 and _is_convex_surface(lv, f, hull_n, hull_d, tol))
    mode = ("hull" if convex else "winding") if inside == "auto" else inside
    if mode in ("hull", "winding") and hull_n.shape[0] == 0:
        notes.append("the vertices span no volume: nothing is inside")
        mode = "none"
    return _Inside(hull_n, hull_d, hull_vi, convex, mode)


def _outward_normals(lv: np.ndarray, fc: _Faces, ins: _Inside, notes: list[str]) -> np.ndarray:
    """(F, 3) normals reported in results: pointing away from the hull's interior on a convex mesh tested
    by its hull (open hulls may have faces wound inward), else the faces' own."""
    out_n = fc.geo_n.copy()
    if ins.convex and ins.mode == "hull":
        centre = lv[ins.hull_vi].mean(axis=0)
        flip = np.einsum("ij,ij->i", out_n, fc.a - centre) < 0
        if flip.any():
            out_n[flip] *= -1.0
            notes.append(f"{int(flip.sum())} faces wound inward get outward normals")
    return out_n


def _nearest_planes(fc: _Faces, ins: _Inside) -> np.ndarray:
    """(F,) int64 hull plane nearest to each face's centroid (the first one tried by the inside test)."""
    n_faces = fc.t.shape[0]
    tri_plane = np.zeros(n_faces, dtype=np.int64)
    if ins.hull_n.shape[0]:
        cen = fc.t.mean(axis=1)
        step = max(1, 4_000_000 // ins.hull_n.shape[0])
        for s in range(0, n_faces, step):
            tri_plane[s : s + step] = np.argmax(cen[s : s + step] @ ins.hull_n.T - ins.hull_d, axis=1)
    return tri_plane


def _closure_arrays(
    mode: str, lv: np.ndarray, f: np.ndarray, order: np.ndarray, start: np.ndarray, count: np.ndarray, m: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(closure start (M,), closure count (M,), edge starts (E, 3), edge ends (E, 3) m) of the ``m`` BVH nodes
    for the winding test; empty closures in the other modes."""
    if mode == "winding":
        # merge vertices at identical positions so that shared edges cancel
        _, vid = np.unique(lv, axis=0, return_inverse=True)
        vid = vid.ravel()
        tri_v = vid[f][order]
        uniq_pos = np.zeros((int(vid.max()) + 1, 3))
        uniq_pos[vid] = lv
        return _closures(tri_v, start, count, uniq_pos)
    return np.full(m, -1, dtype=np.int64), np.zeros(m, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3))


def _build(v: np.ndarray, f: np.ndarray, inside: str) -> MeshAccel:
    """The :class:`MeshAccel` of vertices ``v`` (V, 3) m and faces ``f`` (F, 3) with the ``inside`` mode asked."""
    lo_w = v.min(axis=0)
    hi_w = v.max(axis=0)
    shift = 0.5 * (lo_w + hi_w)
    lv = v - shift
    scale = float(np.linalg.norm(hi_w - lo_w)) or 1.0
    notes: list[str] = []
    fc = _faces(lv, f, notes)
    ins = _inside_test(lv, f, scale, inside, notes)
    out_n = _outward_normals(lv, fc, ins, notes)
    tri_plane = _nearest_planes(fc, ins)

    a, b, c = fc.a, fc.b, fc.c
    lo = np.minimum(np.minimum(a, b), c)
    hi = np.maximum(np.maximum(a, b), c)
    order, node_lo, node_hi, left, right, start, count = _build_bvh(lo, hi)

    tri = np.concatenate([a, b, c, fc.geo_n, fc.side.reshape(-1, 9), fc.side_off], axis=1)[order]
    close_start, close_count, cu, cv = _closure_arrays(ins.mode, lv, f, order, start, count, node_lo.shape[0])
    hull_n = ins.hull_n
    hull = np.concatenate([hull_n, ins.hull_d[:, None]], axis=1) if hull_n.shape[0] else np.zeros((0, 4))
    tri = np.ascontiguousarray(tri)
    deg_o = np.ascontiguousarray(fc.deg[order])
    nodes_box = np.ascontiguousarray(np.concatenate([node_lo, node_hi], axis=1))
    nodes_int = np.ascontiguousarray(np.stack([left, right, start, count], axis=1))
    grid, grid_dim, grid_seed = _seed_grid(lv.min(axis=0), lv.max(axis=0), tri, deg_o, nodes_box, nodes_int)

    return MeshAccel(
        shift=shift,
        n_vertices=int(v.shape[0]),
        n_faces=int(f.shape[0]),
        inside_mode=ins.mode,
        convex=ins.convex,
        box=np.concatenate([lv.min(axis=0), lv.max(axis=0)]),
        sphere_radius=float(np.sqrt((lv**2).sum(axis=1).max())),
        tri=tri,
        tri_deg=deg_o,
        tri_normal=np.ascontiguousarray(out_n[order]),
        tri_plane=np.ascontiguousarray(tri_plane[order]),
        tri_id=order,
        nodes_box=nodes_box,
        nodes_int=nodes_int,
        hull=np.ascontiguousarray(hull),
        closure=np.ascontiguousarray(np.stack([close_start, close_count], axis=1)),
        close_u=np.ascontiguousarray(cu),
        close_v=np.ascontiguousarray(cv),
        grid=grid,
        grid_dim=grid_dim,
        grid_seed=grid_seed,
        notes=tuple(notes),
    )


def prepare_mesh(vertices: np.ndarray, faces: np.ndarray, inside: str = "auto") -> MeshAccel:
    """Acceleration data for a mesh (vertices (V, 3) metres, faces (F, 3) int).

    ``inside`` is one of :data:`INSIDE_MODES`. Results are kept on the mesh's
    geometry (:func:`sphri.geometry.link.geometry_of_arrays`, shared by the
    bytes of the mesh), one per mode, so calling this once per frame chunk
    costs one hash.
    """
    if inside not in INSIDE_MODES:
        raise ValueError(f"inside={inside!r} is invalid: allowed values: {list(INSIDE_MODES)}")
    v, f = _as_mesh_arrays(vertices, faces)
    return geometry_of_arrays(v, f).derived(("contact", inside), lambda: _build(v, f, inside))
