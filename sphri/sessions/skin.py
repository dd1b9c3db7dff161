"""A skin design from the whole-body study: patches, the budget curve, and a patch export a lab can build from.

Patches. Each body part's reachable elements (:attr:`BodySurface.reachable`)
are split into patches of about ``patch_cm2`` by k-means (farthest-point
seeds, Lloyd steps; deterministic) on their link-frame positions and normals (a part smaller than one patch is one patch), so a
placement can take a region within a part instead of the whole part.

Budget curve. A contact frame is *captured* when it touches a chosen patch.
:func:`greedy_patches` adds patches by the most not-yet-captured frames per
cm^2 (within an area budget, or without one for the curve; patches that
capture nothing new come last, smallest first). The curve is the captured
share against the cumulative area (cm^2) and against taxels at a pitch
(area / pitch^2), in-sample (chosen and scored on the same frames: with
every patch taken it ends at the share of frames touching mountable surface)
and held-out: participants are split in half at
random ``heldout_splits`` times; each half's order scores the other half's
frames, and the curve is the mean (and SD) over the 2 x ``heldout_splits``
scorings, per scenario and pooled.

Export. The pooled design under the study's budget, per link: each chosen
patch as PLY meshes in the link's frame (the link's mesh subdivided to edges
of at most the element spacing, each face given the patch of its nearest
element), one per connected piece of the patch on the surface
(:func:`connected_pieces`: shells that touch are one piece; pieces below the
study's ``min_patch_cm2`` are dropped and counted), with its taxels at the
pitch (:func:`place_taxels`: positions and normals), and a manifest (JSON and
CSV): link, part, patch id, piece, mesh area (cm^2), taxels at the pitch, the
share of contact frames the patch touches alone and the share it adds in the
greedy order; the JSON also holds each piece's outline, its link's rest pose
and the links merged into that link.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import sparse

from sphri.sessions.body import BodySurface

#: Columns of ``budget_curve.csv``.
CURVE_COLUMNS = (
    "scenario",
    "curve",
    "area_cm2",
    "area_share",
    "taxels",
    "captured",
    "captured_sd",
    "n_frames",
    "n_splits",
)


@dataclass
class Patches:
    """Patches of the reachable surface."""

    of_element: np.ndarray
    """(P,) int64: patch of each element of the body surface, -1 where out of reach."""
    table: pd.DataFrame
    """Per patch (row = patch id): ``patch``, ``link``, ``part``, ``area_cm2`` (sampled), ``n_elements``."""

    @property
    def area_m2(self) -> np.ndarray:
        return self.table["area_cm2"].to_numpy(float) * 1e-4


def make_patches(body: BodySurface, patch_cm2: float, mountable: np.ndarray | None = None) -> Patches:
    """Split each body part's reachable elements (per link; only where ``mountable``, (P,) bool, when given) into
    patches of about ``patch_cm2``."""
    if not patch_cm2 > 0:
        raise ValueError(f"patch_cm2={patch_cm2} is invalid: must be > 0")
    of = np.full(body.samples.n, -1, dtype=np.int64)
    reach = body.reachable if mountable is None else body.reachable & np.asarray(mountable, dtype=bool)
    area_cm2 = body.samples.area_m2 * 1e4
    rows: list[dict[str, Any]] = []
    # normals weigh as much as half a patch's width: the two faces of a thin part fall into different patches
    normal_scale = 0.5 * np.sqrt(patch_cm2) * 1e-2
    for li, link in enumerate(body.links):
        sl = np.arange(body.offset[li], body.offset[li + 1])
        local = body.local[li]
        for part in sorted(set(body.part[sl])):
            idx = sl[(body.part[sl] == part) & reach[sl]]
            if idx.size == 0:
                continue
            a = float(area_cm2[idx].sum())
            k = int(min(max(1, round(a / patch_cm2)), idx.size))
            if k == 1:
                labels = np.zeros(idx.size, dtype=np.int64)
            else:
                j = idx - body.offset[li]
                x = np.hstack([local.points_m[j], normal_scale * local.normal[j]])
                labels = _kmeans(x, k)
            for c in np.unique(labels):
                members = idx[labels == c]
                of[members] = len(rows)
                rows.append(
                    dict(
                        patch=f"{part}#{len(rows)}",
                        link=link,
                        part=part,
                        area_cm2=float(area_cm2[members].sum()),
                        n_elements=int(members.size),
                    )
                )
    table = pd.DataFrame(rows, columns=["patch", "link", "part", "area_cm2", "n_elements"])
    return Patches(of, table)


def _kmeans(x: np.ndarray, k: int, iterations: int = 10) -> np.ndarray:
    """(n,) labels of ``k`` clusters of ``x (n, d)``: farthest-point seeds (deterministic), then Lloyd steps."""
    from scipy.spatial import cKDTree

    seeds = [0]
    d = np.linalg.norm(x - x[0], axis=1)
    for _ in range(1, k):
        seeds.append(int(np.argmax(d)))
        d = np.minimum(d, np.linalg.norm(x - x[seeds[-1]], axis=1))
    c = x[seeds]
    labels = np.zeros(len(x), dtype=np.int64)
    for _ in range(iterations):
        new = cKDTree(c).query(x)[1]
        if np.array_equal(new, labels) and _ > 0:
            break
        labels = new
        n = np.bincount(labels, minlength=k)
        keep = n > 0
        c = (
            np.stack([np.bincount(labels, x[:, j], minlength=k) for j in range(x.shape[1])], axis=1)[keep]
            / n[keep, None]
        )
        labels = np.unique(labels, return_inverse=True)[1]  # empty clusters dropped, labels 0..k'-1
        k = int(keep.sum())
    return labels


def frame_patch_matrix(
    frames: np.ndarray,
    elements: np.ndarray,
    of_element: np.ndarray,
    n_patches: int,
    counted: np.ndarray | None = None,
) -> tuple[np.ndarray, sparse.csr_matrix]:
    """(unique frames (U,), (U, n_patches) CSR of ones) from (frame, element) pairs. The frames are those touching
    an element where ``counted`` ((P,) bool; default: elements in a patch), so a frame touching only surface no
    patch holds (a joint shell) is a row of zeros: captured by no skin."""
    p = of_element[elements]
    c = p >= 0 if counted is None else np.asarray(counted, dtype=bool)[elements] | (p >= 0)
    uf, inv = np.unique(frames[c], return_inverse=True)
    keep = p[c] >= 0
    inv, p = inv[keep], p[c][keep]
    m = sparse.csr_matrix((np.ones(inv.size, dtype=np.float64), (inv, p)), shape=(uf.size, n_patches))
    m.data[:] = 1.0  # duplicates were summed by the constructor (its conversion to CSR sums them)
    return uf, m


def greedy_patches(
    m: sparse.csr_matrix, area_m2: np.ndarray, budget_m2: float = np.inf
) -> tuple[np.ndarray, np.ndarray]:
    """(order of patches, frames newly captured by each) by not-yet-captured frames per m^2 within ``budget_m2``.

    Without a budget every patch is ordered (those adding nothing last, smallest first); with one, only the
    patches chosen (a patch that does not fit is passed over for smaller ones, as in
    :func:`sphri.sessions.placement.greedy_parts`).
    """
    area = np.asarray(area_m2, dtype=np.float64)
    n_frames, k = m.shape
    mc = m.tocsc()
    gain = np.asarray(m.sum(axis=0)).ravel()
    covered = np.zeros(n_frames, dtype=bool)
    chosen = np.zeros(k, dtype=bool)
    order, new_counts = [], []
    left = float(budget_m2)
    while True:
        ratio = np.where(~chosen & (gain > 0) & (area <= left + 1e-12), gain / np.maximum(area, 1e-12), -1.0)
        j = int(np.argmax(ratio)) if k else 0
        if k == 0 or ratio[j] <= 0:
            break
        rows = mc.indices[mc.indptr[j] : mc.indptr[j + 1]]
        new = rows[~covered[rows]]
        covered[new] = True
        chosen[j] = True
        left -= float(area[j])
        order.append(j)
        new_counts.append(new.size)
        if new.size:  # the patches those frames touch lose them from their gain
            gain -= np.bincount(m.indices[_row_slots(m.indptr, new)], minlength=k)
    if np.isinf(budget_m2):
        rest = np.flatnonzero(~chosen)
        rest = rest[np.lexsort((rest, area[rest]))]
        order += rest.tolist()
        new_counts += [0] * rest.size
    return np.asarray(order, dtype=np.int64), np.asarray(new_counts, dtype=np.int64)


def _row_slots(indptr: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Positions in a CSR matrix's ``indices`` of the entries of ``rows``."""
    start, n = indptr[rows], indptr[rows + 1] - indptr[rows]
    total = int(n.sum())
    return np.repeat(start - np.r_[0, np.cumsum(n)[:-1]], n) + np.arange(total)


