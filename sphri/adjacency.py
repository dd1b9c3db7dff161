"""Taxel adjacency: which taxels of a skin are neighbours, one definition for every stage.

Noise (crosstalk), the Random Forest's features (largest connected contact)
and the live classifier (touch clusters) all ask the same question; this
module answers it once, from a :class:`~sphri.types.TaxelGeometry`:

- **Grids** (``grid_shape`` set, row-major H x W, rows along u): taxels that
  share an edge (4-neighbours, ``diagonal=False``) or an edge or a corner
  (8-neighbours, ``diagonal=True``); the first and last columns are
  neighbours when v wraps around the link.
- **Other layouts**: taxels closer than :data:`NEIGHBOUR_RADIUS` times the
  median nearest-neighbour spacing, measured in :func:`metric_coords`
  (the chart's metres, periodic around a wrapping link; without a chart, the
  two principal axes of the 3-D positions). ``diagonal`` does not apply.

:class:`Adjacency` holds the pairs and answers the two questions the stages
ask: each taxel's neighbour list (:meth:`Adjacency.table`), the summed
weight of each frame's largest connected group of touched taxels
(:meth:`Adjacency.largest_component`) and, per touched taxel, the summed
weight of the group it belongs to (:meth:`Adjacency.component_weight`, what
the spatial skin filter ``filter=despeckle`` thresholds). On grids both go
through ``scipy.ndimage.label`` (one label call for all frames, labels
joined across the v seam), which is faster than the general graph path and
gives the same components.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from sphri.types import TaxelGeometry

#: Neighbour radius of non-grid layouts, in median nearest-neighbour spacings.
NEIGHBOUR_RADIUS = 1.5


@dataclass(frozen=True)
class MetricCoords:
    """Taxel positions in metres on the skin's 2-D chart."""

    a_m: np.ndarray
    """(N,) float64 position along the link (metres)."""
    b_m: np.ndarray
    """(N,) float64 position around the link (metres; in [0, circumference) when wrapping)."""
    circumference_m: float
    """Period of ``b_m`` in metres (0 when b does not wrap)."""
    full_a_m: float
    """Length of the chart along a (metres; 0 without a chart)."""
    full_b_m: float
    """Length of the chart along b (metres; 0 without a chart)."""


def metric_coords(geometry: TaxelGeometry) -> MetricCoords:
    """Chart coordinates of the taxels in metres; the principal axes of ``position_m`` without a chart.

    Raises ``ValueError`` naming the field on shapes that do not agree or
    non-finite values.
    """
    pos = np.asarray(geometry.position_m, dtype=np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] < 1:
        raise ValueError(f"geometry.position_m must be (N, 3) with N >= 1, got shape {pos.shape}")
    n = pos.shape[0]
    grid = geometry.grid_shape
    if grid is not None and (int(grid[0]) < 1 or int(grid[1]) < 1 or int(grid[0]) * int(grid[1]) != n):
        raise ValueError(f"geometry.grid_shape={tuple(grid)} does not hold the {n} taxels of geometry.position_m")
    if has_chart(geometry):
        uv = np.asarray(geometry.uv, dtype=np.float64)
        if uv.shape != (n, 2):
            raise ValueError(f"geometry.uv must be (N, 2) = ({n}, 2), got shape {uv.shape}")
        if not np.all(np.isfinite(uv)):
            raise ValueError("geometry.uv holds NaN or infinite values")
        wrap = bool(geometry.wrap_v)
        a = uv[:, 0] * geometry.metres_per_u
        b = (np.mod(uv[:, 1], 1.0) if wrap else uv[:, 1]) * geometry.metres_per_v
        circ = float(geometry.metres_per_v) if wrap else 0.0
        return MetricCoords(a, b, circ, float(geometry.metres_per_u), float(geometry.metres_per_v))
    if not np.all(np.isfinite(pos)):
        raise ValueError("geometry.position_m holds NaN or infinite values")
    centred = pos - pos.mean(axis=0)
    axes = np.zeros((2, 3))
    if n > 1:
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        axes[: min(2, vt.shape[0])] = vt[:2]
    return MetricCoords(centred @ axes[0], centred @ axes[1], 0.0, 0.0, 0.0)


