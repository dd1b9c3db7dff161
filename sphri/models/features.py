"""The Random Forest's 32 hand-crafted touch features, computed per trial.

A trial is a window ``x[i]`` of shape (L, N): L frames (aligned to contact
onset by the window stage) of N taxel readings in [0, 1]. Readings below
``active_threshold`` count as no contact; the others weigh the taxel (1 for
binary skins). Per frame, seven signals are computed in physical units from
the skin's :class:`~sphri.types.TaxelGeometry`, so that features of
different resolutions are comparable:

- ``area``: active contact area, sum of weights x taxel area (m^2);
- ``cop_a``, ``cop_b``: centre of pressure (weighted mean position) along the
  link (``a = u * metres_per_u``) and around it (``b = v * metres_per_v``;
  circular mean when v wraps), metres;
- ``speed``: centre-of-pressure displacement between consecutive contact
  frames (metres per frame; wrapped around the link);
- ``bbox``: area of the bounding box of the active taxels (m^2; around a
  wrapping link, the shortest arc holding them all);
- ``lcc``: area of the largest connected component of active taxels (m^2;
  8-connected on grids, merged across the v seam when v wraps; on other
  layouts, taxels closer than 1.5 x the median nearest-neighbour spacing);
- ``spread_a``, ``spread_b``: second moments of the weights about the centre
  of pressure (``Ixx``, ``Iyy``), m^2.

Layouts without a chart (``uv is None``) use the two principal axes of the
3-D taxel positions as ``a`` and ``b`` (no wrap). Each signal is summarised
over time (:data:`FEATURE_NAMES` lists the exact 32): ``area``, ``bbox`` and
``lcc`` over all L frames (0 without contact), centre-of-pressure signals
over the frames with contact (0 when a trial has none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sphri.adjacency import Adjacency, metric_coords, taxel_adjacency
from sphri.types import TaxelGeometry

#: The 32 features, in column order of :func:`extract_features`.
FEATURE_NAMES: tuple[str, ...] = (
    # activation: contact area per frame, its first differences, bursts
    "area_mean_m2",
    "area_std_m2",
    "area_range_m2",
    "area_max_m2",
    "darea_absmean_m2",  # mean |area(t) - area(t-1)|
    "darea_std_m2",
    "darea_range_m2",
    "darea_max_m2",  # largest increase between two frames
    "peak_count",  # contact bursts: upward crossings of half the trial's peak area
    "contact_fraction",  # fraction of the L frames with any active taxel
    # motion: centre-of-pressure trajectory (contact frames) and its speed
    "cop_a_std_m",
    "cop_a_range_m",
    "cop_b_std_m",  # circular around a wrapping link
    "cop_b_range_m",
    "speed_mean_m",  # metres per frame
    "speed_max_m",
    # spatial extent
    "bbox_mean_m2",
    "bbox_std_m2",
    "bbox_range_m2",
    "bbox_max_m2",
    "lcc_mean_m2",
    "lcc_std_m2",
    "lcc_range_m2",
    "lcc_max_m2",
    # spatial spread: second moments about the centre of pressure (Ixx, Iyy)
    "spread_a_mean_m2",
    "spread_a_std_m2",
    "spread_a_range_m2",
    "spread_a_max_m2",
    "spread_b_mean_m2",
    "spread_b_std_m2",
    "spread_b_range_m2",
    "spread_b_max_m2",
)
assert len(FEATURE_NAMES) == 32, len(FEATURE_NAMES)

#: Elements (trials x frames x taxels) processed at once; bounds memory.
_CHUNK_ELEMENTS = 1 << 21


@dataclass(frozen=True)
class TaxelCoords:
    """Taxel positions in metres on the skin's 2-D chart, derived from geometry."""

    a_m: np.ndarray
    """(N,) float64 position along the link (metres)."""
    b_m: np.ndarray
    """(N,) float64 position around the link (metres; in [0, circumference) when wrapping)."""
    circumference_m: float
    """Period of ``b_m`` in metres (0 when b does not wrap)."""
    pitch_a_m: float
    """Taxel spacing along a (metres)."""
    pitch_b_m: float
    """Taxel spacing along b (metres)."""
    grid_shape: tuple[int, int] | None
    """(H, W) for row-major grids (rows along a, columns along b)."""
    adjacency: Adjacency
    """Neighbouring taxels (:func:`sphri.adjacency.taxel_adjacency`, 8-connected on grids)."""

    @property
    def n_taxels(self) -> int:
        return int(self.a_m.shape[0])

    @property
    def taxel_area_m2(self) -> float:
        """Area one taxel stands for (m^2): pitch_a x pitch_b."""
        return self.pitch_a_m * self.pitch_b_m

    @property
    def wraps(self) -> bool:
        return self.circumference_m > 0


