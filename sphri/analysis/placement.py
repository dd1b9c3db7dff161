"""Coverage curve and skin placement: how much area captures most contact.

Greedy placement: surface elements are covered in decreasing order of
contact density; after covering elements ``order[:k]`` the curve reports the
share of the link's area covered and the share of *contact frames*
captured, a frame being captured when at least one element it touches is
covered (a taxel there would have fired). The recommendation is the
smallest prefix capturing ``capture`` (0.9) of the frames.

Because the same frames rank the elements and score them, the in-sample
curve is optimistic; :func:`heldout_capture` scores each participant's
frames with the placement chosen from the other participants only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from sphri.geometry.samples import SurfaceSamples
from sphri.surface.charts import chart_of
from sphri.surface.density import SurfaceKernel


@dataclass
class CoverageCurve:
    """Greedy coverage of one group's contact density on one link."""

    group: str
    order: np.ndarray
    """(P,) int64 elements by decreasing density."""
    area_share: np.ndarray
    """(P + 1,) float64 share of the link's area covered by ``order[:k]``."""
    frame_share: np.ndarray
    """(P + 1,) float64 share of contact frames captured by ``order[:k]``."""
    n_frames: int
    """Contact frames of the group."""
    capture: float
    """Target share of contact frames (e.g. 0.9)."""
    k: int
    """Elements in the smallest prefix reaching ``capture`` (0 without frames)."""
    first_rank: np.ndarray = field(repr=False)
    """(n_frames,) int64 position in ``order`` of each frame's first covered element."""

    @property
    def area_at_capture(self) -> float:
        """Share of the link's area (0..1) needed to capture ``capture`` of the frames."""
        return float(self.area_share[self.k])

    @property
    def mask(self) -> np.ndarray:
        """(P,) bool: elements of the recommended placement."""
        m = np.zeros(self.order.size, dtype=bool)
        m[self.order[: self.k]] = True
        return m

    def resampled(self, n_points: int = 201) -> pd.DataFrame:
        """The curve at ``n_points`` evenly spaced area shares (for CSV and plots)."""
        a = np.linspace(0.0, 1.0, n_points)
        idx = np.searchsorted(self.area_share, a, side="right") - 1
        idx = np.clip(idx, 0, self.area_share.size - 1)
        return pd.DataFrame({"group": self.group, "area_share": a, "frame_share": self.frame_share[idx]})


def _first_rank(rank: np.ndarray, frames: np.ndarray, elements: np.ndarray) -> np.ndarray:
    """(n_frames,) min over each frame's elements of their rank; frames sorted."""
    if frames.size == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.flatnonzero(np.r_[True, frames[1:] != frames[:-1]])
    return np.minimum.reduceat(rank[elements], starts).astype(np.int64)


