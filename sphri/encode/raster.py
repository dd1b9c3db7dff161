"""Ellipse rasterizer for chart grids (numba).

A contact patch (a disc of ``patch_radius_m`` on the triangle's plane at
``point_m``) maps into the chart as an ellipse through the local Jacobian of
the map: ``uv0 + J [e1 e2] r w`` for ``|w| <= 1``. In cell units (rows along
u, columns along v) it is ``{x : x^T Q x <= 1}`` around its centre.

The raster cuts every taxel row into ``subsamples`` sub-rows; on each sub-row
the ellipse is an exact interval in v, which wraps around the seam when the
chart does. Per frame the intervals of all patches are merged (a union, so
overlapping patches are not counted twice) and their length is accumulated
into the cells: coverage is exact along v and sampled along u. Patches
thinner than two sub-rows are not sampled: their exact area goes to the row of
their centre, split over the columns by the ellipse's chords. Binary
readings are ``coverage >= threshold``, and the taxel holding a patch centre
is always on, so a patch smaller than a taxel still activates it. Hex grids
shift odd rows by half a cell (``row_offset``).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from sphri.encode.common import tangent_basis
from sphri.surface.charts import jacobian, to_uv
from sphri.types import SurfaceMap


def patch_ellipses(
    surface: SurfaceMap,
    point_m: np.ndarray,
    normal: np.ndarray,
    radius_m: np.ndarray,
    grid_shape: tuple[int, int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Chart ellipses of K contact patches in cell units.

    Returns centre ``cu, cv (K,)`` (row and column coordinates, cells) and the
    quadratic form ``qa, qb, qc (K,)`` of ``Q = [[qa, qb], [qb, qc]]``. A
    1e-6-cell floor on the semi-axes keeps ``Q`` finite for patches seen
    edge-on (e.g. on a cylinder's end cap, where the angle's derivative
    vanishes in one direction).
    """
    h, w = grid_shape
    k = point_m.shape[0]
    if k == 0:
        z = np.zeros(0)
        return z, z, z, z, z
    uv = to_uv(surface, point_m)
    jac = jacobian(surface, point_m)  # (K, 2, 3)
    e1, e2 = tangent_basis(normal)
    # rows of A = diag(H, W) J [e1 e2] r: the patch's two radii mapped into cell units
    ju = jac[:, 0, :] * (h * radius_m)[:, None]
    jv = jac[:, 1, :] * (w * radius_m)[:, None]
    a00, a01 = (ju * e1).sum(axis=1), (ju * e2).sum(axis=1)
    a10, a11 = (jv * e1).sum(axis=1), (jv * e2).sum(axis=1)
    eps = 1e-6
    m00 = a00 * a00 + a01 * a01 + eps * eps  # M = A A^T
    m11 = a10 * a10 + a11 * a11 + eps * eps
    m01 = a00 * a10 + a01 * a11
    det = m00 * m11 - m01 * m01
    return uv[:, 0] * h, uv[:, 1] * w, m11 / det, -m01 / det, m00 / det


@njit(cache=True)
def _touch(cell, mark, touched, n_touched):  # pragma: no cover - numba
    if mark[cell] == 0:
        mark[cell] = 1
        touched[n_touched] = cell
        n_touched += 1
    return n_touched


@njit(cache=True)
def _chord_integral(x, hv):  # pragma: no cover - numba
    """Integral from 0 to x of 2 sqrt(hv^2 - t^2) dt (|x| <= hv)."""
    x = min(max(x, -hv), hv)
    return x * np.sqrt(max(hv * hv - x * x, 0.0)) + hv * hv * np.arcsin(x / hv)


@njit(cache=True)
def _add_interval(s, x0, x1, n_int, head, nxt, a0, a1, subs, n_subs):  # pragma: no cover - numba
    """Push [x0, x1) onto sub-row ``s``'s list; returns (n_int, n_subs)."""
    if head[s] < 0:
        subs[n_subs] = s
        n_subs += 1
    a0[n_int] = x0
    a1[n_int] = x1
    nxt[n_int] = head[s]
    head[s] = n_int
    return n_int + 1, n_subs


@njit(cache=True)
def _intervals(cap):  # pragma: no cover - numba
    """Interval scratch for ``cap`` intervals: (next in bucket, start, end, sort buffer)."""
    return (
        np.empty(cap, dtype=np.int64),
        np.empty(cap, dtype=np.float64),
        np.empty(cap, dtype=np.float64),
        np.empty(cap, dtype=np.int64),
    )