def has_chart(geometry: TaxelGeometry) -> bool:
    """Whether the layout has chart coordinates with a metric scale."""
    return geometry.uv is not None and geometry.metres_per_u > 0 and geometry.metres_per_v > 0


@dataclass(frozen=True)
class Adjacency:
    """Neighbouring taxel pairs of one skin (see the module docstring for the rule)."""

    n_taxels: int
    pairs: np.ndarray
    """(E, 2) int64 neighbour pairs, i < j, each once."""
    grid_shape: tuple[int, int] | None
    """(H, W) of a grid layout (the fast component path), else None."""
    wrap_v: bool
    """Grid columns 0 and W-1 are neighbours (v wraps)."""
    diagonal: bool
    """Grids: corner-sharing taxels are neighbours too (8-connectivity)."""
    spacing_m: float
    """Median nearest-neighbour distance of a non-grid layout (metres, or chart units); 0 on grids."""

    def table(self) -> np.ndarray:
        """(N, K) int64 neighbours of each taxel, -1 where a taxel has fewer than K (K >= 1)."""
        n = self.n_taxels
        both = np.concatenate([self.pairs, self.pairs[:, ::-1]]) if self.pairs.size else np.zeros((0, 2), np.int64)
        both = both[np.lexsort((both[:, 1], both[:, 0]))]
        counts = np.bincount(both[:, 0], minlength=n)
        k = max(1, int(counts.max()) if n else 1)
        out = np.full((n, k), -1, dtype=np.int64)
        start = np.concatenate([[0], np.cumsum(counts)[:-1]])
        slot = np.arange(both.shape[0]) - start[both[:, 0]]
        out[both[:, 0], slot] = both[:, 1]
        return out

    def largest_component(self, weights: np.ndarray) -> np.ndarray:
        """(M,) float64 summed weight of each frame's largest connected group of taxels with weight > 0.

        ``weights`` (M, N) non-negative per-frame taxel weights (1 for
        touched taxels of a binary skin: the group's size).
        """
        w = np.asarray(weights, dtype=np.float64)
        if w.ndim != 2 or w.shape[1] != self.n_taxels:
            raise ValueError(f"weights must be (frames, {self.n_taxels}), got shape {w.shape}")
        if self.grid_shape is not None:
            return _largest_component_grid(w, self.grid_shape, self.wrap_v, self.diagonal)
        return _largest_component_graph(w, self.pairs)

    def component_weight(self, active: np.ndarray, taxel_weight: np.ndarray) -> np.ndarray:
        """(M, N) float64: for each active taxel, the summed ``taxel_weight`` of its frame's connected group.

        ``active`` (M, N) bool touched taxels per frame; ``taxel_weight`` (N,)
        per-taxel weight (a taxel's area in m^2: the group's area). 0 where a
        taxel is not active. Groups never span frames.
        """
        act = np.asarray(active, dtype=bool)
        tw = np.asarray(taxel_weight, dtype=np.float64)
        if act.ndim != 2 or act.shape[1] != self.n_taxels:
            raise ValueError(f"active must be (frames, {self.n_taxels}), got shape {act.shape}")
        if tw.shape != (self.n_taxels,):
            raise ValueError(f"taxel_weight must be ({self.n_taxels},), got shape {tw.shape}")
        if self.grid_shape is not None:
            return _component_weight_grid(act, tw, self.grid_shape, self.wrap_v, self.diagonal)
        return _component_weight_graph(act, tw, self.pairs)


