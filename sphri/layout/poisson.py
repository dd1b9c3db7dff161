"""Irregular layouts on the 3-D surface: ``layout=random`` and ``layout=density``.

Both place exactly the grid-equivalent taxel count for ``res`` (see
:func:`sphri.layout.common.grid_equivalent_count`) by weighted sample
elimination (Yuksel 2015, "Sample Elimination for Generating Poisson Disk
Sample Sets"): draw ``candidates x N`` area-weighted surface points, then
repeatedly drop the point most crowded by its neighbours. ``density`` draws
candidates in proportion to a contact-density map and shrinks the Poisson
radius where contact is frequent, so taxels crowd there. Seeded.

The density map is either a file (``layout.density_path``, e.g. exported by
``sphri coverage``) or, with ``density_path`` empty, the run's own
contacts: the same density the coverage analysis exports (frames touching
each surface element, smoothed along the surface by ``bandwidth_mm``;
:func:`density_from_contacts`). The latter is built from every
participant, held-out ones included, so under leave-one-subject-out it is an
optimistic placement; for a held-out one, export the density from other
participants or another study and pass its file.
"""

from __future__ import annotations

import heapq
import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from sphri.config import Configured
from sphri.geometry.link import face_areas, face_normals, sample_surface
from sphri.layout.common import (
    LayoutFileError,
    grid_equivalent_count,
    nn_spacing,
    npz_arrays,
    scattered_layout,
    voronoi_areas,
)
from sphri.layout.schema import DensityLayoutSchema, RandomLayoutSchema, check_res
from sphri.types import Contacts, Layout, Link, SurfaceMap

log = logging.getLogger(__name__)

_ALPHA = 8.0
_BETA = 0.65
_GAMMA = 1.5


@njit(cache=True)
def _eliminate(indptr, nbr, wgt, weights, n_keep):  # pragma: no cover - numba
    """Drop the most crowded candidate until ``n_keep`` remain; returns kept mask."""
    n = weights.shape[0]
    alive = np.ones(n, dtype=np.bool_)
    version = np.zeros(n, dtype=np.int64)
    heap = [(-weights[0], np.int64(0), np.int64(0))]
    heap.pop()
    for i in range(n):
        heap.append((-weights[i], np.int64(i), np.int64(0)))
    heapq.heapify(heap)
    remaining = n
    while remaining > n_keep and len(heap) > 0:
        negw, i, ver = heapq.heappop(heap)
        if not alive[i] or ver != version[i]:
            continue
        alive[i] = False
        remaining -= 1
        for k in range(indptr[i], indptr[i + 1]):
            j = nbr[k]
            if alive[j]:
                weights[j] -= wgt[k]
                version[j] += 1
                heapq.heappush(heap, (-weights[j], j, version[j]))
    return alive


def sample_elimination(points: np.ndarray, radius: np.ndarray, n_keep: int) -> np.ndarray:
    """Indices (n_keep,) of a Poisson-disk subset of ``points (C, 3)``.

    ``radius (C,)`` is each candidate's target Poisson radius r_max in metres
    (uniform for a uniform layout); pairs interact within ``2 max(r_i, r_j)``.
    """
    c = len(points)
    if n_keep >= c:
        return np.arange(c)
    tree = cKDTree(points)
    lists = tree.query_ball_point(points, 2.0 * radius, return_sorted=False)
    lens = np.fromiter((len(x) for x in lists), dtype=np.int64, count=c)
    rows = np.repeat(np.arange(c), lens)
    cols = np.concatenate([np.asarray(x, dtype=np.int64) for x in lists]) if lens.sum() else np.zeros(0, np.int64)
    keep = rows != cols
    rows, cols = rows[keep], cols[keep]
    pairs = np.unique(np.concatenate([np.stack([rows, cols], 1), np.stack([cols, rows], 1)]), axis=0)
    rows, cols = pairs[:, 0], pairs[:, 1]
    d = np.linalg.norm(points[rows] - points[cols], axis=1)
    rij = np.maximum(radius[rows], radius[cols])
    rmin = rij * (1.0 - (n_keep / c) ** _GAMMA) * _BETA
    w = (1.0 - np.maximum(d, rmin) / (2.0 * rij)) ** _ALPHA
    w[d >= 2.0 * rij] = 0.0
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=c))]).astype(np.int64)
    weights = np.bincount(rows, weights=w, minlength=c).astype(np.float64)
    alive = _eliminate(indptr, cols.astype(np.int64), w.astype(np.float64), weights, int(n_keep))
    return np.flatnonzero(alive)