def first_rank(m: sparse.csr_matrix, order: np.ndarray) -> np.ndarray:
    """(U,) per frame, the position in ``order`` of the first patch it touches (``len(order)`` if none)."""
    k = m.shape[1]
    rank = np.full(k, len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    out = np.full(m.shape[0], len(order), dtype=np.int64)
    nz = np.diff(m.indptr) > 0
    if nz.any():
        out[nz] = np.minimum.reduceat(rank[m.indices], m.indptr[:-1][nz])
    return out


def _captured_curve(train: sparse.csr_matrix, test: sparse.csr_matrix, area: np.ndarray, grid: np.ndarray):
    """Share of ``test``'s frames captured at each grid area by the patches in ``train``'s greedy order."""
    order, _ = greedy_patches(train, area)
    rank = first_rank(test, order)
    cap = np.r_[0, np.cumsum(np.bincount(rank, minlength=len(order) + 1)[: len(order)])] / rank.size
    # at each grid area, the share of the longest prefix whose area fits (a step function)
    fits = np.searchsorted(np.r_[0.0, np.cumsum(area[order])], grid * (1 + 1e-9) + 1e-12, side="right")
    return cap[fits - 1]


def _halves(rng: np.random.Generator, unit: np.ndarray, splits: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(train, test) frame masks: the participants (``unit`` per frame) split in half at random ``splits`` times,
    each half choosing for the other (none with fewer than two participants; no empty half)."""
    units = np.asarray(pd.unique(unit))
    for _ in range(splits if units.size >= 2 else 0):
        in_a = np.isin(unit, rng.permutation(units)[: units.size // 2])
        for train, test in ((in_a, ~in_a), (~in_a, in_a)):
            if train.any() and test.any():
                yield train, test


def budget_curves(
    m: sparse.csr_matrix,
    frame_group: np.ndarray,
    frame_unit: np.ndarray,
    groups: list[str],
    area_m2: np.ndarray,
    pitch_mm: float,
    n_points: int = 101,
    heldout_splits: int = 10,
    seed: int = 0,
) -> pd.DataFrame:
    """``budget_curve.csv``: per group (``all`` first) the in-sample and held-out curves on one area grid."""
    area = np.asarray(area_m2, dtype=np.float64)
    total = float(area.sum())
    # evenly spaced areas, and log-spaced ones from the smallest patch (the curve rises fastest there)
    small = float(area[area > 0].min()) if (area > 0).any() else total
    grid = (
        np.unique(np.r_[np.linspace(0.0, total, n_points), np.geomspace(small, total, n_points)])
        if total > 0
        else np.zeros(1)
    )
    rng = np.random.default_rng(seed)
    rows = []

    def add(group, curve, cap, sd, n_frames, n_splits):
        rows.append(
            pd.DataFrame(
                {
                    "scenario": group,
                    "curve": curve,
                    "area_cm2": grid * 1e4,
                    "area_share": grid / total if total else 0.0,
                    "taxels": np.floor(grid * 1e6 / pitch_mm**2 + 1e-9).astype(np.int64),
                    "captured": cap,
                    "captured_sd": sd,
                    "n_frames": n_frames,
                    "n_splits": n_splits,
                }
            )
        )

    for g in ["all"] + list(groups):
        sel = np.ones(m.shape[0], bool) if g == "all" else frame_group == g
        mg, ug = m[np.flatnonzero(sel)], frame_unit[sel]
        n = mg.shape[0]
        if n == 0:
            continue
        add(g, "in_sample", _captured_curve(mg, mg, area, grid), np.nan, n, 0)
        scores = [
            _captured_curve(mg[np.flatnonzero(train)], mg[np.flatnonzero(test)], area, grid)
            for train, test in _halves(rng, ug, heldout_splits)
        ]
        if scores:
            s = np.stack(scores)
            add(g, "heldout", s.mean(axis=0), s.std(axis=0, ddof=1) if len(s) > 1 else np.nan, n, len(s))
    return pd.concat(rows, ignore_index=True)[list(CURVE_COLUMNS)] if rows else pd.DataFrame(columns=CURVE_COLUMNS)


def patch_placement(
    m: sparse.csr_matrix,
    frame_group: np.ndarray,
    frame_unit: np.ndarray,
    groups: list[str],
    patches: Patches,
    budget_m2: float,
    heldout_splits: int = 10,
    seed: int = 0,
) -> pd.DataFrame:
    """Per group (``all`` first): the patches chosen under the budget, their area, in-sample and held-out capture
    (half the participants choose, the other half is scored; mean over 2 x ``heldout_splits``)."""
    area = patches.area_m2
    total = float(area.sum())
    rng = np.random.default_rng(seed)
    rows = []
    for g in ["all"] + list(groups):
        sel = np.flatnonzero(np.ones(m.shape[0], bool) if g == "all" else frame_group == g)
        mg, ug = m[sel], frame_unit[sel]
        order, new = greedy_patches(mg, area, budget_m2)
        n = mg.shape[0]
        held = []
        for train, test in _halves(rng, ug, heldout_splits):
            o, _ = greedy_patches(mg[np.flatnonzero(train)], area, budget_m2)
            held.append(float((first_rank(mg[np.flatnonzero(test)], o) < len(o)).mean()))
        chosen_parts = patches.table["part"].to_numpy()[order]
        rows.append(
            dict(
                group=g,
                n_contact_frames=int(n),
                n_patches=int(order.size),
                patches=";".join(patches.table["patch"].to_numpy()[order]),
                parts=";".join(dict.fromkeys(chosen_parts.tolist())),
                area_cm2=float(area[order].sum() * 1e4),
                area_share=float(area[order].sum() / total),
                captured=float(new.sum() / n) if n else np.nan,
                heldout_captured=float(np.mean(held)) if held else np.nan,
                heldout_sd=float(np.std(held, ddof=1)) if len(held) > 1 else np.nan,
                n_heldout=len(held),
            )
        )
    return pd.DataFrame(rows)


def _face_patches(
    body: BodySurface, li: int, vertices: np.ndarray, faces: np.ndarray, of_element: np.ndarray
) -> np.ndarray:
    """(F,) patch of each face (link frame): that of the nearest element on the same side (normals agree)."""
    s = body.local[li]
    tri = vertices[faces]
    cen = tri.mean(axis=1)
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-18)
    k = min(8, s.n)
    _, nb = s.tree.query(cen, k=k)
    nb = nb.reshape(len(cen), k)
    agree = np.einsum("fkd,fd->fk", s.normal[nb], nrm) > 0.0
    pick = np.where(agree.any(axis=1), np.argmax(agree, axis=1), 0)
    return of_element[body.offset[li] + nb[np.arange(len(cen)), pick]]


#: Two pieces of a patch closer than this (m) on the surface touch: shells of a multi-shell mesh that meet are one.
TOUCH_M = 1e-3


def connected_pieces(vertices: np.ndarray, faces: np.ndarray, touch_m: float = TOUCH_M) -> list[np.ndarray]:
    """Face indices of each connected piece of a triangle surface, largest area first. Faces connect through a
    shared vertex once vertices within ``touch_m`` are merged, and two pieces connect where a vertex of one lies
    within ``touch_m`` of the other's surface (shells that touch without sharing vertices)."""
    import trimesh
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return []
    used = np.unique(f)
    # vertices within touch_m are one vertex
    pairs = cKDTree(v[used]).query_pairs(touch_m, output_type="ndarray")
    nv = used.size
    g = sparse.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(nv, nv)) if len(pairs) else None
    canon = connected_components(g, directed=False)[1] if g is not None else np.arange(nv)
    vid = np.full(len(v), -1, dtype=np.int64)
    vid[used] = canon
    ff = vid[f]
    nc = int(ff.max()) + 1
    # faces sharing a (merged) vertex: components of the face-vertex incidence graph
    rows = np.repeat(np.arange(len(ff)), 3)
    inc = sparse.coo_matrix((np.ones(rows.size), (rows, ff.ravel())), shape=(len(ff), nc)).tocsr()
    lab = connected_components(sparse.bmat([[None, inc], [inc.T, None]]), directed=False)[1]
    lab = lab[: len(ff)]
    pieces = [np.flatnonzero(lab == k) for k in np.unique(lab)]
    if len(pieces) > 1:  # pieces whose surfaces touch
        boxes = [
            (v[f[p]].reshape(-1, 3).min(axis=0) - touch_m, v[f[p]].reshape(-1, 3).max(axis=0) + touch_m) for p in pieces
        ]
        join = []
        for i in range(len(pieces)):
            vi = v[np.unique(f[pieces[i]])]
            for j in range(len(pieces)):
                if i == j or np.any(boxes[i][0] > boxes[j][1]) or np.any(boxes[j][0] > boxes[i][1]):
                    continue
                mj = trimesh.Trimesh(v, f[pieces[j]], process=False)
                if (mj.nearest.on_surface(vi)[1] <= touch_m).any():
                    join.append((i, j))
        if join:
            joined = np.asarray(join)
            k = len(pieces)
            comp = connected_components(
                sparse.coo_matrix((np.ones(len(joined)), (joined[:, 0], joined[:, 1])), shape=(k, k)), directed=False
            )[1]
            pieces = [np.concatenate([pieces[i] for i in range(k) if comp[i] == c]) for c in np.unique(comp)]
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return sorted(pieces, key=lambda p: -float(area[p].sum()))


def place_taxels(mesh, pitch_mm: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(T, 3) taxel positions on a patch's surface (its frame, metres), no two closer than ``pitch_mm``, and their
    (T, 3) outward unit normals (of the faces they lie on): a dense random sample of the surface thinned greedily
    (Poisson-disk-like even spacing)."""
    import trimesh

    pitch_m = float(pitch_mm) * 1e-3
    n = max(1, int(np.ceil(mesh.area / pitch_m**2)))
    pts, face = trimesh.sample.sample_surface(mesh, 30 * n, seed=seed)
    keep = _thin(pts, pitch_m)
    nrm = np.asarray(mesh.face_normals)[face[keep]]
    return pts[keep], nrm


def _thin(points: np.ndarray, radius: float) -> np.ndarray:
    """Indices of a subset of ``points`` (in their order) with no two closer than ``radius``; each point left out
    lies within ``radius`` of one kept."""
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    free = np.ones(len(points), dtype=bool)
    keep = []
    for i in range(len(points)):
        if free[i]:
            keep.append(i)
            free[tree.query_ball_point(points[i], radius * (1 - 1e-9))] = False
    return np.asarray(keep, dtype=np.int64)


def patch_outline(mesh) -> list[np.ndarray]:
    """The boundary loops of a patch (each (n, 3), metres): edges held by one face, chained; none for a closed
    surface."""
    if len(mesh.faces) == 0:
        return []
    try:
        return [np.asarray(x) for x in mesh.outline().discrete]
    except (ValueError, IndexError):  # a boundary that does not chain into loops: its edges as segments
        from trimesh.grouping import group_rows

        e = mesh.edges_sorted
        return [mesh.vertices[e[i]] for i in group_rows(e, require_count=1)]


def export_patches(
    body: BodySurface,
    robot,
    patches: Patches,
    order: np.ndarray,
    m: sparse.csr_matrix,
    new_counts: np.ndarray,
    pitch_mm: float,
    out_dir: Path,
    fmt: str = "ply",
    min_piece_cm2: float = 0.0,
) -> list[Path]:
    """Write ``out_dir/<link>__<piece>.<fmt>`` per connected piece of each chosen patch (link frame) and
    ``manifest.json`` / ``.csv``. A patch whose faces form several pieces (:func:`connected_pieces`) is exported
    as its pieces of at least ``min_piece_cm2``, named ``<patch>_1``, ``<patch>_2`` (largest first); smaller
    pieces are dropped and counted. The contact shares of a piece are those of the patch it was cut from.

    Per piece also ``<link>__<piece>_taxels.csv``: taxels at ``pitch_mm`` (:func:`place_taxels`: positions and
    outward normals, link frame, metres), and in ``manifest.json`` its outline (:func:`patch_outline`), the link's
    pose at the rest pose it was cut at (4 x 4, world frame) and the links merged into that link."""
    out_dir.mkdir(parents=True, exist_ok=True)
    n_frames = max(m.shape[0], 1)
    ex = _Export(
        out_dir=out_dir,
        fmt=fmt,
        pitch_mm=pitch_mm,
        min_piece_cm2=min_piece_cm2,
        n_frames=n_frames,
        alone=np.asarray(m.sum(axis=0)).ravel() / n_frames,
        new_counts=new_counts,
        rank={int(p): i for i, p in enumerate(order)},
        rest=robot.rest_poses() if hasattr(robot, "rest_poses") else None,
        tree_links=list(robot.tree.links) if getattr(robot, "tree", None) is not None else [],
    )
    chosen = set(order.tolist())
    for li, link_name in enumerate(body.links):
        mine = [int(p) for p in np.flatnonzero(patches.table["link"].to_numpy() == link_name) if int(p) in chosen]
        if mine:
            _export_link(ex, body, robot, patches, li, link_name, mine)
    man = _manifest_table(ex.rows)
    man.to_csv(out_dir / "manifest.csv", index=False, float_format="%.6g")
    meta = _manifest_meta(ex, man, int(m.shape[0]), robot.name)
    (out_dir / "manifest.json").write_text(json.dumps(meta, indent=1))
    return ex.files + [out_dir / "manifest.csv", out_dir / "manifest.json"]


@dataclass
class _Export:
    """The patch export's settings and what it has written so far (:func:`export_patches`)."""

    out_dir: Path
    fmt: str
    pitch_mm: float
    min_piece_cm2: float
    n_frames: int
    """Contact frames (at least 1)."""
    alone: np.ndarray
    """(P,) share of the contact frames each patch touches."""
    new_counts: np.ndarray
    """Frames each chosen patch adds, in the greedy order."""
    rank: dict[int, int]
    """Patch -> its place in the greedy order (0 first)."""
    rest: np.ndarray | None
    """(L, 4, 4) link poses at the rest pose (world), or None."""
    tree_links: list[str]
    rows: list[dict] = field(default_factory=list)
    """Manifest rows, one per piece."""
    files: list[Path] = field(default_factory=list)
    extra: dict[str, dict] = field(default_factory=dict)
    """Piece -> its outline, link rest pose and merged links (``manifest.json`` only)."""
    dropped: int = 0
    dropped_cm2: float = 0.0


def _export_link(ex: _Export, body: BodySurface, robot, patches: Patches, li: int, link_name: str, mine: list[int]):
    """Export the chosen patches ``mine`` of link ``link_name``: its mesh subdivided to edges of at most the element
    spacing, each face given the patch of its nearest element (:func:`_face_patches`), each patch cut into its
    connected pieces."""
    import trimesh
    from trimesh.remesh import subdivide_to_size

    link = robot.links[link_name]
    max_edge = max(float(body.samples.spacing_m), 1e-3)
    v, f = subdivide_to_size(np.asarray(link.vertices, float), np.asarray(link.faces), max_edge, max_iter=12)
    fp = _face_patches(body, li, v, f, patches.of_element)
    pose = ex.rest[ex.tree_links.index(link_name)] if ex.rest is not None and link_name in ex.tree_links else np.eye(4)
    merged = [c for c, r in getattr(robot, "skipped", ()) if str(r).startswith(f"merged into {link_name!r}")]
    for p in mine:
        row = patches.table.iloc[p]
        sel = f[fp == p]
        meshes = []
        for piece in connected_pieces(v, sel):
            mesh = trimesh.Trimesh(v, sel[piece], process=False)
            mesh.remove_unreferenced_vertices()
            if mesh.area * 1e4 < ex.min_piece_cm2:
                ex.dropped += 1
                ex.dropped_cm2 += float(mesh.area * 1e4)
            else:
                meshes.append(mesh)
        for k, mesh in enumerate(meshes):
            piece_name = f"{row['patch']}_{k + 1}" if len(meshes) > 1 else str(row["patch"])
            _export_piece(ex, mesh, p, row, link_name, piece_name, pose, merged)


def _export_piece(
    ex: _Export, mesh, p: int, row: pd.Series, link_name: str, piece_name: str, pose: np.ndarray, merged: list[str]
) -> None:
    """Write one piece of patch ``p`` (``row``: its row of the patch table): its mesh and its taxels at the pitch
    (link frame, m); add its manifest row and its outline, link pose at rest (``pose``, 4 x 4, world) and the
    links ``merged`` into its link."""
    from sphri.analysis.coverage import safe_name

    stem = f"{safe_name(link_name, 'x')}__{safe_name(piece_name, 'x')}"
    name = f"{stem}.{ex.fmt}"
    mesh.export(ex.out_dir / name)
    ex.files.append(ex.out_dir / name)
    area_cm2 = float(mesh.area * 1e4)
    pts, nrm = place_taxels(mesh, ex.pitch_mm, seed=p)
    tax_name = f"{stem}_taxels.csv"
    pd.DataFrame(np.hstack([pts, nrm]), columns=["x_m", "y_m", "z_m", "nx", "ny", "nz"]).to_csv(
        ex.out_dir / tax_name, index=False, float_format="%.6g"
    )
    ex.files.append(ex.out_dir / tax_name)
    ex.extra[piece_name] = {
        "outline_m": [np.round(loop, 6).tolist() for loop in patch_outline(mesh)],
        "link_pose_rest": np.round(pose, 9).tolist(),
        "merged_links": merged,
    }
    ex.rows.append(
        dict(
            link=link_name,
            part=row["part"],
            patch=row["patch"],
            piece=piece_name,
            file=name,
            order=ex.rank[p] + 1,
            area_cm2=area_cm2,
            sampled_area_cm2=float(row["area_cm2"]),
            taxels=int(np.floor(area_cm2 * 100.0 / ex.pitch_mm**2 + 1e-9)),
            taxels_placed=int(len(pts)),
            taxel_file=tax_name,
            share_captured_alone=float(ex.alone[p]),
            share_added=float(ex.new_counts[ex.rank[p]] / ex.n_frames),
            n_faces=int(len(mesh.faces)),
        )
    )


def _manifest_table(rows: list[dict]) -> pd.DataFrame:
    """The pieces in greedy order, with the cumulative share of contact frames captured (a patch's share counts
    once however many pieces it has)."""
    man = pd.DataFrame(rows)
    if len(man):
        man = man.sort_values(["order", "piece"]).reset_index(drop=True)
        first = ~man["patch"].duplicated()
        man["cumulative_share"] = (man["share_added"] * first).cumsum()
    return man


def _manifest_meta(ex: _Export, man: pd.DataFrame, n_contact_frames: int, robot_name: str) -> dict:
    """``manifest.json``: the export's totals (area cm^2, share captured, taxels), what was dropped, and the
    pieces' rows with their outlines, rest poses and merged links."""
    first = ~man["patch"].duplicated() if len(man) else None
    return {
        "frame": "each link's own frame (the robot description's link frame), metres",
        "pitch_mm": ex.pitch_mm,
        "n_contact_frames": n_contact_frames,
        "area_cm2": float(man["area_cm2"].sum()) if len(man) else 0.0,
        "captured": float(man["share_added"][first].sum()) if len(man) else 0.0,
        "taxels": int(man["taxels"].sum()) if len(man) else 0,
        "taxels_placed": int(man["taxels_placed"].sum()) if len(man) else 0,
        "min_piece_cm2": ex.min_piece_cm2,
        "dropped_pieces": ex.dropped,
        "dropped_area_cm2": ex.dropped_cm2,
        "robot": robot_name,
        "taxel_placement": "taxels no closer than pitch_mm on each piece's surface (x_m, y_m, z_m, nx, ny, nz "
        "in the link's frame); outline_m: the piece's boundary loops; link_pose_rest: the link's pose (world frame) "
        "at the rest pose the patches were cut at; merged_links: links joined into the link at that pose",
        "patches": [{**r, **ex.extra[r["piece"]]} for r in json.loads(man.to_json(orient="records"))],
    }


@dataclass
class SkinDesign:
    """The study's skin design (see the module docstring)."""

    patches: Patches
    frames: np.ndarray
    """(U,) contact frames touching reachable surface."""
    matrix: sparse.csr_matrix
    """(U, n_patches) frame touches patch."""
    curves: pd.DataFrame
    """``budget_curve.csv``."""
    placement: pd.DataFrame
    """``patch_placement.csv``: per group, the patches chosen under the budget."""
    order: np.ndarray
    """Patches of the pooled design under the budget, in the order chosen."""
    new_counts: np.ndarray
    """Frames each of them adds."""
    pitch_mm: float
    budget_m2: float

    @property
    def element_mask(self) -> np.ndarray:
        """(P,) bool: elements of the pooled design."""
        return np.isin(self.patches.of_element, self.order)


def skin_design(
    body: BodySurface,
    frames: np.ndarray,
    elements: np.ndarray,
    frame_session: np.ndarray,
    sessions: pd.DataFrame,
    scenarios: list[str],
    patch_cm2: float,
    pitch_mm: float,
    budget_m2: float,
    heldout_splits: int = 10,
    seed: int = 0,
    mountable: np.ndarray | None = None,
) -> SkinDesign:
    """Patches (on the ``mountable`` elements when given), budget curves and the patch-level placement from the
    study's (frame, element) pairs; a frame counts when it touches reachable surface."""
    patches = make_patches(body, patch_cm2, mountable)
    uf, m = frame_patch_matrix(frames, elements, patches.of_element, len(patches.table), body.reachable)
    f_scen = sessions["scenario"].to_numpy()[frame_session[uf]]
    f_unit = sessions["participant"].to_numpy()[frame_session[uf]]
    curves = budget_curves(
        m, f_scen, f_unit, scenarios, patches.area_m2, pitch_mm, heldout_splits=heldout_splits, seed=seed
    )
    placement = patch_placement(m, f_scen, f_unit, scenarios, patches, budget_m2, heldout_splits, seed)
    order, new = greedy_patches(m, patches.area_m2, budget_m2)
    return SkinDesign(patches, uf, m, curves, placement, order, new, float(pitch_mm), float(budget_m2))


def write_design(
    design: SkinDesign, body: BodySurface, robot, out: Path, fmt: str = "ply", min_piece_cm2: float = 0.0
) -> list[Path]:
    """``budget_curve.csv``, ``patches.csv``, ``patch_placement.csv`` and the ``skin_export/`` folder."""
    files = [out / "budget_curve.csv", out / "patches.csv", out / "patch_placement.csv"]
    design.curves.to_csv(files[0], index=False, float_format="%.6g")
    t = design.patches.table.copy()
    t["contact_frames"] = np.asarray(design.matrix.sum(axis=0)).ravel().astype(np.int64)
    t["frames_per_cm2"] = t["contact_frames"] / t["area_cm2"]
    t.to_csv(files[1], index_label="patch_id", float_format="%.6g")
    design.placement.to_csv(files[2], index=False, float_format="%.6g")
    files += export_patches(
        body,
        robot,
        design.patches,
        design.order,
        design.matrix,
        design.new_counts,
        design.pitch_mm,
        out / "skin_export",
        fmt,
        min_piece_cm2,
    )
    return files