def grid_adjacency(grid_shape: tuple[int, int], wrap_v: bool, diagonal: bool) -> Adjacency:
    """Adjacency of an H x W row-major grid (rows along u; v wraps between columns 0 and W-1)."""
    h, w = int(grid_shape[0]), int(grid_shape[1])
    if h < 1 or w < 1:
        raise ValueError(f"grid_shape={grid_shape} must be two positive sizes")
    idx = np.arange(h * w).reshape(h, w)
    steps = [(1, 0), (0, 1)] + ([(1, 1), (1, -1)] if diagonal else [])
    pairs = []
    for di, dj in steps:
        src = idx[: h - di] if di else idx
        dst = idx[di:] if di else idx
        if wrap_v and w > 1:
            dst = np.roll(dst, -dj, axis=1)
        elif dj > 0:
            src, dst = src[:, : w - dj], dst[:, dj:]
        elif dj < 0:
            src, dst = src[:, -dj:], dst[:, : w + dj]
        pairs.append(np.column_stack([src.ravel(), dst.ravel()]))
    p = np.sort(np.concatenate(pairs), axis=1)
    p = np.unique(p[p[:, 0] != p[:, 1]], axis=0).astype(np.int64).reshape(-1, 2)
    return Adjacency(h * w, p, (h, w), bool(wrap_v) and w > 1, bool(diagonal), 0.0)


def point_adjacency(points: np.ndarray, period: float = 0.0) -> Adjacency:
    """Pairs of points (N, 2) closer than :data:`NEIGHBOUR_RADIUS` x the median nearest-neighbour spacing.

    ``period`` > 0: the second coordinate wraps with that period.
    """
    pts = np.array(points, dtype=np.float64)  # a copy: shifted below
    n = pts.shape[0]
    none = np.zeros((0, 2), dtype=np.int64)
    if n <= 1:
        return Adjacency(n, none, None, False, False, 0.0)
    pts[:, 0] = pts[:, 0] - pts[:, 0].min()
    if period > 0:
        pts[:, 1] = np.mod(pts[:, 1], period)
        pts[:, 1] = np.where(pts[:, 1] >= period, 0.0, pts[:, 1])
        span = float(pts[:, 0].max()) * 3.0 + 1.0
        tree = cKDTree(pts, boxsize=[span, period])
    else:
        tree = cKDTree(pts)
    d, _ = tree.query(pts, k=2)
    nn = d[:, 1]
    spacing = float(np.median(nn[nn > 0])) if np.any(nn > 0) else 0.0
    if spacing <= 0:
        return Adjacency(n, none, None, False, False, 0.0)
    pairs = tree.query_pairs(NEIGHBOUR_RADIUS * spacing, output_type="ndarray")
    return Adjacency(n, np.sort(pairs.astype(np.int64), axis=1).reshape(-1, 2), None, False, False, spacing)


def taxel_adjacency(geometry: TaxelGeometry, diagonal: bool = True) -> Adjacency:
    """The neighbours of a skin's taxels (module docstring): grid rule on grids, radius rule elsewhere."""
    coords = metric_coords(geometry)
    if geometry.grid_shape is not None:
        return grid_adjacency(geometry.grid_shape, bool(geometry.wrap_v) and has_chart(geometry), diagonal)
    return point_adjacency(np.column_stack([coords.a_m, coords.b_m]), coords.circumference_m)


#: Connectivity within a frame, none across frames (axis 0 = frames).
def _structure(diagonal: bool) -> np.ndarray:
    s = np.zeros((3, 3, 3), dtype=bool)
    s[1] = True if diagonal else ndimage.generate_binary_structure(2, 1)
    return s


def _largest_component_grid(w: np.ndarray, grid_shape: tuple[int, int], wrap: bool, diagonal: bool) -> np.ndarray:
    """Grid path of :meth:`Adjacency.largest_component`: label each frame, join labels across the v seam."""
    h, wd = grid_shape
    grid = w.reshape(-1, h, wd)
    m = grid.shape[0]
    lab, n_lab = ndimage.label(grid > 0, structure=_structure(diagonal))
    if n_lab == 0:
        return np.zeros(m)
    weight = np.bincount(lab.ravel(), weights=grid.ravel(), minlength=n_lab + 1)
    # label() numbers features in C order, so a frame's labels exceed those
    # of every earlier frame: the frame of label k is the first frame whose
    # running maximum label reaches k.
    run_max = np.maximum.accumulate(lab.reshape(m, -1).max(axis=1))
    frame_of = np.searchsorted(run_max, np.arange(n_lab + 1), side="left")
    comp = _join_seam(lab, n_lab, wrap, diagonal)
    comp_weight = np.bincount(comp[1:], weights=weight[1:])
    out = np.zeros(m)
    np.maximum.at(out, frame_of[1:], comp_weight[comp[1:]])
    return out