def _irregular_layout(
    link: Link, surface: SurfaceMap, kind: str, pts: np.ndarray, nrm: np.ndarray, seed: int
) -> Layout:
    pitch = float(np.mean(nn_spacing(pts))) if len(pts) > 1 else float(np.sqrt(face_areas(link).sum()))
    area = voronoi_areas(link, pts, seed + 1)
    return scattered_layout(surface, kind, pts, nrm, area, pitch)


def build_random(
    link: Link, surface: SurfaceMap, res: int, aspect: float = 1.0, seed: int = 0, candidates: int = 5
) -> Layout:
    """Poisson-disk taxels, as many as the grid at ``res`` would have."""
    res = check_res(res, "layout.random")
    n = grid_equivalent_count(link, surface, res, aspect)
    area = float(face_areas(link).sum())
    cand, face = sample_surface(link, candidates * n, seed)
    r = np.full(len(cand), np.sqrt(area / (2.0 * np.sqrt(3.0) * n)))
    idx = sample_elimination(cand, r, n)
    return _irregular_layout(link, surface, "random", cand[idx], face_normals(link)[face[idx]], seed)


def load_density(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a density map: ``points_m (P, 3)`` metres and ``density (P,)`` >= 0."""
    p = Path(path)
    if not str(path):
        raise ValueError("layout.density_path is empty: set it to an .npz with points_m (P,3) and density (P,)")
    pts, dens = npz_arrays(p, "layout.density_path", ("points_m", "density"))
    if pts.ndim != 2 or pts.shape[1] != 3 or dens.shape != (pts.shape[0],) or len(pts) == 0:
        raise LayoutFileError(f"{path}: points_m must be (P, 3) and density (P,), got {pts.shape} and {dens.shape}")
    if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(dens))) or dens.min() < 0 or dens.max() <= 0:
        raise LayoutFileError(f"{path}: density must be finite, >= 0 and not all zero; points_m finite")
    return pts, dens


DensityAt = Callable[[np.ndarray], np.ndarray]
"""Density (>= 0, any scale) at (P, 3) surface points (metres) -> (P,)."""


def nearest_density(points_m: np.ndarray, density: np.ndarray, link: Link, source: str) -> DensityAt:
    """Density at surface points from a sampled map: each point takes its nearest map point's value."""
    tree = cKDTree(points_m)
    scale = np.sqrt(float(face_areas(link).sum()))

    def at(points: np.ndarray) -> np.ndarray:
        dist, nearest = tree.query(points)
        if np.median(dist) > 0.1 * scale:
            log.warning(
                "layout.density: the density map (%s) lies %.1f mm (median) from link %r's surface; is it for this link?",
                source,
                np.median(dist) * 1e3,
                link.name,
            )
        return density[nearest]

    return at


def density_from_contacts(contacts: Contacts, link: Link, bandwidth_mm: float, seed: int = 0) -> DensityAt:
    """The coverage analysis's contact density of ``contacts`` on ``link`` (``sphri coverage``'s map).

    Surface samples about 4 mm apart; each frame counts once per element its
    contact patches touch; geodesic Gaussian smoothing of ``bandwidth_mm``
    (:mod:`sphri.surface.density`).
    """
    from sphri.surface.density import SurfaceKernel, sample_link, touched_elements

    if contacts.n_contacts == 0:
        raise ValueError(
            f"layout=density with an empty layout.density_path places taxels by this run's contacts, "
            f"but there is no contact on link {link.name!r}; set layout.density_path to a density .npz"
        )
    samples = sample_link(link, spacing_mm=4.0, seed=seed)
    _, elements = touched_elements(samples, contacts.frame, contacts.point_m, contacts.normal, contacts.patch_radius_m)
    counts = np.bincount(elements, minlength=samples.n).astype(np.float64)
    density = SurfaceKernel(samples, bandwidth_mm=bandwidth_mm).smooth(counts)
    return nearest_density(samples.points_m, density, link, "this run's contacts")


def build_density(
    link: Link,
    surface: SurfaceMap,
    res: int,
    density_at: DensityAt,
    aspect: float = 1.0,
    seed: int = 0,
    candidates: int = 5,
    min_density_fraction: float = 0.05,
) -> Layout:
    """Grid-equivalent count of taxels, denser where ``density_at`` is high."""
    res = check_res(res, "layout.density")
    n = grid_equivalent_count(link, surface, res, aspect)
    area = float(face_areas(link).sum())
    pool, face = sample_surface(link, candidates * n * 4, seed)
    rho_pool = np.asarray(density_at(pool), dtype=np.float64)
    if rho_pool.max() <= 0:
        raise ValueError(f"layout.density: the density is zero everywhere on link {link.name!r}")
    rho_pool = np.maximum(rho_pool, min_density_fraction * rho_pool.mean())
    mean_rho = rho_pool.mean()  # integral(rho dA) ~ mean_rho * area (uniform pool)
    rng = np.random.default_rng(seed + 7)
    pick = rng.choice(len(pool), size=candidates * n, replace=False, p=rho_pool / rho_pool.sum())
    cand, face, rho = pool[pick], face[pick], rho_pool[pick]
    # local taxel density n(x) = n * rho(x) / integral(rho dA) (1/m^2); Poisson radius from it
    local = n * rho / (mean_rho * area)
    r = np.sqrt(1.0 / (2.0 * np.sqrt(3.0) * local))
    idx = sample_elimination(cand, r, n)
    return _irregular_layout(link, surface, "density", cand[idx], face_normals(link)[face[idx]], seed)


class RandomLayout(Configured):
    """``layout=random``: Poisson-disk taxels on the 3-D surface (seeded)."""

    VERSION = "1"

    SCHEMA = RandomLayoutSchema
    aspect: float  # these three set from SCHEMA by Configured
    seed: int
    candidates: int

    def build(self, link: Link, surface: SurfaceMap, res: int) -> Layout:
        """As many taxels as the grid at ``res``, Poisson-disk on the surface."""
        return build_random(link, surface, res, self.aspect, self.seed, self.candidates)


class DensityLayout(Configured):
    """``layout=density``: more taxels where contact is frequent.

    The density comes from ``density_path`` (an .npz from the coverage
    analysis) or, when that is empty, from the run's contacts
    (``uses_contacts``: the pipeline then passes them and keys the layout on
    them; see the module doc for why that placement is optimistic under LOSO).
    """

    VERSION = "3"

    SCHEMA = DensityLayoutSchema
    density_path: str  # these six set from SCHEMA by Configured
    bandwidth_mm: float
    aspect: float
    seed: int
    candidates: int
    min_density_fraction: float

    @property
    def uses_contacts(self) -> bool:
        """True when the density comes from the run's contacts (no ``density_path``)."""
        return not str(self.density_path)

    def build(self, link: Link, surface: SurfaceMap, res: int, contacts: Contacts | None = None) -> Layout:
        """Grid-equivalent count of taxels placed by the density map (file or ``contacts``)."""
        if self.uses_contacts:
            if contacts is None:
                raise ValueError(
                    "layout=density needs layout.density_path (an .npz from sphri coverage) "
                    "or the run's contacts (the pipeline passes them when density_path is empty)"
                )
            density_at = density_from_contacts(contacts, link, self.bandwidth_mm, self.seed)
        else:
            density_at = nearest_density(*load_density(self.density_path), link, self.density_path)
        return build_density(
            link, surface, res, density_at, self.aspect, self.seed, self.candidates, self.min_density_fraction
        )