@njit(cache=True)
def _raster_frame(
    lo, hi, ellipses, h, w, ss, row_offset, wrap, cov, mark, forced, touched, head, subs, intervals
):  # pragma: no cover - numba
    """Accumulate the union of ellipses ``lo..hi-1`` into ``cov``.

    ``ellipses`` is ``(cu, cv, qa, qb, qc)``, ``intervals`` the scratch of :func:`_intervals`.
    Intervals are bucketed per sub-row (``head``/``nxt`` linked lists), then
    each sub-row's few intervals are sorted, merged and spread over the cells.
    Returns the number of touched cells (listed in ``touched``), or -1 when
    the interval scratch (``nxt``/``a0``/``a1``) is too small.
    """
    cu, cv, qa, qb, qc = ellipses
    nxt, a0, a1, tmp = intervals
    n_touched = 0
    n_int = 0
    n_subs = 0
    n_sub = h * ss
    cap = a0.shape[0]
    for k in range(lo, hi):
        # the centre cell (always on in binary mode)
        r0 = min(max(int(np.floor(cu[k])), 0), h - 1)
        c0 = int(np.floor(cv[k] - row_offset[r0]))
        c0 = c0 % w if wrap else min(max(c0, 0), w - 1)
        cell0 = r0 * w + c0
        forced[cell0] = 1
        n_touched = _touch(cell0, mark, touched, n_touched)
        detq = qa[k] * qc[k] - qb[k] * qb[k]
        hu = np.sqrt(qc[k] / detq)
        if 2.0 * hu * ss < 2.0:
            # thinner than two sub-rows: sampling in u would be coarse, so its exact
            # area goes to the centre row, split over columns by the ellipse's chords
            hv = np.sqrt(qa[k] / detq)
            xc = cv[k] - row_offset[r0]
            scale = np.sqrt(detq) / qa[k]
            for j in range(int(np.floor(xc - hv)), int(np.ceil(xc + hv))):
                xa = max(float(j), xc - hv) - xc
                xb = min(j + 1.0, xc + hv) - xc
                if xb <= xa:
                    continue
                area = scale * (_chord_integral(xb, hv) - _chord_integral(xa, hv))
                if wrap:
                    jj = j % w
                elif j < 0 or j >= w:
                    continue
                else:
                    jj = j
                cell = r0 * w + jj
                n_touched = _touch(cell, mark, touched, n_touched)
                cov[cell] += area
            continue
        s_lo = max(int(np.ceil((cu[k] - hu) * ss - 0.5)), 0)
        s_hi = min(int(np.floor((cu[k] + hu) * ss - 0.5)), n_sub - 1)
        for s in range(s_lo, s_hi + 1):
            dy = (s + 0.5) / ss - cu[k]
            disc = qc[k] - detq * dy * dy
            if disc < 0.0:
                continue
            half = np.sqrt(disc) / qc[k]
            mid = cv[k] - qb[k] * dy / qc[k]
            r = s // ss
            x0 = mid - half - row_offset[r]
            x1 = mid + half - row_offset[r]
            if n_int + 2 > cap:
                for q in range(n_subs):  # leave the buckets clean for the retry
                    head[subs[q]] = -1
                return -1
            if wrap:
                if x1 - x0 >= w:
                    n_int, n_subs = _add_interval(s, 0.0, float(w), n_int, head, nxt, a0, a1, subs, n_subs)
                else:
                    xm = x0 - np.floor(x0 / w) * w
                    if xm >= w:
                        xm = 0.0
                    xe = xm + (x1 - x0)
                    if xe > w:
                        n_int, n_subs = _add_interval(s, xm, float(w), n_int, head, nxt, a0, a1, subs, n_subs)
                        n_int, n_subs = _add_interval(s, 0.0, xe - w, n_int, head, nxt, a0, a1, subs, n_subs)
                    else:
                        n_int, n_subs = _add_interval(s, xm, xe, n_int, head, nxt, a0, a1, subs, n_subs)
            else:
                x0 = max(x0, 0.0)
                x1 = min(x1, float(w))
                if x1 > x0:
                    n_int, n_subs = _add_interval(s, x0, x1, n_int, head, nxt, a0, a1, subs, n_subs)
    # per sub-row: sort its intervals by start, merge overlaps, spread over the cells
    inv_ss = 1.0 / ss
    for q in range(n_subs):
        s = subs[q]
        r = s // ss
        n = 0
        i = head[s]
        head[s] = -1
        while i >= 0:
            if n >= tmp.shape[0]:
                break  # cannot happen: tmp is as long as the interval scratch
            # insertion by start
            t = n
            while t > 0 and a0[tmp[t - 1]] > a0[i]:
                tmp[t] = tmp[t - 1]
                t -= 1
            tmp[t] = i
            n += 1
            i = nxt[i]
        cur_a = a0[tmp[0]]
        cur_b = a1[tmp[0]]
        for t in range(1, n + 1):
            if t < n:
                i = tmp[t]
                if a0[i] <= cur_b:
                    if a1[i] > cur_b:
                        cur_b = a1[i]
                    continue
            for j in range(max(int(np.floor(cur_a)), 0), min(int(np.ceil(cur_b)), w)):
                ov = min(cur_b, j + 1.0) - max(cur_a, float(j))
                if ov > 0.0:
                    cell = r * w + j
                    n_touched = _touch(cell, mark, touched, n_touched)
                    cov[cell] += ov * inv_ss
            if t < n:
                cur_a = a0[i]
                cur_b = a1[i]
    return n_touched


