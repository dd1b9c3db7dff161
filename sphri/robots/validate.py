"""Mesh validation and repair for robot links (every loader ends here).

:func:`make_link` turns raw vertices and faces into a :class:`sphri.types.Link`:
it checks shapes and values, fixes units (mm -> m), merges duplicate
vertices, drops degenerate and duplicate faces, and orients faces outward:
closed meshes get consistent winding and positive signed volume; open meshes
whose faces all lie on (within 1% of the extent of) their convex hull, like
the real study's hulls, get each face turned away from an interior point;
other open meshes get consistent winding (only where it is inconsistent) and
are inverted as a whole when most of their area faces the centroid.
Open boundaries are kept (``watertight=False``).
What was found and done goes to ``Link.notes`` and the log.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from sphri.config import require_choice
from sphri.geometry.link import triangle_normals_areas
from sphri.robots.schema import UNITS
from sphri.types import Link

if TYPE_CHECKING:  # trimesh (about 0.5-1 s to import) loads where a mesh is checked or read, not on a cached run
    import trimesh

log = logging.getLogger(__name__)

#: A link whose main part's largest extent exceeds this (metres) is taken to be in mm under ``units=auto``.
MM_EXTENT_THRESHOLD_M = 5.0
#: Connected components holding at least this fraction of a mesh's faces are its major parts: under
#: ``units=auto`` they must agree on the units, or the mesh is refused as ambiguous.
MAJOR_COMPONENT_FRACTION = 0.25

#: An open mesh whose face centres all lie within this fraction of its largest
#: extent from its convex hull is treated as a (slightly inexact) convex hull.
CONVEX_TOL = 0.01

#: Largest extent (metres, after the units) of a plausible robot link read from a file: outside, the
#: units are wrong and the mesh is refused naming ``robot.units``.
PLAUSIBLE_EXTENT_M = (0.02, 3.0)
#: Under ``units=auto`` a link read as millimetres but smaller than this (metres) may as well be in
#: centimetres: refused as ambiguous.
AMBIGUOUS_MM_BELOW_M = 0.05
#: Metres per unit of the declared mesh units.
UNIT_SCALE = {"mm": 1e-3, "cm": 1e-2}
#: An open mesh whose boundary edges are more than this share of its edges is much damaged: warned.
DAMAGED_BOUNDARY_SHARE = 0.05


class MeshError(ValueError):
    """A link mesh cannot be used; the message names its source."""


def _edges_sorted(faces: np.ndarray) -> np.ndarray:
    e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    return np.sort(e, axis=1)


def edge_defects(faces: np.ndarray) -> tuple[int, int]:
    """``(boundary, non_manifold)``: edges used by one face, and by more than two."""
    if len(faces) == 0:
        return 0, 0
    _, counts = np.unique(_edges_sorted(faces), axis=0, return_counts=True)
    return int((counts == 1).sum()), int((counts > 2).sum())


def is_closed(faces: np.ndarray) -> bool:
    """True when every edge is shared by exactly two faces."""
    return len(faces) > 0 and edge_defects(faces) == (0, 0)


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume (m^3) enclosed by the faces; > 0 when wound counter-clockwise from outside."""
    t = vertices[faces]
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)


def _on_convex_hull(vertices: np.ndarray, faces: np.ndarray, tol: float) -> tuple[bool, np.ndarray | None]:
    """Whether every face centroid lies within ``tol`` (m) of the vertices' convex hull; also an interior point."""
    import trimesh

    try:
        hull = trimesh.convex.convex_hull(vertices)
    except Exception:  # qhull fails on flat or too few points
        return False, None
    if hull.volume <= 0:
        return False, None
    normals = hull.face_normals
    offsets = np.einsum("ij,ij->i", normals, hull.vertices[hull.faces[:, 0]])
    centres = vertices[faces].mean(axis=1)
    worst = -np.inf
    for start in range(0, len(centres), 4096):  # chunked: (chunk, hull faces)
        d = centres[start : start + 4096] @ normals.T - offsets  # signed distance to each plane (<= 0 inside)
        worst = max(worst, float(np.abs(d.max(axis=1)).max()))
    return worst <= tol, hull.vertices.mean(axis=0)


