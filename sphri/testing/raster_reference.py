"""Supersampled reference rasters, to check the fast encoders (tests, bench).

:func:`reference_raster` samples every taxel cell with ``ss x ss`` points and
tests each against every ellipse of its frame (all wrap images), so its
coverage is the union area up to ``1/ss^2``. Slow and simple on purpose.
"""

from __future__ import annotations

import numpy as np


def reference_raster(
    start: np.ndarray,
    cu: np.ndarray,
    cv: np.ndarray,
    qa: np.ndarray,
    qb: np.ndarray,
    qc: np.ndarray,
    grid_shape: tuple[int, int],
    row_offset: np.ndarray,
    wrap: bool,
    ss: int = 32,
    binary: bool = True,
    threshold: float = 0.5,
) -> np.ndarray:
    """Same contract as :func:`sphri.encode.raster.rasterize`, by brute-force supersampling."""
    h, w = grid_shape
    m = len(start) - 1
    cov = np.zeros((m, h, w), dtype=np.float64)
    forced = np.zeros((m, h, w), dtype=bool)
    sub = (np.arange(ss) + 0.5) / ss
    for f in range(m):
        inside = np.zeros((h * ss, w * ss), dtype=bool)
        for k in range(start[f], start[f + 1]):
            det = qa[k] * qc[k] - qb[k] ** 2
            hu = np.sqrt(qc[k] / det)
            hv = np.sqrt(qa[k] / det)
            r_lo = max(int(np.floor(cu[k] - hu)), 0)
            r_hi = min(int(np.ceil(cu[k] + hu)), h - 1)
            r0 = min(max(int(np.floor(cu[k])), 0), h - 1)
            c0 = int(np.floor(cv[k] - row_offset[r0]))
            c0 = c0 % w if wrap else min(max(c0, 0), w - 1)
            forced[f, r0, c0] = True
            if r_hi < r_lo:
                continue
            rows = np.arange(r_lo, r_hi + 1)
            y = (rows[:, None] + sub[None, :]).reshape(-1)  # (R*ss,)
            x = (np.arange(w)[:, None] + sub[None, :]).reshape(-1)  # (W*ss,)
            off = np.repeat(row_offset[rows], ss)
            dy = (y - cu[k])[:, None]
            xx = x[None, :] + off[:, None]
            shifts = range(-int(np.ceil(hv / w)) - 1, int(np.ceil(hv / w)) + 2) if wrap else (0,)
            hit = np.zeros((len(y), len(x)), dtype=bool)
            for s in shifts:
                dx = xx + s * w - cv[k]
                hit |= qa[k] * dy * dy + 2 * qb[k] * dy * dx + qc[k] * dx * dx <= 1.0
            inside[r_lo * ss : (r_hi + 1) * ss] |= hit
        cov[f] = inside.reshape(h, ss, w, ss).mean(axis=(1, 3))
    flat = cov.reshape(m, h * w)
    if not binary:
        return flat.astype(np.float32)
    return ((flat >= threshold - 1e-9) | forced.reshape(m, h * w)).astype(np.uint8)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two binary arrays (1.0 when both are empty)."""
    a = np.asarray(a).astype(bool)
    b = np.asarray(b).astype(bool)
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)
