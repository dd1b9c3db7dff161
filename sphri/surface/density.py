"""Contact density on a link's surface: samples, footprints and kernel smoothing.

The surface is represented by the link's surface elements
(:class:`~sphri.geometry.samples.SurfaceSamples` from
:func:`~sphri.geometry.samples.sample_link`, kept on the link's geometry with
their search tree and neighbour graphs; re-exported here).

- :func:`touched_elements`: the (frame, element) pairs of a set of contacts:
  each contact row touches the element nearest its ``point_m`` (among the 4
  nearest samples, the first whose normal agrees with the contact's, so a
  thin wall's far side is never hit) and, with ``footprint="patch"``, every
  element whose sample lies within the row's ``patch_radius_m`` of its
  ``point_m`` and faces the same way as that nearest element. Pairs are unique, so an element counts one per frame
  however many capsules touch it.
- :class:`SurfaceKernel`: truncated Gaussian smoothing over the samples,
  ``rho_i = sum_j K(d_ij) c_j`` with ``K(d) = exp(-d^2 / 2 h^2)`` for ``d <=
  3 h``, normalized so that ``sum_i rho_i * area_i = 1`` (a density in
  1/m^2). ``d`` is geodesic (default: shortest paths on the samples' 10-NN
  graph, edges between opposite-facing samples removed, divided by the
  graph's stretch measured on a plane sampled alike, and never below the
  chord) or Euclidean.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy import sparse
from scipy.sparse.csgraph import dijkstra

from sphri.geometry.samples import (
    AREA_POINTS_PER_SAMPLE,
    MIN_NORMAL_DOT,
    SurfaceSamples,
    knn_graph,
    neighbour_csr,
    sample_link,
)

KERNELS = ("geodesic", "euclidean")
FOOTPRINTS = ("patch", "point")
#: Kernel support in bandwidths.
CUTOFF_SIGMAS = 3.0
#: Neighbours per sample in the geodesic graph.
GRAPH_K = 10
__all__ = [
    "AREA_POINTS_PER_SAMPLE",
    "MIN_NORMAL_DOT",
    "SurfaceKernel",
    "SurfaceSamples",
    "graph_stretch",
    "sample_link",
    "touched_elements",
]


@njit(cache=True)
def _expand(frame, elem, radius, snap, point, sample, indptr, nbr, dist):  # pragma: no cover - numba
    """(frame, element) pairs: each row's element plus the neighbours of that
    element whose sample lies within ``radius`` of the row's contact point
    (neighbours sorted by distance to the element; ``snap`` = contact point
    to element distance bounds the search)."""
    n = frame.shape[0]
    out_f = np.empty(16, dtype=np.int64)
    out_e = np.empty(16, dtype=np.int64)
    c = 0
    for k in range(n):
        e = elem[k]
        r2 = radius[k] * radius[k]
        reach = radius[k] + snap[k]
        for t in range(indptr[e] - 1, indptr[e + 1]):
            if t < indptr[e]:
                j = e
            else:
                if dist[t] > reach:
                    break
                j = nbr[t]
                dx = sample[j, 0] - point[k, 0]
                dy = sample[j, 1] - point[k, 1]
                dz = sample[j, 2] - point[k, 2]
                if dx * dx + dy * dy + dz * dz > r2:
                    continue
            if c == out_f.shape[0]:
                grown_f = np.empty(2 * c, dtype=np.int64)
                grown_e = np.empty(2 * c, dtype=np.int64)
                grown_f[:c] = out_f
                grown_e[:c] = out_e
                out_f = grown_f
                out_e = grown_e
            out_f[c] = frame[k]
            out_e[c] = j
            c += 1
    return out_f[:c], out_e[:c]


def touched_elements(
    samples: SurfaceSamples,
    frame: np.ndarray,
    point_m: np.ndarray,
    normal: np.ndarray | None = None,
    patch_radius_m: np.ndarray | None = None,
    footprint: str = "patch",
    max_radius_m: float = 0.05,
) -> tuple[np.ndarray, np.ndarray]:
    """Unique (frame, element) pairs touched by contact rows.

    ``frame (K,)`` int, ``point_m (K, 3)``, ``normal (K, 3)`` and
    ``patch_radius_m (K,)`` as in :class:`~sphri.types.Contacts`. Returns
    ``frames (E,)`` and ``elements (E,)`` int64, sorted by frame then
    element. Patch radii are capped at ``max_radius_m``.
    """
    if footprint not in FOOTPRINTS:
        raise ValueError(f"footprint={footprint!r} is invalid: allowed values: {list(FOOTPRINTS)}")
    frame = np.asarray(frame, dtype=np.int64)
    if frame.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    elem = samples.nearest(point_m, normal)
    if footprint == "patch":
        if patch_radius_m is None:
            raise ValueError("footprint='patch' needs patch_radius_m (K,)")
        r = np.minimum(np.asarray(patch_radius_m, dtype=np.float64), max_radius_m)
        if r.shape != frame.shape or not np.all(np.isfinite(r)):
            raise ValueError(f"patch_radius_m must be finite with shape {frame.shape}, got {r.shape}")
        pts = np.asarray(point_m, dtype=np.float64)
        snap = np.linalg.norm(samples.points_m[elem] - pts, axis=1)
        reach = float((r + snap).max())
        if reach > 0:
            indptr, nbr, dist = neighbour_csr(samples, reach)  # a reach per call: not kept
            frame, elem = _expand(frame, elem, r, snap, np.ascontiguousarray(pts), samples.points_m, indptr, nbr, dist)
    key = np.sort(frame * samples.n + elem)  # sort-based unique (numpy's hash unique is slow here)
    if key.size:
        key = key[np.r_[True, key[1:] != key[:-1]]]
    return key // samples.n, key % samples.n


# ----------------------------------------------------------------------------- kernel


def graph_stretch(spacing_m: float, k: int = GRAPH_K, bandwidth_m: float | None = None, seed: int = 0) -> float:
    """Mean ratio of k-NN graph path length to straight distance on a plane
    sampled at ``spacing_m`` (for distances between h and 3 h)."""
    h = bandwidth_m if bandwidth_m is not None else 3.0 * spacing_m
    side = 10.0 * h
    n = int(np.ceil((side / spacing_m) ** 2))
    rng = np.random.default_rng(seed)
    pts = np.zeros((n, 3))
    pts[:, :2] = rng.random((n, 2)) * side
    g = knn_graph(pts, np.tile([0.0, 0.0, 1.0], (n, 1)), k)
    centre = np.flatnonzero(np.linalg.norm(pts[:, :2] - side / 2, axis=1) < side / 6)[:40]
    dg = dijkstra(g, directed=False, indices=centre, limit=CUTOFF_SIGMAS * h)
    de = np.linalg.norm(pts[centre][:, None, :] - pts[None, :, :], axis=2)
    ok = np.isfinite(dg) & (de >= h) & (de <= CUTOFF_SIGMAS * h)
    if not ok.any():
        return 1.0
    return float(max(np.median(dg[ok] / de[ok]), 1.0))


class SurfaceKernel:
    """Truncated Gaussian smoothing over surface samples (bandwidth in mm)."""

    def __init__(self, samples: SurfaceSamples, bandwidth_mm: float = 10.0, kernel: str = "geodesic") -> None:
        if kernel not in KERNELS:
            raise ValueError(f"kernel={kernel!r} is invalid: allowed values: {list(KERNELS)}")
        if not bandwidth_mm > 0:
            raise ValueError(f"bandwidth_mm={bandwidth_mm} is invalid: must be > 0")
        self.samples = samples
        self.bandwidth_m = float(bandwidth_mm) * 1e-3
        self.kernel = kernel
        self.stretch = 1.0
        cut = CUTOFF_SIGMAS * self.bandwidth_m
        pts = samples.points_m
        n = samples.n
        if kernel == "euclidean":
            pairs = samples.tree.query_pairs(cut, output_type="ndarray")
            i = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)])
            j = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)])
            d = np.linalg.norm(pts[i] - pts[j], axis=1)
        else:
            self.stretch = graph_stretch(samples.spacing_m, GRAPH_K, self.bandwidth_m)
            g = samples.knn_graph(GRAPH_K)
            ii, jj, dd = [], [], []
            chunk = max(1, int(2e7 // max(n, 1)))
            for s in range(0, n, chunk):
                src = np.arange(s, min(n, s + chunk))
                dg = dijkstra(g, directed=False, indices=src, limit=cut * self.stretch)
                r, c = np.nonzero(np.isfinite(dg))
                ii.append(src[r])
                jj.append(c)
                dd.append(dg[r, c])
            i, j = np.concatenate(ii), np.concatenate(jj)
            chord = np.linalg.norm(pts[i] - pts[j], axis=1)
            d = np.maximum(np.concatenate(dd) / self.stretch, chord)
            keep = d <= cut
            i, j, d = i[keep], j[keep], d[keep]
        w = np.exp(-0.5 * (d / self.bandwidth_m) ** 2)
        self.matrix = sparse.csr_matrix((w, (i, j)), shape=(n, n))
        """(P, P) kernel weights K(d_ij) (symmetric)."""

    def smooth(self, counts: np.ndarray) -> np.ndarray:
        """Counts (P,) or (G, P) per element -> densities in 1/m^2 (each row
        integrates to 1 over the surface; all-zero rows stay zero)."""
        c = np.asarray(counts, dtype=np.float64)
        one = c.ndim == 1
        c2 = np.atleast_2d(c)
        if c2.shape[1] != self.samples.n:
            raise ValueError(f"counts must have {self.samples.n} elements per row, got {c2.shape}")
        rho = np.asarray(self.matrix @ c2.T).T
        mass = rho @ self.samples.area_m2
        rho = np.divide(rho, mass[:, None], out=np.zeros_like(rho), where=mass[:, None] > 0)
        return rho[0] if one else rho