@njit(cache=True, parallel=True)
def _raster_all(
    start, cu, cv, qa, qb, qc, h, w, ss, row_offset, wrap, binary, threshold, out_u8, out_f32, n_chunks
):  # pragma: no cover - numba
    m_total = start.shape[0] - 1
    n_cells = h * w
    ellipses = (cu, cv, qa, qb, qc)
    for c in prange(n_chunks):
        m0 = (m_total * c) // n_chunks
        m1 = (m_total * (c + 1)) // n_chunks
        cov = np.zeros(n_cells, dtype=np.float64)
        mark = np.zeros(n_cells, dtype=np.uint8)
        forced = np.zeros(n_cells, dtype=np.uint8)
        touched = np.zeros(n_cells, dtype=np.int64)
        head = np.full(h * ss, -1, dtype=np.int64)
        subs = np.zeros(h * ss, dtype=np.int64)
        cap = 1024
        intervals = _intervals(cap)
        for m in range(m0, m1):
            lo = start[m]
            hi = start[m + 1]
            if hi == lo:
                continue
            while True:
                n_t = _raster_frame(
                    lo, hi, ellipses, h, w, ss, row_offset, wrap, cov, mark, forced, touched, head, subs, intervals
                )
                if n_t >= 0:
                    break
                # interval scratch too small: reset, grow, redo the frame
                for cell in range(n_cells):
                    cov[cell] = 0.0
                    mark[cell] = 0
                    forced[cell] = 0
                cap *= 4
                intervals = _intervals(cap)
            for t in range(n_t):
                cell = touched[t]
                val = cov[cell]
                if binary:
                    out_u8[m, cell] = 1 if (val >= threshold - 1e-9 or forced[cell] == 1) else 0
                else:
                    out_f32[m, cell] = min(val, 1.0)
                cov[cell] = 0.0
                mark[cell] = 0
                forced[cell] = 0
    return 0


def rasterize(
    start: np.ndarray,
    cu: np.ndarray,
    cv: np.ndarray,
    qa: np.ndarray,
    qb: np.ndarray,
    qc: np.ndarray,
    grid_shape: tuple[int, int],
    row_offset: np.ndarray,
    wrap: bool,
    subsamples: int,
    binary: bool,
    threshold: float = 0.5,
) -> np.ndarray:
    """Rasterize ellipses grouped by frame: frame m owns rows ``start[m]:start[m+1]``.

    Returns (M, H*W) uint8 (binary) or float32 (covered fraction in [0, 1]).
    """
    h, w = grid_shape
    m = len(start) - 1
    n = h * w
    out_u8 = np.zeros((m, n) if binary else (0, 0), dtype=np.uint8)
    out_f32 = np.zeros((0, 0) if binary else (m, n), dtype=np.float32)
    if m == 0 or start[-1] == 0:
        return out_u8 if binary else out_f32
    n_chunks = int(min(max(1, m // 256), 64))
    start_c = np.ascontiguousarray(start, dtype=np.int64)
    cu_c, cv_c, qa_c, qb_c, qc_c = (np.ascontiguousarray(x, dtype=np.float64) for x in (cu, cv, qa, qb, qc))
    _raster_all(
        start_c,
        cu_c,
        cv_c,
        qa_c,
        qb_c,
        qc_c,
        int(h),
        int(w),
        int(subsamples),
        np.ascontiguousarray(row_offset, dtype=np.float64),
        bool(wrap),
        bool(binary),
        float(threshold),
        out_u8,
        out_f32,
        n_chunks,
    )
    return out_u8 if binary else out_f32
