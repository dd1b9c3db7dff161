"""3-D taxel encoders' kernels: a voxel hash over taxels and per-frame loops (numba).

Used by ``encoder=coverage`` on layouts without a chart grid and by
``encoder=proximity``. Taxels are bucketed in a dense voxel grid (CSR); each
contact visits only the voxels its query ball overlaps.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


class VoxelHash:
    """Taxel positions bucketed into cubes of ``cell_m`` metres (CSR over a dense grid)."""

    def __init__(self, positions: np.ndarray, cell_m: float) -> None:
        p = np.asarray(positions, dtype=np.float64)
        self.cell_m = float(cell_m)
        self.origin = p.min(axis=0) - 1e-9
        idx = np.floor((p - self.origin) / self.cell_m).astype(np.int64)
        self.dims = (idx.max(axis=0) + 1).astype(np.int64)
        flat = (idx[:, 0] * self.dims[1] + idx[:, 1]) * self.dims[2] + idx[:, 2]
        order = np.argsort(flat, kind="stable")
        self.order = order.astype(np.int64)
        counts = np.bincount(flat, minlength=int(np.prod(self.dims)))
        self.start = np.zeros(counts.size + 1, dtype=np.int64)
        np.cumsum(counts, out=self.start[1:])


def voxel_size(positions: np.ndarray, spacing_m: float) -> float:
    """A voxel edge (metres) holding a few taxels, with at most ~4M voxels."""
    ext = np.ptp(np.asarray(positions), axis=0).max() if len(positions) else 1.0
    return float(max(spacing_m, 1e-4, ext / 150.0))


@njit(cache=True)
def _visit(hash_origin, cell, dims, vstart, vorder, c, radius, out, n_out):  # pragma: no cover - numba
    """Append to ``out`` the taxels in voxels overlapping the ball (c, radius)."""
    lo0 = max(int(np.floor((c[0] - radius - hash_origin[0]) / cell)), 0)
    lo1 = max(int(np.floor((c[1] - radius - hash_origin[1]) / cell)), 0)
    lo2 = max(int(np.floor((c[2] - radius - hash_origin[2]) / cell)), 0)
    hi0 = min(int(np.floor((c[0] + radius - hash_origin[0]) / cell)), dims[0] - 1)
    hi1 = min(int(np.floor((c[1] + radius - hash_origin[1]) / cell)), dims[1] - 1)
    hi2 = min(int(np.floor((c[2] + radius - hash_origin[2]) / cell)), dims[2] - 1)
    for i in range(lo0, hi0 + 1):
        for j in range(lo1, hi1 + 1):
            base = (i * dims[1] + j) * dims[2]
            for k in range(lo2, hi2 + 1):
                v = base + k
                for t in range(vstart[v], vstart[v + 1]):
                    if n_out >= out.shape[0]:
                        return n_out
                    out[n_out] = vorder[t]
                    n_out += 1
    return n_out


@njit(cache=True, inline="always")
def _facing_dist2(t, k, tpos, tnormal, point, cnormal):  # pragma: no cover - numba
    """(taxel t faces the same way as contact k (``n_t . n > 0``), squared distance from taxel t to
    ``point[k]``); the distance is 0 when it does not face it."""
    dn = tnormal[t, 0] * cnormal[k, 0] + tnormal[t, 1] * cnormal[k, 1] + tnormal[t, 2] * cnormal[k, 2]
    if dn <= 0.0:
        return False, 0.0
    dx = tpos[t, 0] - point[k, 0]
    dy = tpos[t, 1] - point[k, 1]
    dz = tpos[t, 2] - point[k, 2]
    return True, dx * dx + dy * dy + dz * dz


@njit(cache=True, parallel=True)
def coverage_kernel(
    start,
    centre,
    cnormal,
    cradius,
    tpos,
    tnormal,
    tradius,
    samples,
    hash_origin,
    cell,
    dims,
    vstart,
    vorder,
    out,
    n_chunks,
):  # pragma: no cover - numba
    """out[m, t] = fraction of taxel t's sample points inside any patch of frame m.

    A sample point q of taxel t is covered by patch (c, n, r) when
    ``|q - c| <= r`` and the taxel faces the same way (``n_t . n > 0``).
    """
    m_total = start.shape[0] - 1
    n_tax = tpos.shape[0]
    s_per = samples.shape[1]
    tr_max = 0.0
    for t in range(n_tax):
        tr_max = max(tr_max, tradius[t])
    for ch in prange(n_chunks):
        m0 = (m_total * ch) // n_chunks
        m1 = (m_total * (ch + 1)) // n_chunks
        bits = np.zeros((n_tax, s_per), dtype=np.uint8)
        mark = np.zeros(n_tax, dtype=np.uint8)
        touched = np.zeros(n_tax, dtype=np.int64)
        cand = np.zeros(n_tax, dtype=np.int64)
        for m in range(m0, m1):
            n_t = 0
            for k in range(start[m], start[m + 1]):
                r = cradius[k]
                nc = _visit(hash_origin, cell, dims, vstart, vorder, centre[k], r + tr_max, cand, 0)
                for q in range(nc):
                    t = cand[q]
                    facing, d2 = _facing_dist2(t, k, tpos, tnormal, centre, cnormal)
                    reach = r + tradius[t]
                    if not facing or d2 > reach * reach:
                        continue
                    for s in range(s_per):
                        if bits[t, s] == 1:
                            continue
                        ex = samples[t, s, 0] - centre[k, 0]
                        ey = samples[t, s, 1] - centre[k, 1]
                        ez = samples[t, s, 2] - centre[k, 2]
                        if ex * ex + ey * ey + ez * ez <= r * r:
                            bits[t, s] = 1
                            if mark[t] == 0:
                                mark[t] = 1
                                touched[n_t] = t
                                n_t += 1
            for q in range(n_t):
                t = touched[q]
                cnt = 0
                for s in range(s_per):
                    cnt += bits[t, s]
                    bits[t, s] = 0
                out[m, t] = cnt / s_per
                mark[t] = 0
    return 0


@njit(cache=True, parallel=True)
def proximity_kernel(
    start,
    sphere,
    sradius,
    cnormal,
    tpos,
    tnormal,
    sensing,
    depth_scale,
    hash_origin,
    cell,
    dims,
    vstart,
    vorder,
    binary,
    out_u8,
    out_f32,
    n_chunks,
):  # pragma: no cover - numba
    """Taxel t reads capsule sphere (s, rc) of frame m when ``|p_t - s| - rc <= sensing``.

    ``binary``: 1; else ``clip((sensing - d) / (sensing + depth_scale), 0, 1)``
    with d = |p_t - s| - rc (negative inside the capsule), max over capsules.
    Taxels facing away from the contact (``n_t . n <= 0``) do not sense it.
    """
    m_total = start.shape[0] - 1
    n_tax = tpos.shape[0]
    for ch in prange(n_chunks):
        m0 = (m_total * ch) // n_chunks
        m1 = (m_total * (ch + 1)) // n_chunks
        cand = np.zeros(n_tax, dtype=np.int64)
        for m in range(m0, m1):
            for k in range(start[m], start[m + 1]):
                reach = sradius[k] + sensing
                nc = _visit(hash_origin, cell, dims, vstart, vorder, sphere[k], reach, cand, 0)
                for q in range(nc):
                    t = cand[q]
                    facing, d2 = _facing_dist2(t, k, tpos, tnormal, sphere, cnormal)
                    if not facing:
                        continue
                    d = np.sqrt(d2) - sradius[k]
                    if d > sensing:
                        continue
                    if binary:
                        out_u8[m, t] = 1
                    else:
                        val = (sensing - d) / (sensing + depth_scale)
                        val = min(max(val, 0.0), 1.0)
                        if val > out_f32[m, t]:
                            out_f32[m, t] = val
    return 0


def sunflower_disc(n: int) -> np.ndarray:
    """(n, 2) points evenly spread over the unit disc (Vogel's sunflower spiral)."""
    i = np.arange(n) + 0.5
    r = np.sqrt(i / n)
    th = i * np.pi * (3.0 - np.sqrt(5.0))
    return np.column_stack([r * np.cos(th), r * np.sin(th)])