def _join_seam(lab: np.ndarray, n_lab: int, wrap: bool, diagonal: bool) -> np.ndarray:
    """(n_lab + 1,) component of each ``ndimage.label`` label of (M, H, W) frames, labels that touch
    across the v seam (columns 0 and W-1, same or, with ``diagonal``, adjacent rows) joined; 0 stays 0."""
    _, h, wd = lab.shape
    comp = np.arange(n_lab + 1)
    if wrap and wd > 2:
        left, right = lab[:, :, 0], lab[:, :, wd - 1]
        pairs = []
        for dr in (-1, 0, 1) if diagonal else (0,):
            lo, hi = max(0, -dr), min(h, h - dr)
            l_, r_ = left[:, lo:hi], right[:, lo + dr : hi + dr]
            ok = (l_ > 0) & (r_ > 0)
            pairs.append(np.column_stack([l_[ok], r_[ok]]))
        joined = np.concatenate(pairs)
        if joined.size:
            g = coo_matrix((np.ones(len(joined)), (joined[:, 0], joined[:, 1])), shape=(n_lab + 1, n_lab + 1))
            _, comp = connected_components(g, directed=False)
    return comp


def _component_weight_grid(
    active: np.ndarray, tw: np.ndarray, grid_shape: tuple[int, int], wrap: bool, diagonal: bool
) -> np.ndarray:
    """Grid path of :meth:`Adjacency.component_weight`."""
    m, n = active.shape
    h, wd = grid_shape
    lab, n_lab = ndimage.label(active.reshape(m, h, wd), structure=_structure(diagonal))
    out = np.zeros((m, n))
    if n_lab == 0:
        return out
    comp = _join_seam(lab, n_lab, wrap, diagonal)
    of = comp[lab.reshape(m, n)]
    total = np.bincount(of.ravel(), weights=np.broadcast_to(tw, (m, n)).ravel(), minlength=int(comp.max()) + 1)
    np.copyto(out, total[of], where=active)
    return out


def _graph_components(active: np.ndarray, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Graph path (any layout): the flat indices of the active taxels of (M, N) ``active`` and the connected
    group of each (groups never span frames; both empty when nothing is active)."""
    m, n_tax = active.shape
    flat = np.flatnonzero(active.ravel())
    if flat.size == 0:
        return flat, flat
    node = np.full(m * n_tax, -1, dtype=np.int64)
    node[flat] = np.arange(flat.size)
    both = active[:, pairs[:, 0]] & active[:, pairs[:, 1]] if pairs.size else np.zeros((m, 0), bool)
    f, k = np.nonzero(both)
    src = node[f * n_tax + pairs[k, 0]]
    dst = node[f * n_tax + pairs[k, 1]]
    g = coo_matrix((np.ones(src.size), (src, dst)), shape=(flat.size, flat.size))
    _, comp = connected_components(g, directed=False)
    return flat, comp


def _component_weight_graph(active: np.ndarray, tw: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Graph path of :meth:`Adjacency.component_weight` (any layout)."""
    out = np.zeros(active.shape)
    flat, comp = _graph_components(active, pairs)
    if flat.size:
        out.ravel()[flat] = np.bincount(comp, weights=tw[flat % active.shape[1]])[comp]
    return out


def _largest_component_graph(w: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Graph path of :meth:`Adjacency.largest_component` (any layout)."""
    out = np.zeros(w.shape[0])
    flat, comp = _graph_components(w > 0, pairs)
    if flat.size:
        np.maximum.at(out, flat // w.shape[1], np.bincount(comp, weights=w.ravel()[flat])[comp])
    return out
