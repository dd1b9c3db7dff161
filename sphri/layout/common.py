"""Helpers shared by the layouts: grid sizing, taxel areas, spacing, projection."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from sphri.config import ConfigError
from sphri.geometry.link import face_areas, face_normals, project_along, sample_surface
from sphri.limits import over_limit
from sphri.surface.charts import chart_of, from_uv, to_uv
from sphri.types import Layout, Link, SurfaceMap

#: Peak memory of the layout stage and the stages after it per taxel (bytes): a 2 M-taxel grid peaked
#: at 14.6 GB in the layout stage alone.
BYTES_PER_TAXEL = 7300


def check_taxel_count(h: int, w: int, res: int, aspect: float) -> None:
    """Refuse an H x W grid whose taxels would not fit in memory, before anything is built; the message
    names ``layout.res`` and ``layout.aspect``, the estimate and the limit (:mod:`sphri.limits`)."""
    why = over_limit(
        f"a layout of {h} x {w} = {h * w} taxels (about {BYTES_PER_TAXEL} bytes each)", h * w * float(BYTES_PER_TAXEL)
    )
    if why is not None:
        raise ConfigError(f"layout.res={res} with layout.aspect={aspect:g} is invalid: {why}")


def long_axis_length_m(surface: SurfaceMap) -> float:
    """Length of the link along its long axis (metres): what ``res`` divides."""
    return chart_of(surface).long_axis_length_m(surface)


def grid_dims(surface: SurfaceMap, res: int, aspect: float = 1.0, hex_rows: bool = False) -> tuple[int, int]:
    """(H, W) of a grid with ``res`` taxels along the long axis.

    Pitch along ``p = length / res``; ``H = round(metres_per_u / p)`` (= res
    for a cylinder); around ``W = max(1, round(metres_per_v / (p * aspect)))``.

    Hex lattices keep the square grid's area per taxel (``p^2 * aspect``, so
    about the same taxel count: layouts compare at matched counts) on an
    equilateral lattice: rows ``sqrt(3)/2 * c`` apart with in-row spacing
    ``c = p * sqrt(2 / sqrt(3)) * aspect``, i.e. about ``1.075 res`` rows.
    """
    if not surface.has_uv:
        raise ValueError(f"a grid needs a surface with a 2-D chart; surface kind {surface.kind!r} has none")
    pitch = long_axis_length_m(surface) / res
    h = max(1, int(round(surface.metres_per_u / pitch)))
    w = max(1, int(round(surface.metres_per_v / (pitch * aspect))))
    check_taxel_count(h, w, res, aspect)
    if not hex_rows:
        return h, w
    stretch = np.sqrt(2.0 / np.sqrt(3.0))  # in-row spacing / p, keeping the area per taxel
    rows = surface.metres_per_u * stretch / pitch  # rows sqrt(3)/2 * in-row spacing apart
    cols = surface.metres_per_v / (pitch * aspect * stretch)
    # of the integer (rows, cols) around the ideal, the one closest to the square grid's count,
    # then the closest to equilateral
    options = [
        (max(1, a), max(1, b))
        for a in {int(np.floor(rows)), int(np.ceil(rows))}
        for b in {int(np.floor(cols)), int(np.ceil(cols))}
    ]
    return min(
        options, key=lambda o: (abs(o[0] * o[1] - h * w), abs(np.log(o[0] / rows)) + abs(np.log(o[1] / cols)), o)
    )


def grid_uv(h: int, w: int, hex_rows: bool = False) -> np.ndarray:
    """(H*W, 2) cell-centre chart coordinates in row-major (u, v) order."""
    i, j = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    off = 0.5 * (i % 2) if hex_rows else 0.0
    u = (i + 0.5) / h
    v = np.mod((j + 0.5 + off) / w, 1.0)
    return np.column_stack([u.ravel(), v.ravel()]).astype(np.float64)


def row_offsets(layout_uv: np.ndarray, grid_shape: tuple[int, int]) -> np.ndarray:
    """(H,) float64 column offset of each row's cells, in cells (0 = plain grid, 0.5 = shifted)."""
    h, w = grid_shape
    first = layout_uv.reshape(h, w, 2)[:, 0, 1]
    return np.mod(first * w - 0.5 + 1e-9, 1.0) - 1e-9


def grid_equivalent_count(link: Link, surface: SurfaceMap, res: int, aspect: float = 1.0) -> int:
    """Taxels a square grid at ``res`` would put on the link (its non-void cells).

    Without a chart: ``round(area / (p * p * aspect))`` with ``p = length / res``.
    """
    if surface.has_uv:
        h, w = grid_dims(surface, res, aspect)
        if chart_of(surface).every_cell_valid:
            return h * w
        _, valid = from_uv(surface, grid_uv(h, w), return_valid=True)
        return max(1, int(valid.sum()))
    pitch = long_axis_length_m(surface) / res
    area = float(face_areas(link).sum())
    return max(1, int(round(area / (pitch * pitch * aspect))))