def component_extents(v: np.ndarray, f: np.ndarray) -> list[tuple[int, float]]:
    """(face count, largest extent) of each connected component (vertices merged at 1e-6 of the
    extent, so an STL's unshared triangles still connect), most faces first."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    extent = float((v.max(axis=0) - v.min(axis=0)).max()) or 1.0
    _, inv = np.unique(np.round(v / (extent * 1e-6)).astype(np.int64), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    g = inv[f]
    n = int(inv.max()) + 1
    rows, cols = g[:, [0, 1, 2]].ravel(), g[:, [1, 2, 0]].ravel()
    _, label = connected_components(coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n)), directed=False)
    face_label = label[g[:, 0]]
    out = []
    for c in np.unique(face_label):
        fv = f[face_label == c].ravel()
        pts = v[fv]
        out.append((int((face_label == c).sum()), float((pts.max(axis=0) - pts.min(axis=0)).max())))
    return sorted(out, key=lambda t: -t[0])


def make_link(
    name: str,
    vertices: np.ndarray,
    faces: np.ndarray,
    units: str = "auto",
    source: str = "",
    notes: Sequence[str] = (),
    plausible: bool = False,
) -> Link:
    """Validate and repair a triangle mesh into a :class:`Link`.

    ``vertices`` (V, 3) in the file's units, ``faces`` (F, 3) vertex indices;
    ``units`` is ``auto`` (mm when the largest extent of the main connected
    component, the one with most faces, is over :data:`MM_EXTENT_THRESHOLD_M`,
    so a stray part far away never scales the link; refused when major
    components disagree, or when the main part reads as metres but other parts
    stretch the mesh past the threshold), ``m`` or ``mm``. ``source`` (a path or a
    description) names the mesh in errors and notes; ``notes`` are prepended
    to what validation adds. ``plausible``: refuse a link whose largest extent after the units lies
    outside :data:`PLAUSIBLE_EXTENT_M` (a robot link read from a file). Raises :class:`MeshError` for
    unusable input.
    """
    require_choice("robot.units", units, UNITS)
    note = _Notes(f"link {name!r}" + (f" ({source})" if source else ""), list(notes))
    v, f = _checked_arrays(note.where, vertices, faces)
    v = _in_metres(v, f, units, note)
    extent = float((v.max(axis=0) - v.min(axis=0)).max())
    if extent <= 0:
        raise MeshError(f"{note.where}: all vertices coincide")
    lo, hi = PLAUSIBLE_EXTENT_M
    if plausible and not lo <= extent <= hi:
        raise MeshError(
            f"{note.where}: its largest extent is {extent:.3g} m with robot.units={units}, outside a robot link's "
            f"{lo * 100:g} cm to {hi:g} m: set robot.units to the file's units (m, cm or mm)"
        )
    v, f = _merge_vertices(v, f, extent, note)
    f = _drop_bad_faces(v, f, extent, note)
    v, f = _drop_unused_vertices(v, f, note)
    # a skin needs a 3-D surface: a flat mesh (one triangle, a planar sheet) has no inside or axis
    centred = v - v.mean(axis=0)
    thickness = float(np.linalg.svd(centred, compute_uv=False)[-1] / np.sqrt(len(v)))
    if thickness <= extent * 1e-6:
        raise MeshError(
            f"{note.where}: the mesh is flat ({len(f)} face(s), all {len(v)} vertices in one plane); a link needs a "
            "3-D surface, e.g. its closed collision mesh or convex hull"
        )
    closed = is_closed(f)
    f = _orient_closed(v, f, note) if closed else _orient_open(v, f, extent, note)
    return Link(name=name, vertices=v, faces=f, watertight=closed, notes=tuple(note.notes))


@dataclass
class _Notes:
    """What validating one mesh found and did: ``where`` names the mesh in errors and the log."""

    where: str
    notes: list[str]

    def __call__(self, msg: str, level: int = logging.INFO) -> None:
        """Keep ``msg`` for ``Link.notes`` and log it at ``level``."""
        self.notes.append(msg)
        log.log(level, "%s: %s", self.where, msg)


def _checked_arrays(where: str, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (V, 3) float64, faces (F, 3) int64)`` once their shapes, indices and values are usable;
    :class:`MeshError` naming ``where`` otherwise."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise MeshError(f"{where}: vertices must have shape (V, 3) with V > 0, got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise MeshError(f"{where}: faces must be triangles of shape (F, 3) with F > 0, got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.all(np.mod(f, 1) == 0):
            raise MeshError(f"{where}: face indices must be integers")
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"{where}: face indices must lie in [0, {len(v)}), found {f.min()}..{f.max()}")
    bad_v = ~np.isfinite(v).all(axis=1)
    if bad_v.any():
        raise MeshError(f"{where}: {int(bad_v.sum())} vertices are NaN/inf (first at index {int(np.argmax(bad_v))})")
    return v, f


def _in_metres(v: np.ndarray, f: np.ndarray, units: str, note: _Notes) -> np.ndarray:
    """The vertices ``v`` (file units) in metres by ``units`` (see :func:`make_link`); :class:`MeshError`
    when ``auto`` cannot tell."""
    extent = float((v.max(axis=0) - v.min(axis=0)).max())
    if units in UNIT_SCALE:
        note(f"scaled by {UNIT_SCALE[units]:g} (units={units})")
        return v * UNIT_SCALE[units]
    if units == "auto" and extent > MM_EXTENT_THRESHOLD_M:
        return _auto_millimetres(v, f, extent, note)
    if extent > MM_EXTENT_THRESHOLD_M:
        note(f"largest extent {extent:g} m with units=m: kept; is it in millimetres?", logging.WARNING)
    return v


def _auto_millimetres(v: np.ndarray, f: np.ndarray, extent: float, note: _Notes) -> np.ndarray:
    """``units=auto`` for a mesh ``extent`` (file units) across, over the threshold: ``v`` scaled from mm
    to metres when its major parts agree it is in millimetres; :class:`MeshError` when they disagree, or
    when the main part reads as metres (or may be centimetres)."""
    where = note.where
    parts = component_extents(v, f)
    main_faces, main_extent = parts[0]
    major = [(n, e) for n, e in parts if n >= MAJOR_COMPONENT_FRACTION * len(f)]
    if len({e > MM_EXTENT_THRESHOLD_M for _, e in major}) > 1:
        sizes = ", ".join(f"{n} faces {e:.3g} across" for n, e in major)
        raise MeshError(
            f"{where}: units are ambiguous: its major parts ({sizes}) read as both metres and millimetres "
            f"(threshold {MM_EXTENT_THRESHOLD_M:g}); set robot.units=m or robot.units=mm"
        )
    if main_extent <= MM_EXTENT_THRESHOLD_M:  # metres by its main part, yet over 5 m across: a stray part
        raise MeshError(
            f"{where}: its main part ({main_faces} of {len(f)} faces, {main_extent:.3g} across) reads as metres "
            f"but {len(parts) - 1} other part(s) stretch the mesh to {extent:.3g} across: a stray part far from "
            f"the link? Remove it from the file, or set robot.units=m to use the mesh as it is (robot.units=mm "
            f"if it is in millimetres)"
        )
    if main_extent * 1e-3 < AMBIGUOUS_MM_BELOW_M:
        raise MeshError(
            f"{where}: units are ambiguous: its main part is {main_extent:.3g} across, "
            f"{main_extent * 1e-3 * 100:.3g} cm as millimetres (a small link) or {main_extent:.3g} cm as "
            f"centimetres; set robot.units=mm or robot.units=cm"
        )
    note(
        f"largest extent {main_extent:g} of its main part > {MM_EXTENT_THRESHOLD_M:g} m: taken as millimetres "
        f"and scaled by 0.001 (set units=m to keep it)",
        logging.WARNING,
    )
    return v * 1e-3


def _merge_vertices(v: np.ndarray, f: np.ndarray, extent: float, note: _Notes) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` with duplicate vertices (equal after rounding to 1e-9 of ``extent``, metres)
    merged, the first occurrences kept in their order."""
    key = np.round(v / (extent * 1e-9)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    if len(first) < len(v):
        note(f"merged {len(v) - len(first)} duplicate vertices")
    order = np.argsort(first)  # keep the original order of first occurrences
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return v[first[order]], rank[inverse[f]]


def _drop_bad_faces(v: np.ndarray, f: np.ndarray, extent: float, note: _Notes) -> np.ndarray:
    """The faces without degenerate ones (a repeated vertex, or an area at most (1e-7 ``extent``)^2, m^2) and
    duplicates (same vertex set, either winding: the first kept); :class:`MeshError` when none is left."""
    _, area = triangle_normals_areas(v, f)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    degenerate = repeated | (area <= (extent * 1e-7) ** 2)
    if degenerate.any():
        note(f"removed {int(degenerate.sum())} degenerate faces (repeated vertex or zero area)")
        f = f[~degenerate]
    if len(f) == 0:
        raise MeshError(f"{note.where}: no faces left after removing degenerate ones")
    _, keep = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    if len(keep) < len(f):
        note(f"removed {len(f) - len(keep)} duplicate faces")
        f = f[np.sort(keep)]
    return f


def _drop_unused_vertices(v: np.ndarray, f: np.ndarray, note: _Notes) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` without the vertices no face uses (faces renumbered)."""
    used = np.zeros(len(v), dtype=bool)
    used[f.ravel()] = True
    if not used.all():
        note(f"removed {int((~used).sum())} unreferenced vertices")
        remap = np.cumsum(used) - 1
        v = v[used]
        f = remap[f]
    return v, f


def _orient_closed(v: np.ndarray, f: np.ndarray, note: _Notes) -> np.ndarray:
    """The faces of a closed mesh wound consistently, enclosing a positive volume."""
    import trimesh

    before = f.copy()
    mesh = trimesh.Trimesh(v, f, process=False)
    trimesh.repair.fix_normals(mesh, multibody=True)
    f = np.asarray(mesh.faces, dtype=np.int64)
    if signed_volume(v, f) < 0:
        f = f[:, ::-1].copy()
    changed = int((f != before).any(axis=1).sum())
    if changed:
        note(f"closed mesh: re-oriented {changed} faces outward (consistent winding, positive volume)")
    return f


def _orient_open(v: np.ndarray, f: np.ndarray, extent: float, note: _Notes) -> np.ndarray:
    """The faces of an open mesh (``extent`` metres across) oriented outward (see the module docstring);
    its holes are noted, with a warning when it looks damaged."""
    nb, nm = edge_defects(f)
    n_edges = len(np.unique(_edges_sorted(f), axis=0))
    share = nb / max(n_edges, 1)
    what = f"{nb} of {n_edges} edges ({share:.1%}) are boundary edges (holes)" + (
        f", {nm} shared by more than two faces" if nm else ""
    )
    damaged = share > DAMAGED_BOUNDARY_SHARE or nm > 0
    note(
        f"not closed: {what}; kept as is (watertight=False)"
        + ("; the mesh looks damaged (faces missing?)" if damaged else ""),
        logging.WARNING if damaged else logging.INFO,
    )
    normals, _ = triangle_normals_areas(v, f)
    convex, inner = _on_convex_hull(v, f, tol=extent * CONVEX_TOL)
    if convex:
        away = np.einsum("ij,ij->i", normals, v[f].mean(axis=1) - inner) < 0
        if away.any():
            f[away] = f[away][:, ::-1]
            note(f"open (near-)convex surface: turned {int(away.sum())} inward faces away from its interior")
        return f
    import trimesh

    before = f.copy()
    mesh = trimesh.Trimesh(v, f, process=False)
    if not mesh.is_winding_consistent:
        trimesh.repair.fix_winding(mesh)
        f = np.asarray(mesh.faces, dtype=np.int64).copy()
    normals, area = triangle_normals_areas(v, f)
    centroid = (v[f].mean(axis=1) * area[:, None]).sum(axis=0) / area.sum()
    outward = np.einsum("ij,ij->i", normals, v[f].mean(axis=1) - centroid)
    if float((np.sign(outward) * area).sum()) < 0:  # most area faces the centroid: inverted
        f = f[:, ::-1].copy()
    changed = int((f != before).any(axis=1).sum())
    if changed:
        note(f"open surface: re-oriented {changed} faces (consistent winding, most area facing away from the centroid)")
    return f


def load_mesh_file(path, name: str, units: str = "auto", key: str = "") -> Link:
    """Read a mesh file (obj, stl, ply, dae, ...) into a validated :class:`Link`.

    ``key`` names the config entry in errors (e.g. ``robot.links.l_arm``).
    Scenes (several meshes, e.g. COLLADA) are flattened with their transforms.
    """
    from pathlib import Path

    path = Path(path)
    label = f"{key}: " if key else ""
    if not path.is_file():
        raise FileNotFoundError(f"{label}mesh file not found: {path}")
    loaded = read_mesh(path, label)
    return make_link(name, loaded.vertices, loaded.faces, units=units, source=str(path), plausible=True)


def read_mesh(path, label: str = "") -> trimesh.Trimesh:
    """The triangles of a mesh file (as stored, unprocessed; scenes flattened), or a :class:`MeshError`
    that names the file (``label`` first, e.g. ``"link 'arm': "``): the one reader of mesh files."""
    import trimesh

    try:
        loaded = trimesh.load(str(path), process=False, force="mesh")
    except Exception as exc:
        raise MeshError(f"{label}cannot read mesh file {path}: {exc}") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f"{label}mesh file {path} holds no triangles")
    return loaded
