"""A link's surface elements: samples with their cells' areas, their search tree and their neighbour graphs.

The surface is represented by ``P`` area-weighted random samples (about one
per ``spacing_mm``^2); each sample stands for its surface Voronoi cell (the
surface points nearer to it than to any other sample), whose area is
measured by Monte-Carlo with :data:`AREA_POINTS_PER_SAMPLE` dense points per
sample. Those cells are the *surface elements* of the coverage analysis
(:mod:`sphri.surface.density`, :mod:`sphri.analysis.placement`).

Each :class:`SurfaceSamples` keeps its KD-tree (:attr:`SurfaceSamples.tree`)
and its neighbour graphs (:meth:`SurfaceSamples.neighbours`: same-facing
pairs within a radius; :meth:`SurfaceSamples.knn_graph`: the k-NN graph
without opposite-facing edges), each built once. :func:`sample_link` keeps
the samples on the link's :class:`~sphri.geometry.link.LinkGeometry`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from sphri.geometry.link import _frozen, _Lru, geometry_of
from sphri.types import Link

if TYPE_CHECKING:
    from scipy import sparse
    from scipy.spatial import cKDTree

    from sphri.geometry.link import LinkGeometry

#: Opposite-facing samples (normals more than 120 degrees apart) are never neighbours in the k-NN graph.
MIN_NORMAL_DOT = -0.5
#: Dense points per sample that measure the cells' areas.
AREA_POINTS_PER_SAMPLE = 24


@dataclass(frozen=True)
class SurfaceSamples:
    """``P`` samples of a link surface with their cells' areas (metres, link frame)."""

    link: str
    points_m: np.ndarray
    """(P, 3) float64 sample positions on the surface."""
    normal: np.ndarray
    """(P, 3) float64 outward unit normals (of the sampled triangle)."""
    face: np.ndarray
    """(P,) int64 triangle of each sample."""
    area_m2: np.ndarray
    """(P,) float64 area of each sample's surface Voronoi cell (sums to the link's area)."""
    spacing_m: float
    """Nominal spacing: sqrt(area / P)."""

    @property
    def n(self) -> int:
        return int(self.points_m.shape[0])

    @property
    def total_area_m2(self) -> float:
        return float(self.area_m2.sum())

    @cached_property
    def tree(self) -> cKDTree:
        """KD-tree of :attr:`points_m` (built on first use, kept)."""
        from scipy.spatial import cKDTree

        return cKDTree(self.points_m)

    @cached_property
    def _graphs(self) -> _Lru:
        return _Lru()

    def nearest(self, points: np.ndarray, normals: np.ndarray | None = None, k: int = 4) -> np.ndarray:
        """(K,) int64 nearest sample to each of (K, 3) points; with ``normals``
        (K, 3) the nearest of the ``k`` closest whose normal agrees (dot > 0),
        falling back to the nearest."""
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must be (K, 3) metres, got {pts.shape}")
        if pts.shape[0] == 0:
            return np.zeros(0, dtype=np.int64)
        kk = min(k, self.n)
        _, idx = self.tree.query(pts, k=kk)
        idx = idx.reshape(pts.shape[0], kk)
        if normals is None or kk == 1:
            return idx[:, 0].astype(np.int64)
        nrm = np.asarray(normals, dtype=np.float64)
        agree = np.einsum("kjc,kc->kj", self.normal[idx], nrm) > 0
        first = np.where(agree.any(axis=1), agree.argmax(axis=1), 0)
        return idx[np.arange(idx.shape[0]), first].astype(np.int64)

    def interpolation(
        self, points: np.ndarray, normals: np.ndarray | None = None, k: int = 6
    ) -> tuple[np.ndarray, np.ndarray]:
        """Inverse-distance weights of the ``k`` nearest samples of (K, 3) points:
        ``idx (K, k)`` and ``w (K, k)`` (rows sum to 1; samples facing away
        from ``normals`` get zero weight unless none faces the same way)."""
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must be (K, 3) metres, got {pts.shape}")
        kk = min(k, self.n)
        d, idx = self.tree.query(pts, k=kk)
        d, idx = d.reshape(-1, kk), idx.reshape(-1, kk)
        w = 1.0 / (d + 0.05 * self.spacing_m)
        if normals is not None:
            ok = np.einsum("kjc,kc->kj", self.normal[idx], np.asarray(normals, dtype=np.float64)) > 0
            ok[~ok.any(axis=1), 0] = True
            w = w * ok
        w /= w.sum(axis=1, keepdims=True)
        return idx, w

    def neighbours(self, radius_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Same-facing sample pairs within ``radius_m`` as CSR ``(indptr (P+1,), neighbour, distance)``, each row
        sorted by distance (built once per radius)."""
        return self._graphs.get(("radius", float(radius_m)), lambda: neighbour_csr(self, radius_m))

    def knn_graph(self, k: int) -> sparse.csr_matrix:
        """(P, P) symmetric k-NN graph with Euclidean edge lengths, no edge between opposite-facing samples
        (normals' dot <= :data:`MIN_NORMAL_DOT`) (built once per ``k``)."""
        return self._graphs.get(("knn", int(k)), lambda: knn_graph(self.points_m, self.normal, k, tree=self.tree))


def neighbour_csr(s: SurfaceSamples, radius_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Same-facing sample pairs within ``radius_m``, CSR sorted by distance per row (see
    :meth:`SurfaceSamples.neighbours`, which keeps it)."""
    pairs = s.tree.query_pairs(radius_m, output_type="ndarray")  # (E, 2) int64, (0, 2) when none
    pairs = pairs[np.einsum("kc,kc->k", s.normal[pairs[:, 0]], s.normal[pairs[:, 1]]) > 0]
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    d = np.linalg.norm(s.points_m[i] - s.points_m[j], axis=1)
    order = np.lexsort((d, i))
    i, j, d = i[order], j[order], d[order]
    indptr = np.zeros(s.n + 1, dtype=np.int64)
    np.cumsum(np.bincount(i, minlength=s.n), out=indptr[1:])
    return _frozen(indptr), _frozen(j.astype(np.int64)), _frozen(d)


def knn_graph(points: np.ndarray, normals: np.ndarray, k: int, tree: cKDTree | None = None) -> sparse.csr_matrix:
    """Symmetric k-NN graph of ``points`` (Euclidean edge lengths) without edges between opposite-facing points."""
    from scipy import sparse
    from scipy.spatial import cKDTree

    n = points.shape[0]
    kk = min(k + 1, n)
    d, idx = (tree if tree is not None else cKDTree(points)).query(points, k=kk)
    rows = np.repeat(np.arange(n), kk - 1)
    cols = idx[:, 1:].ravel()
    w = d[:, 1:].ravel()
    ok = np.einsum("kc,kc->k", normals[rows], normals[cols]) > MIN_NORMAL_DOT
    ok &= w > 0
    g = sparse.csr_matrix((w[ok], (rows[ok], cols[ok])), shape=(n, n))
    return g.maximum(g.T).tocsr()


def build_samples(geom: LinkGeometry, spacing_mm: float, seed: int, max_samples: int) -> SurfaceSamples:
    """Area-weighted samples of ``geom`` about ``spacing_mm`` apart, with their cells' areas (uncached)."""
    geom.check()
    if not spacing_mm > 0:
        raise ValueError(f"spacing_mm={spacing_mm} is invalid: must be > 0")
    total = float(geom.face_areas.sum())
    n = int(np.ceil(total / (spacing_mm * 1e-3) ** 2))
    if n > max_samples:
        raise ValueError(
            f"link {geom.name!r}: {total * 1e4:.0f} cm^2 at {spacing_mm} mm spacing needs {n} samples "
            f"(> {max_samples}); raise the spacing"
        )
    n = max(n, 64)
    pts, face = geom.sample(n, seed)
    normals = geom.face_normals[face]
    dense, dface = geom.sample(AREA_POINTS_PER_SAMPLE * n, seed + 1)
    s0 = SurfaceSamples(geom.name, pts, normals, face, np.full(n, total / n), float(np.sqrt(total / n)))
    owner = s0.nearest(dense, geom.face_normals[dface])
    counts = np.bincount(owner, minlength=n).astype(np.float64)
    # cells no dense point fell in keep a sliver of area so every element is usable
    counts = np.maximum(counts, 0.5)
    area = total * counts / counts.sum()
    out = SurfaceSamples(
        geom.name, _frozen(pts), _frozen(normals), _frozen(face), _frozen(area), float(np.sqrt(total / n))
    )
    out.__dict__["tree"] = s0.tree  # same points: keep the tree the cells were measured with
    return out


def sample_link(link: Link, spacing_mm: float = 4.0, seed: int = 0, max_samples: int = 80_000) -> SurfaceSamples:
    """Area-weighted samples about ``spacing_mm`` apart, with their cells' areas (kept on the link's geometry:
    a second call with the same arguments returns the same object)."""
    if not spacing_mm > 0:
        raise ValueError(f"spacing_mm={spacing_mm} is invalid: must be > 0")
    geom = geometry_of(link)
    key = ("surface_samples", float(spacing_mm), int(seed), int(max_samples))
    return geom.derived(key, lambda: build_samples(geom, spacing_mm, seed, max_samples))