def taxel_coords(geometry: TaxelGeometry) -> TaxelCoords:
    """Chart coordinates (metres), pitches and neighbours of a layout's taxels.

    Coordinates and neighbours are :func:`sphri.adjacency.metric_coords` and
    :func:`sphri.adjacency.taxel_adjacency` (8-connected on grids). Raises
    ``ValueError`` on shapes that do not agree.
    """
    mc = metric_coords(geometry)
    a, b, circ = mc.a_m, mc.b_m, mc.circumference_m
    adjacency = taxel_adjacency(geometry, diagonal=True)
    grid = adjacency.grid_shape
    if grid is not None:
        h, w = grid
        a_rows = a.reshape(h, w).mean(axis=1)
        b_cols = b.reshape(h, w)[0]
        pa = float(np.median(np.abs(np.diff(a_rows)))) if h > 1 else mc.full_a_m
        if circ > 0:
            pb = circ / w
        else:
            pb = float(np.median(np.abs(np.diff(b_cols)))) if w > 1 else mc.full_b_m
        if pa <= 0 and pb > 0:
            pa = pb
        if pb <= 0 and pa > 0:
            pb = pa
    else:
        pa = pb = adjacency.spacing_m
    if not pa > 0 or not pb > 0:
        # a single taxel without any chart: its size is unknown, so features
        # are in taxel units (area 1 per active taxel).
        pa = pb = 1.0
    return TaxelCoords(
        a_m=a, b_m=b, circumference_m=circ, pitch_a_m=pa, pitch_b_m=pb, grid_shape=grid, adjacency=adjacency
    )


def check_windows(x: np.ndarray, n_taxels: int | None = None, what: str = "x") -> np.ndarray:
    """Validate model input: (n, L, N) finite readings; returns it as float32."""
    x = np.asarray(x)
    if x.ndim != 3:
        raise ValueError(f"{what} must be (n_trials, L, N_taxels) windows, got shape {x.shape}")
    if n_taxels is not None and x.shape[2] != n_taxels:
        raise ValueError(f"{what} has {x.shape[2]} taxels per frame but the geometry has {n_taxels}")
    if x.shape[1] < 1:
        raise ValueError(f"{what} has windows of 0 frames (shape {x.shape})")
    x = x.astype(np.float32, copy=False)
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{what} holds NaN or infinite readings")
    return x


def frame_signals(x: np.ndarray, coords: TaxelCoords, active_threshold: float = 0.5) -> dict[str, np.ndarray]:
    """Per-frame signals of windows ``x`` (n, L, N): dict of (n, L) float64.

    Keys: ``area``, ``cop_a``, ``cop_b``, ``spread_a``, ``spread_b``, ``bbox``,
    ``lcc`` (see the module docstring for units) and ``contact`` (bool: the
    frame has an active taxel). Centre-of-pressure signals are 0 where
    ``contact`` is False.
    """
    n, length, n_tax = x.shape
    m = n * length
    w = np.where(x >= active_threshold, x, 0).reshape(m, n_tax).astype(np.float64)
    active = w > 0
    s = w.sum(axis=1)
    contact = s > 0
    safe = np.where(contact, s, 1.0)
    ta = coords.taxel_area_m2
    a, b = coords.a_m, coords.b_m

    cop_a = (w @ a) / safe
    spread_a = np.maximum((w @ (a * a)) / safe - cop_a**2, 0.0)
    if coords.wraps:
        circ = coords.circumference_m
        theta = 2.0 * np.pi * b / circ
        ang = np.arctan2(w @ np.sin(theta), w @ np.cos(theta))
        cop_b = np.mod(ang * circ / (2.0 * np.pi), circ)
        if coords.grid_shape is not None:  # one b per grid column
            h, wd = coords.grid_shape
            wb, bb = w.reshape(m, h, wd).sum(axis=1), b.reshape(h, wd)[0]
        else:
            wb, bb = w, b
        dev = _wrap(bb[None, :] - cop_b[:, None], circ)
        spread_b = np.einsum("mn,mn->m", wb, dev * dev) / safe
    else:
        cop_b = (w @ b) / safe
        spread_b = np.maximum((w @ (b * b)) / safe - cop_b**2, 0.0)

    bbox = _span_a(active, coords) * _span_b(active, coords) * contact
    lcc = coords.adjacency.largest_component(w)

    out = {
        "area": s * ta,
        "cop_a": np.where(contact, cop_a, 0.0),
        "cop_b": np.where(contact, cop_b, 0.0),
        "spread_a": np.where(contact, spread_a, 0.0),
        "spread_b": np.where(contact, spread_b, 0.0),
        "bbox": bbox,
        "lcc": lcc * ta,
        "contact": contact,
    }
    return {k: v.reshape(n, length) for k, v in out.items()}