def n_area_samples(n_taxels: int) -> int:
    """Surface samples used to measure taxel areas (about 30 per taxel)."""
    return int(np.clip(30 * n_taxels, 100_000, 3_000_000))


def grid_cell_areas(
    link: Link, surface: SurfaceMap, grid_shape: tuple[int, int], offsets: np.ndarray, seed: int
) -> np.ndarray:
    """(H*W,) float64 mesh area (m^2) mapping into each chart cell (area-weighted samples)."""
    h, w = grid_shape
    n = n_area_samples(h * w)
    pts, _ = sample_surface(link, n, seed)
    uv = to_uv(surface, pts)
    row = np.clip((uv[:, 0] * h).astype(np.int64), 0, h - 1)
    colf = uv[:, 1] * w - offsets[row]
    col = np.floor(colf).astype(np.int64)
    col = np.mod(col, w) if surface.wrap_v else np.clip(col, 0, w - 1)
    counts = np.bincount(row * w + col, minlength=h * w).astype(np.float64)
    return counts * (face_areas(link).sum() / n)


def project_chart_points(link: Link, surface: SurfaceMap, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Taxels at chart points ``uv (K, 2)`` moved onto the mesh along the primitive normal.

    Returns ``position (K, 3)``, outward ``normal (K, 3)`` and ``valid (K,)``
    (False in void chart cells).
    """
    prim, pn, valid = from_uv(surface, uv, return_normal=True, return_valid=True)
    v = np.asarray(link.vertices)
    reach = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    pos, face, _ = project_along(link, prim, pn, max_dist_m=reach)
    nrm = face_normals(link)[face]
    flip = np.einsum("ij,ij->i", nrm, pn) < 0
    nrm[flip] *= -1
    bad = np.linalg.norm(nrm, axis=1) < 0.5
    nrm[bad] = pn[bad]
    return pos, nrm, valid


def nn_spacing(points: np.ndarray) -> np.ndarray:
    """(N,) float64 distance from each point to its nearest other point (metres; 0 if N = 1)."""
    if len(points) < 2:
        return np.zeros(len(points))
    d, _ = cKDTree(points).query(points, k=2)
    return d[:, 1]


def scattered_layout(
    surface: SurfaceMap, kind: str, pts: np.ndarray, nrm: np.ndarray, area: np.ndarray, pitch: float
) -> Layout:
    """Taxels at ``pts`` (normals ``nrm``, areas ``area``) that form no grid (file, random, density): their
    (u, v) where the surface has a chart, ``pitch`` both ways."""
    return Layout(
        kind=kind,
        position_m=pts,
        normal=nrm,
        area_m2=area,
        uv=to_uv(surface, pts) if surface.has_uv else None,
        grid_shape=None,
        pitch_u_m=pitch,
        pitch_v_m=pitch,
    )


class LayoutFileError(ValueError):
    """A layout or density file (``layout.path``, ``layout.density_path``) that does not read as one: the
    message names the file (and the line or array); one line ``layout file error: ...`` at the command line."""


def npz_arrays(path: str | Path, setting: str, keys: tuple[str, ...]) -> list[np.ndarray]:
    """The float64 arrays ``keys`` of the ``.npz`` file ``path`` that the setting ``setting`` names
    (``layout.path``): a missing file or array is one line naming the setting, the file and the array."""
    if not Path(path).is_file():
        raise FileNotFoundError(f"{setting}={str(path)!r}: no such file")
    if not zipfile.is_zipfile(path):
        raise LayoutFileError(f"{setting}={str(path)!r}: not an .npz file (numpy's zip of arrays)")
    try:
        with np.load(path, allow_pickle=False) as z:
            has = sorted(z.files)
            arrays = {key: np.asarray(z[key], dtype=np.float64) for key in keys if key in has}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, TypeError) as exc:  # not an npz, or not numbers
        raise LayoutFileError(f"{setting}={str(path)!r}: not a readable .npz of numbers ({exc})") from None
    missing = [key for key in keys if key not in arrays]
    if missing:
        raise LayoutFileError(f"{setting}={str(path)!r}: missing array {missing[0]!r} (has {has})")
    return [arrays[key] for key in keys]


def voronoi_areas(link: Link, positions: np.ndarray, seed: int, max_dist_m: float | None = None) -> np.ndarray:
    """(N,) float64 surface area (m^2) nearer to each taxel than to any other.

    Samples farther than ``max_dist_m`` from every taxel are unassigned
    (a skin patch that does not cover the whole link).
    """
    n = n_area_samples(len(positions))
    pts, _ = sample_surface(link, n, seed)
    d, idx = cKDTree(positions).query(pts)
    if max_dist_m is not None:
        idx = idx[d <= max_dist_m]
    counts = np.bincount(idx, minlength=len(positions)).astype(np.float64)
    return counts * (face_areas(link).sum() / n)