def _check_pairs(frames: np.ndarray, elements: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    f = np.asarray(frames, dtype=np.int64)
    e = np.asarray(elements, dtype=np.int64)
    if f.shape != e.shape or f.ndim != 1:
        raise ValueError(f"frames and elements must be equal-length 1-D arrays, got {f.shape} and {e.shape}")
    if f.size and (np.any(np.diff(f) < 0) or e.min() < 0 or e.max() >= n):
        raise ValueError(f"frames must be sorted and elements in [0, {n})")
    return f, e


def coverage_curve(
    density: np.ndarray,
    area_m2: np.ndarray,
    frames: np.ndarray,
    elements: np.ndarray,
    capture: float = 0.9,
    group: str = "all",
) -> CoverageCurve:
    """Greedy coverage curve of (frame, element) pairs ranked by ``density (P,)``."""
    if not 0.0 < capture <= 1.0:
        raise ValueError(f"capture={capture} is invalid: must be in (0, 1]")
    dens = np.asarray(density, dtype=np.float64)
    area = np.asarray(area_m2, dtype=np.float64)
    if dens.ndim != 1 or area.shape != dens.shape:
        raise ValueError(f"density and area_m2 must be (P,), got {dens.shape} and {area.shape}")
    f, e = _check_pairs(frames, elements, dens.size)
    order = np.lexsort((np.arange(dens.size), -dens))
    rank = np.empty(dens.size, dtype=np.int64)
    rank[order] = np.arange(dens.size)
    first = _first_rank(rank, f, e)
    n_frames = int(first.size)
    area_share = np.r_[0.0, np.cumsum(area[order])] / area.sum()
    captured = np.r_[0, np.cumsum(np.bincount(first, minlength=dens.size))]
    frame_share = captured / max(n_frames, 1)
    if n_frames == 0:
        k = 0
    else:
        need = int(np.ceil(capture * n_frames - 1e-9))
        k = int(np.searchsorted(captured, need, side="left"))
    return CoverageCurve(group, order, area_share, frame_share.astype(np.float64), n_frames, float(capture), k, first)


@njit(cache=True)
def _min_rank_per_frame(rank, elements, bounds):  # pragma: no cover - numba
    """(n_frames,) min of rank[elements[b0:b1]] over each frame's pair range."""
    n = bounds.shape[0] - 1
    out = np.empty(n, dtype=np.int64)
    for i in range(n):
        m = rank.shape[0]
        for t in range(bounds[i], bounds[i + 1]):
            r = rank[elements[t]]
            if r < m:
                m = r
        out[i] = m
    return out


def heldout_capture(
    kernel: SurfaceKernel,
    frames: np.ndarray,
    elements: np.ndarray,
    frame_unit: np.ndarray,
    capture: float = 0.9,
) -> pd.DataFrame:
    """Leave-one-unit-out check of the placement (units = participants).

    ``frame_unit (E,)`` gives each pair's unit (e.g. participant; one unit
    per frame). For each unit the density and the ``capture`` placement come
    from the other units' frames; the row reports ``area_share`` of that
    placement and the held-out unit's ``captured`` share of frames.
    """
    s = kernel.samples
    f, e = _check_pairs(frames, elements, s.n)
    unit = np.asarray(frame_unit)
    if unit.shape != f.shape:
        raise ValueError(f"frame_unit must have shape {f.shape}, got {unit.shape}")
    cols = ["unit", "area_share", "captured", "n_frames"]
    if f.size == 0:
        return pd.DataFrame(columns=cols)
    codes, names = pd.factorize(unit)
    starts = np.flatnonzero(np.r_[True, f[1:] != f[:-1]])
    bounds = np.r_[starts, f.size].astype(np.int64)
    frame_code = codes[starts]
    n_units = len(names)
    per_unit = np.bincount(codes * s.n + e, minlength=n_units * s.n).reshape(n_units, s.n).astype(np.float64)
    dens = kernel.smooth(per_unit.sum(axis=0)[None, :] - per_unit)  # row c: every unit but c
    total_area = s.area_m2.sum()
    rows = []
    for c in range(n_units):
        train = frame_code != c
        n_train = int(train.sum())
        if n_train == 0:
            continue
        order = np.lexsort((np.arange(s.n), -dens[c]))
        rank = np.empty(s.n, dtype=np.int64)
        rank[order] = np.arange(s.n)
        first = _min_rank_per_frame(rank, e, bounds)
        captured = np.r_[0, np.cumsum(np.bincount(first[train], minlength=s.n))]
        k = int(np.searchsorted(captured, int(np.ceil(capture * n_train - 1e-9)), side="left"))
        area_share = float(s.area_m2[order[:k]].sum() / total_area)
        held = first[~train]
        rows.append(
            {
                "unit": names[c],
                "area_share": area_share,
                "captured": float(np.mean(held < k)),
                "n_frames": int(held.size),
            }
        )
    return pd.DataFrame(rows, columns=cols)


# ----------------------------------------------------------------------------- regions in words


def _circular_range(v: np.ndarray) -> tuple[float, float]:
    """Smallest arc [start, end] (in [0, 1), may wrap) holding all values of v in [0, 1)."""
    s = np.sort(np.mod(v, 1.0))
    gaps = np.diff(np.r_[s, s[0] + 1.0])
    g = int(np.argmax(gaps))
    return float(s[(g + 1) % s.size]), float(s[g])


def describe_regions(
    samples: SurfaceSamples,
    mask: np.ndarray,
    uv: np.ndarray | None = None,
    weight: np.ndarray | None = None,
    max_regions: int = 3,
    min_share: float = 0.05,
) -> list[dict]:
    """Connected parts of ``mask`` (elements within 2.5 spacings, same facing),
    largest ``weight`` (default: area) first; each with its area (cm^2),
    centroid (mm) and, with ``uv (P, 2)``, its chart extent. Parts below
    ``min_share`` of the total weight are dropped."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return []
    idx = np.flatnonzero(mask)
    indptr, nbr, _ = samples.neighbours(2.5 * samples.spacing_m)
    g = sparse.csr_matrix((np.ones(nbr.size), nbr, indptr), shape=(samples.n, samples.n), copy=True)
    _, labels = connected_components(g[idx][:, idx], directed=False)
    w = samples.area_m2 if weight is None else np.asarray(weight, dtype=np.float64)
    total = float(w[idx].sum())
    parts = []
    for lab in np.unique(labels):
        members = idx[labels == lab]
        share = float(w[members].sum()) / total if total > 0 else 0.0
        if share < min_share:
            continue
        a = samples.area_m2[members]
        part = {
            "area_cm2": float(a.sum() * 1e4),
            "share": share,
            "centroid_mm": (np.average(samples.points_m[members], axis=0, weights=a) * 1e3).tolist(),
        }
        if uv is not None:
            u = uv[members, 0]
            part["u_range"] = (float(u.min()), float(u.max()))
            part["v_range"] = _circular_range(uv[members, 1])
        parts.append(part)
    parts.sort(key=lambda p: -p["share"])
    return parts[:max_regions]


def region_text(part: dict, surface_kind: str) -> str:
    """One region in words, e.g. ``12.3 cm^2 at (3, -40, -410) mm, h 0.55-0.98, a 40-160 deg``."""
    c = part["centroid_mm"]
    text = f"{part['area_cm2']:.1f} cm^2 at ({c[0]:.0f}, {c[1]:.0f}, {c[2]:.0f}) mm"
    if "u_range" in part:
        u0, u1 = part["u_range"]
        v0, v1 = part["v_range"]
        around = bool(np.mod(v1 - v0, 1.0) > 0.85)
        text += ", " + chart_of(surface_kind).describe_uv((u0, u1), (v0, v1), around)
    return text


def recommendation(curve: CoverageCurve, parts: list[dict], surface_kind: str, link: str) -> str:
    """The placement sentence for one group."""
    if curve.n_frames == 0:
        return f"{curve.group}: no contact frames on {link}"
    regions = "; ".join(region_text(p, surface_kind) for p in parts) or "scattered"
    return (
        f"{curve.group}: covering {100 * curve.area_at_capture:.1f} % of {link}'s area "
        f"({regions}) captures {100 * curve.capture:.0f} % of contact frames "
        f"(n = {curve.n_frames} frames)"
    )