def _wrap(d: np.ndarray, period: float) -> np.ndarray:
    """Map differences into [-period/2, period/2)."""
    return np.mod(d + 0.5 * period, period) - 0.5 * period


def _span_a(active: np.ndarray, c: TaxelCoords) -> np.ndarray:
    """(M,) extent of the active taxels along a, one pitch added (metres)."""
    if c.grid_shape is not None:
        h, w = c.grid_shape
        occ = np.any(active.reshape(-1, h, w), axis=2)
        pos = c.a_m.reshape(h, w).mean(axis=1)
    else:
        occ, pos = active, c.a_m
    return _extent(occ, pos, c.pitch_a_m)


def _extent(occ: np.ndarray, pos: np.ndarray, pitch: float) -> np.ndarray:
    """(M,) extent of the occupied positions ``pos`` (metres) of each row of ``occ``, ``pitch`` added; 0 if none."""
    hi = np.where(occ, pos[None, :], -np.inf).max(axis=1)
    lo = np.where(occ, pos[None, :], np.inf).min(axis=1)
    return np.where(occ.any(axis=1), hi - lo + pitch, 0.0)


def _span_b(active: np.ndarray, c: TaxelCoords) -> np.ndarray:
    """(M,) extent of the active taxels along b, one pitch added (metres).

    Around a wrapping link: the circumference minus the largest empty arc
    between active taxels (capped at the circumference).
    """
    if c.grid_shape is not None:
        h, w = c.grid_shape
        occ = np.any(active.reshape(-1, h, w), axis=1)
        pos = c.b_m.reshape(h, w)[0]
    else:
        occ, pos = active, c.b_m
    if not c.wraps:
        return _extent(occ, pos, c.pitch_b_m)
    anyocc = occ.any(axis=1)
    order = np.argsort(pos, kind="stable")
    ps = pos[order]
    occ = occ[:, order]
    k = ps.shape[0]
    idx = np.where(occ, np.arange(k)[None, :], -1)
    last = np.maximum.accumulate(idx, axis=1)  # last active index <= column
    prev = np.concatenate([np.full((occ.shape[0], 1), -1), last[:, :-1]], axis=1)
    gap = np.where(occ & (prev >= 0), ps[None, :] - ps[np.maximum(prev, 0)], 0.0)
    first = np.argmax(occ, axis=1)
    wrap_gap = ps[first] + c.circumference_m - ps[np.maximum(last[:, -1], 0)]
    maxgap = np.maximum(gap.max(axis=1), wrap_gap)
    span = np.minimum(c.circumference_m - maxgap + c.pitch_b_m, c.circumference_m)
    return np.where(anyocc, span, 0.0)


def _summaries(sig: np.ndarray, mask: np.ndarray | None = None) -> list[np.ndarray]:
    """Mean, std, range, max of (n, T) signals over time (over ``mask`` if given; 0 if empty)."""
    if mask is None:
        return [sig.mean(axis=1), sig.std(axis=1), sig.max(axis=1) - sig.min(axis=1), sig.max(axis=1)]
    cnt = mask.sum(axis=1)
    has = cnt > 0
    den = np.maximum(cnt, 1)
    mean = np.where(mask, sig, 0.0).sum(axis=1) / den
    std = np.sqrt(np.where(mask, (sig - mean[:, None]) ** 2, 0.0).sum(axis=1) / den)
    hi = np.where(has, np.where(mask, sig, -np.inf).max(axis=1), 0.0)
    lo = np.where(has, np.where(mask, sig, np.inf).min(axis=1), 0.0)
    return [mean, std, hi - lo, hi]


def trial_features(sig: dict[str, np.ndarray], coords: TaxelCoords) -> np.ndarray:
    """(n, 32) float64 features (:data:`FEATURE_NAMES`) from :func:`frame_signals`."""
    area, contact = sig["area"], sig["contact"]
    n, length = area.shape
    cols: list[np.ndarray] = []
    # activation
    cols += _summaries(area)
    if length > 1:
        d = np.diff(area, axis=1)
        d_sum = _summaries(d)
        cols += [np.abs(d).mean(axis=1), d_sum[1], d_sum[2], d_sum[3]]
    else:
        cols += [np.zeros(n)] * 4
    peak = area.max(axis=1)
    above = area > 0.5 * peak[:, None]
    above &= peak[:, None] > 0
    rising = above & ~np.concatenate([np.zeros((n, 1), dtype=bool), above[:, :-1]], axis=1)
    cols += [rising.sum(axis=1).astype(np.float64), contact.mean(axis=1)]
    # motion: centre of pressure relative to the trial's mean (circular around b)
    cnt = np.maximum(contact.sum(axis=1), 1)
    cop_a = sig["cop_a"]
    rel_a = cop_a - (np.where(contact, cop_a, 0.0).sum(axis=1) / cnt)[:, None]
    cop_b = sig["cop_b"]
    if coords.wraps:
        circ = coords.circumference_m
        th = 2.0 * np.pi * cop_b / circ
        mean_b = np.arctan2(np.where(contact, np.sin(th), 0).sum(axis=1), np.where(contact, np.cos(th), 0).sum(axis=1))
        rel_b = _wrap(cop_b - (mean_b * circ / (2.0 * np.pi))[:, None], circ)
        db = _wrap(np.diff(cop_b, axis=1), circ)
    else:
        rel_b = cop_b - (np.where(contact, cop_b, 0.0).sum(axis=1) / cnt)[:, None]
        db = np.diff(cop_b, axis=1)
    s_a = _summaries(rel_a, contact)
    s_b = _summaries(rel_b, contact)
    cols += [s_a[1], s_a[2], s_b[1], s_b[2]]
    if length > 1:
        speed = np.hypot(np.diff(cop_a, axis=1), db)
        pair = contact[:, 1:] & contact[:, :-1]
        s_v = _summaries(speed, pair)
        cols += [s_v[0], s_v[3]]
    else:
        cols += [np.zeros(n)] * 2
    # spatial extent and spread
    cols += _summaries(sig["bbox"])
    cols += _summaries(sig["lcc"])
    cols += _summaries(sig["spread_a"], contact)
    cols += _summaries(sig["spread_b"], contact)
    out = np.column_stack(cols)
    assert out.shape == (n, len(FEATURE_NAMES)), out.shape
    return out


def extract_features(
    x: np.ndarray,
    geometry: TaxelGeometry,
    active_threshold: float = 0.5,
    coords: TaxelCoords | None = None,
) -> np.ndarray:
    """The 32 features of each window: x (n, L, N) readings -> (n, 32) float64.

    Processes trials in chunks (memory stays around ``_CHUNK_ELEMENTS``).
    ``coords`` may be passed to reuse :func:`taxel_coords` of ``geometry``.
    """
    if coords is None:
        coords = taxel_coords(geometry)
    x = check_windows(x, coords.n_taxels)
    n, length, n_tax = x.shape
    out = np.empty((n, len(FEATURE_NAMES)), dtype=np.float64)
    step = max(1, _CHUNK_ELEMENTS // max(1, length * n_tax))
    for i in range(0, n, step):
        sig = frame_signals(x[i : i + step], coords, active_threshold)
        out[i : i + step] = trial_features(sig, coords)
    return out
