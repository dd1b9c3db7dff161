"""Compiled (numba) kernels of the exact capsule-vs-mesh query.

Everything is scalar float64 arithmetic in the mesh's local frame (see
:mod:`sphri.contact.mesh`); the public entry point is
:func:`sphri.contact.query.capsule_mesh_query`.

Per capsule (segment p0-p1, radius r, reach R = r + margin):

1. the capsule's box (segment box grown by R) against the mesh box: far;
2. the exact distance to a seed triangle (nearest to the grid cell of the
   segment's midpoint), which makes the bound tight from the start;
3. a nearest-triangle search down the BVH, bounded by R or the best so far:
   a node is skipped when the gap between its box and the segment's box is
   not below the bound; a triangle when both ends lie on one side of its
   plane farther than the bound, or beyond one edge's side plane with
   ``h^2 + sigma^2`` not below it (:func:`_side_bound2`); the rest get the
   exact segment-triangle distance (:func:`_seg_tri`);
4. found within R: inside is tested at the segment's closest point (hull
   planes, starting with the one nearest the found triangle; then the
   winding number for ``winding``). Nothing within R: the segment is
   clipped to the hull (Cyrus-Beck); wholly outside means far, otherwise
   the search goes on without a bound (an inside capsule needs its
   distance whatever it is).

The segment-triangle distance is exact in float64: zero when the segment
crosses the triangle's interior, the nearer end's plane distance when that
end projects into the triangle, otherwise the least of the two
endpoint-to-triangle distances (Ericson's Voronoi regions) and the three
segment-to-edge distances; degenerate triangles are their edges. Kernels
take arrays as separate arguments (numba 0.68 mis-lowers unpacking long
tuples of arrays inside prange loops) and only small helpers are inlined.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

_INF = np.inf
_FOUR_PI = 4.0 * np.pi
_STACK = 256
_BLOCK = 512


@njit(cache=True, fastmath=False)
def _clamp01(x):
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@njit(cache=True, fastmath=False, inline="always")
def _on_edge(px, py, pz, ox, oy, oz, ex, ey, ez, t):
    """The point q = o + t * e and its squared distance to p: (d2, qx, qy, qz)."""
    qx = ox + t * ex
    qy = oy + t * ey
    qz = oz + t * ez
    dx = px - qx
    dy = py - qy
    dz = pz - qz
    return dx * dx + dy * dy + dz * dz, qx, qy, qz


@njit(cache=True, fastmath=False)
def _pt_tri(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of a non-degenerate triangle to p: (d2, qx, qy, qz, u, v, w)."""
    abx = bx - ax
    aby = by - ay
    abz = bz - az
    acx = cx - ax
    acy = cy - ay
    acz = cz - az
    apx = px - ax
    apy = py - ay
    apz = pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return apx * apx + apy * apy + apz * apz, ax, ay, az, 1.0, 0.0, 0.0
    bpx = px - bx
    bpy = py - by
    bpz = pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bpx * bpx + bpy * bpy + bpz * bpz, bx, by, bz, 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        d2e, qx, qy, qz = _on_edge(px, py, pz, ax, ay, az, abx, aby, abz, t)
        return d2e, qx, qy, qz, 1.0 - t, t, 0.0
    cpx = px - cx
    cpy = py - cy
    cpz = pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cpx * cpx + cpy * cpy + cpz * cpz, cx, cy, cz, 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        d2e, qx, qy, qz = _on_edge(px, py, pz, ax, ay, az, acx, acy, acz, t)
        return d2e, qx, qy, qz, 1.0 - t, 0.0, t
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        d2e, qx, qy, qz = _on_edge(px, py, pz, bx, by, bz, cx - bx, cy - by, cz - bz, t)
        return d2e, qx, qy, qz, 0.0, 1.0 - t, t
    den = 1.0 / (va + vb + vc)
    v = vb * den
    w = vc * den
    qx = ax + abx * v + acx * w
    qy = ay + aby * v + acy * w
    qz = az + abz * v + acz * w
    dx = px - qx
    dy = py - qy
    dz = pz - qz
    return dx * dx + dy * dy + dz * dz, qx, qy, qz, 1.0 - v - w, v, w


@njit(cache=True, fastmath=False)
def _seg_seg(px, py, pz, ux, uy, uz, qx, qy, qz, vx, vy, vz):
    """Closest points of p + s*u and q + t*v, s, t in [0, 1]: (d2, s, t)."""
    rx = px - qx
    ry = py - qy
    rz = pz - qz
    a = ux * ux + uy * uy + uz * uz
    e = vx * vx + vy * vy + vz * vz
    f = vx * rx + vy * ry + vz * rz
    if a <= 0.0 and e <= 0.0:
        s = 0.0
        t = 0.0
    elif a <= 0.0:
        s = 0.0
        t = _clamp01(f / e)
    else:
        c = ux * rx + uy * ry + uz * rz
        if e <= 0.0:
            t = 0.0
            s = _clamp01(-c / a)
        else:
            b = ux * vx + uy * vy + uz * vz
            denom = a * e - b * b
            if denom > 0.0:
                s = _clamp01((b * f - c * e) / denom)
            else:
                s = 0.0
            tnom = b * s + f
            if tnom < 0.0:
                t = 0.0
                s = _clamp01(-c / a)
            elif tnom > e:
                t = 1.0
                s = _clamp01((b - c) / a)
            else:
                t = tnom / e
    dx = rx + s * ux - t * vx
    dy = ry + s * uy - t * vy
    dz = rz + s * uz - t * vz
    return dx * dx + dy * dy + dz * dz, s, t


@njit(cache=True, fastmath=False)
def _in_tri(xx, xy, xz, ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz):
    """Barycentric (u, v, w) of a point in a triangle's plane and whether all are >= 0."""
    # signed areas of the sub-triangles opposite each vertex, along n
    ax_ = ax - xx
    ay_ = ay - xy
    az_ = az - xz
    bx_ = bx - xx
    by_ = by - xy
    bz_ = bz - xz
    cx_ = cx - xx
    cy_ = cy - xy
    cz_ = cz - xz
    wa = nx * (by_ * cz_ - bz_ * cy_) + ny * (bz_ * cx_ - bx_ * cz_) + nz * (bx_ * cy_ - by_ * cx_)
    wb = nx * (cy_ * az_ - cz_ * ay_) + ny * (cz_ * ax_ - cx_ * az_) + nz * (cx_ * ay_ - cy_ * ax_)
    wc = nx * (ay_ * bz_ - az_ * by_) + ny * (az_ * bx_ - ax_ * bz_) + nz * (ax_ * by_ - ay_ * bx_)
    ok = wa >= 0.0 and wb >= 0.0 and wc >= 0.0
    tot = wa + wb + wc
    if ok and tot > 0.0:
        return True, wa / tot, wb / tot, wc / tot
    return False, 0.0, 0.0, 0.0


@njit(cache=True, fastmath=False)
def _seg_tri(p0x, p0y, p0z, p1x, p1y, p1z, ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz, deg, s0, s1, best2):
    """Segment-triangle distance: (d2, t, qx, qy, qz, u, v, w), or d2 = inf when not below best2.

    s0, s1 are the signed distances of the ends to the triangle's plane
    (ignored when ``deg``).
    """
    ux = p1x - p0x
    uy = p1y - p0y
    uz = p1z - p0z
    if not deg:
        if (s0 > 0.0 and s1 < 0.0) or (s0 < 0.0 and s1 > 0.0):
            t = s0 / (s0 - s1)
            xx = p0x + t * ux
            xy = p0y + t * uy
            xz = p0z + t * uz
            ok, bu, bv, bw = _in_tri(xx, xy, xz, ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz)
            if ok:
                return 0.0, t, xx, xy, xz, bu, bv, bw
        elif s0 != 0.0 or s1 != 0.0:
            # same side: if the nearer end projects into the triangle, that is the answer
            if abs(s0) <= abs(s1):
                t = 0.0
                sn = s0
                ex = p0x
                ey = p0y
                ez = p0z
            else:
                t = 1.0
                sn = s1
                ex = p1x
                ey = p1y
                ez = p1z
            xx = ex - sn * nx
            xy = ey - sn * ny
            xz = ez - sn * nz
            ok, bu, bv, bw = _in_tri(xx, xy, xz, ax, ay, az, bx, by, bz, cx, cy, cz, nx, ny, nz)
            if ok:
                return sn * sn, t, xx, xy, xz, bu, bv, bw
    bd = best2
    bt = 0.0
    bqx = 0.0
    bqy = 0.0
    bqz = 0.0
    bu = 0.0
    bv = 0.0
    bw = 0.0
    found = False
    # the two ends (t = 0, 1)
    for e in range(0 if deg else 2):
        if e == 0:
            d2, qx, qy, qz, u, v, w = _pt_tri(p0x, p0y, p0z, ax, ay, az, bx, by, bz, cx, cy, cz)
        else:
            d2, qx, qy, qz, u, v, w = _pt_tri(p1x, p1y, p1z, ax, ay, az, bx, by, bz, cx, cy, cz)
        if d2 < bd:
            bd = d2
            bt = float(e)
            bqx = qx
            bqy = qy
            bqz = qz
            bu = u
            bv = v
            bw = w
            found = True
    # edges a->b, b->c, c->a
    for k in range(3):
        if k == 0:
            ox = ax
            oy = ay
            oz = az
            vx = bx - ax
            vy = by - ay
            vz = bz - az
        elif k == 1:
            ox = bx
            oy = by
            oz = bz
            vx = cx - bx
            vy = cy - by
            vz = cz - bz
        else:
            ox = cx
            oy = cy
            oz = cz
            vx = ax - cx
            vy = ay - cy
            vz = az - cz
        d2, s, te = _seg_seg(p0x, p0y, p0z, ux, uy, uz, ox, oy, oz, vx, vy, vz)
        if d2 < bd:
            bd = d2
            bt = s
            bqx = ox + te * vx
            bqy = oy + te * vy
            bqz = oz + te * vz
            if k == 0:
                bu = 1.0 - te
                bv = te
                bw = 0.0
            elif k == 1:
                bu = 0.0
                bv = 1.0 - te
                bw = te
            else:
                bu = te
                bv = 0.0
                bw = 1.0 - te
            found = True
    if not found:
        return _INF, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return bd, bt, bqx, bqy, bqz, bu, bv, bw


@njit(cache=True, fastmath=False)
def _solid_angle(qx, qy, qz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Signed solid angle of triangle abc seen from q (Van Oosterom & Strackee)."""
    ax -= qx
    ay -= qy
    az -= qz
    bx -= qx
    by -= qy
    bz -= qz
    cx -= qx
    cy -= qy
    cz -= qz
    la = np.sqrt(ax * ax + ay * ay + az * az)
    lb = np.sqrt(bx * bx + by * by + bz * bz)
    lc = np.sqrt(cx * cx + cy * cy + cz * cz)
    num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    den = (
        la * lb * lc
        + (ax * bx + ay * by + az * bz) * lc
        + (bx * cx + by * cy + bz * cz) * la
        + (cx * ax + cy * ay + cz * az) * lb
    )
    return 2.0 * np.arctan2(num, den)


@njit(cache=True, fastmath=False)
def _winding(qx, qy, qz, TRI, NB, NI, CS, CU, CV, stack):
    """Generalized winding number of the mesh at q, hierarchical (exact up to rounding)."""
    total = 0.0
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        k = stack[top]
        outside = qx < NB[k, 0] or qx > NB[k, 3] or qy < NB[k, 1] or qy > NB[k, 4] or qz < NB[k, 2] or qz > NB[k, 5]
        if outside and CS[k, 0] >= 0:
            ex = 0.5 * (NB[k, 0] + NB[k, 3])
            ey = 0.5 * (NB[k, 1] + NB[k, 4])
            ez = 0.5 * (NB[k, 2] + NB[k, 5])
            s = CS[k, 0]
            for e in range(s, s + CS[k, 1]):
                total += _solid_angle(
                    qx, qy, qz, ex, ey, ez, CU[e, 0], CU[e, 1], CU[e, 2], CV[e, 0], CV[e, 1], CV[e, 2]
                )
        elif NI[k, 0] < 0:
            s = NI[k, 2]
            for j in range(s, s + NI[k, 3]):
                total += _solid_angle(
                    qx,
                    qy,
                    qz,
                    TRI[j, 0],
                    TRI[j, 1],
                    TRI[j, 2],
                    TRI[j, 3],
                    TRI[j, 4],
                    TRI[j, 5],
                    TRI[j, 6],
                    TRI[j, 7],
                    TRI[j, 8],
                )
        else:
            stack[top] = NI[k, 0]
            stack[top + 1] = NI[k, 1]
            top += 2
    return total / _FOUR_PI


@njit(cache=True, fastmath=False)
def _box_gap2(slo0, slo1, slo2, shi0, shi1, shi2, NB, k):
    """Squared gap between the segment's box and node k's box (a lower bound)."""
    g = 0.0
    d = NB[k, 0] - shi0
    if d > 0.0:
        g += d * d
    else:
        d = slo0 - NB[k, 3]
        if d > 0.0:
            g += d * d
    d = NB[k, 1] - shi1
    if d > 0.0:
        g += d * d
    else:
        d = slo1 - NB[k, 4]
        if d > 0.0:
            g += d * d
    d = NB[k, 2] - shi2
    if d > 0.0:
        g += d * d
    else:
        d = slo2 - NB[k, 5]
        if d > 0.0:
            g += d * d
    return g


@njit(cache=True, fastmath=False)
def _side_bound2(p0x, p0y, p0z, p1x, p1y, p1z, TRI, j, h0, h1):
    """Lower bound on the squared segment-triangle distance from the edge side planes.

    The triangle lies in its plane behind each edge's side plane (in-plane
    outward normal m_k). Where both ends are in front of side plane k by
    sigma(s) >= 0, every segment point is at least sqrt(h(s)^2 + sigma(s)^2)
    from the triangle; h and sigma are affine in s, so the bound is the
    minimum of a 1-D quadratic. Returns 0 when no side plane separates.
    """
    best = 0.0
    for k in range(3):
        o = 12 + 3 * k
        mx = TRI[j, o]
        my = TRI[j, o + 1]
        mz = TRI[j, o + 2]
        off = TRI[j, 21 + k]
        g0 = mx * p0x + my * p0y + mz * p0z - off
        if g0 <= 0.0:
            continue
        g1 = mx * p1x + my * p1y + mz * p1z - off
        if g1 <= 0.0:
            continue
        dh = h1 - h0
        dg = g1 - g0
        den = dh * dh + dg * dg
        s = 0.0
        if den > 0.0:
            s = _clamp01(-(h0 * dh + g0 * dg) / den)
        h = h0 + s * dh
        g = g0 + s * dg
        v = h * h + g * g
        if v > best:
            best = v
    return best


@njit(cache=True, fastmath=False)
def _nearest(p0x, p0y, p0z, p1x, p1y, p1z, best2, TRI, DEG, NB, NI, stack, bj, bt, bqx, bqy, bqz, bu, bv, bw):
    """Nearest triangle to the segment closer than sqrt(best2).

    (bj, bt, ...) is the record so far (bj = -1: none; triangle bj is not
    tested again). Returns (d2, j, t, qx, qy, qz, u, v, w) with j = -1 when
    no triangle is closer than the initial sqrt(best2).
    """
    skip = bj
    slo0 = min(p0x, p1x)
    slo1 = min(p0y, p1y)
    slo2 = min(p0z, p1z)
    shi0 = max(p0x, p1x)
    shi1 = max(p0y, p1y)
    shi2 = max(p0z, p1z)
    if _box_gap2(slo0, slo1, slo2, shi0, shi1, shi2, NB, 0) >= best2:
        return best2, bj, bt, bqx, bqy, bqz, bu, bv, bw
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        k = stack[top]
        if _box_gap2(slo0, slo1, slo2, shi0, shi1, shi2, NB, k) >= best2:
            continue  # the bound shrank since this node was pushed
        if NI[k, 0] < 0:
            s = NI[k, 2]
            for j in range(s, s + NI[k, 3]):
                if j == skip:
                    continue
                deg = DEG[j]
                nx = TRI[j, 9]
                ny = TRI[j, 10]
                nz = TRI[j, 11]
                s0 = 0.0
                s1 = 0.0
                if not deg:
                    ax = TRI[j, 0]
                    ay = TRI[j, 1]
                    az = TRI[j, 2]
                    s0 = nx * (p0x - ax) + ny * (p0y - ay) + nz * (p0z - az)
                    s1 = nx * (p1x - ax) + ny * (p1y - ay) + nz * (p1z - az)
                    if s0 > 0.0 and s1 > 0.0:
                        m = min(s0, s1)
                        if m * m >= best2:
                            continue
                    elif s0 < 0.0 and s1 < 0.0:
                        m = max(s0, s1)
                        if m * m >= best2:
                            continue
                    if _side_bound2(p0x, p0y, p0z, p1x, p1y, p1z, TRI, j, s0, s1) >= best2:
                        continue
                d2, t, qx, qy, qz, u, v, w = _seg_tri(
                    p0x,
                    p0y,
                    p0z,
                    p1x,
                    p1y,
                    p1z,
                    TRI[j, 0],
                    TRI[j, 1],
                    TRI[j, 2],
                    TRI[j, 3],
                    TRI[j, 4],
                    TRI[j, 5],
                    TRI[j, 6],
                    TRI[j, 7],
                    TRI[j, 8],
                    nx,
                    ny,
                    nz,
                    deg,
                    s0,
                    s1,
                    best2,
                )
                if d2 < best2:
                    best2 = d2
                    bj = j
                    bt = t
                    bqx = qx
                    bqy = qy
                    bqz = qz
                    bu = u
                    bv = v
                    bw = w
                    if d2 == 0.0:
                        return best2, bj, bt, bqx, bqy, bqz, bu, bv, bw
        else:
            kl = NI[k, 0]
            kr = NI[k, 1]
            gl = _box_gap2(slo0, slo1, slo2, shi0, shi1, shi2, NB, kl)
            gr = _box_gap2(slo0, slo1, slo2, shi0, shi1, shi2, NB, kr)
            # push the farther child first so that the nearer one is searched first
            if gl <= gr:
                if gr < best2:
                    stack[top] = kr
                    top += 1
                if gl < best2:
                    stack[top] = kl
                    top += 1
            else:
                if gl < best2:
                    stack[top] = kl
                    top += 1
                if gr < best2:
                    stack[top] = kr
                    top += 1
    return best2, bj, bt, bqx, bqy, bqz, bu, bv, bw


@njit(cache=True, fastmath=False)
def _cell(x, y, z, GRID, GDIM):
    """Flat index of the seed-grid cell holding (x, y, z), clamped to the grid.

    GRID = (origin x, y, z, 1 / cell size); GDIM = (nx, ny, nz).
    """
    inv = GRID[3]
    i = int(min(max((x - GRID[0]) * inv, 0.0), GDIM[0] - 1.0))
    k = int(min(max((y - GRID[1]) * inv, 0.0), GDIM[1] - 1.0))
    m = int(min(max((z - GRID[2]) * inv, 0.0), GDIM[2] - 1.0))
    return (i * GDIM[1] + k) * GDIM[2] + m


@njit(cache=True, fastmath=False, parallel=True)
def nearest_triangles(Q, TRI, DEG, NB, NI, out):
    """Index (BVH order) of the triangle nearest to each point of Q (local frame)."""
    n = Q.shape[0]
    nblocks = (n + _BLOCK - 1) // _BLOCK
    for blk in prange(nblocks):
        stack = np.empty(_STACK, dtype=np.int64)
        for i in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            x = Q[i, 0]
            y = Q[i, 1]
            z = Q[i, 2]
            d2, j, t, qx, qy, qz, u, v, w = _nearest(
                x, y, z, x, y, z, _INF, TRI, DEG, NB, NI, stack, -1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
            )
            out[i] = j


@njit(cache=True, fastmath=False)
def _in_hull(x, y, z, HP, first):
    """Whether (x, y, z) is strictly inside every hull plane; plane ``first`` is tried first."""
    if HP[first, 0] * x + HP[first, 1] * y + HP[first, 2] * z - HP[first, 3] >= 0.0:
        return False
    for j in range(HP.shape[0]):
        if HP[j, 0] * x + HP[j, 1] * y + HP[j, 2] * z - HP[j, 3] >= 0.0:
            return False
    return True


@njit(cache=True, fastmath=False)
def _reaches_hull(p0x, p0y, p0z, p1x, p1y, p1z, HP):
    """Whether some part of the segment lies inside the hull (Cyrus-Beck clipping)."""
    t_in = 0.0
    t_out = 1.0
    for j in range(HP.shape[0]):
        s0 = HP[j, 0] * p0x + HP[j, 1] * p0y + HP[j, 2] * p0z - HP[j, 3]
        s1 = HP[j, 0] * p1x + HP[j, 1] * p1y + HP[j, 2] * p1z - HP[j, 3]
        if s0 > 0.0 and s1 > 0.0:
            return False
        if s0 > 0.0:
            t = s0 / (s0 - s1)
            if t > t_in:
                t_in = t
        elif s1 > 0.0:
            t = s0 / (s0 - s1)
            if t < t_out:
                t_out = t
        if t_in > t_out:
            return False
    return True


@njit(cache=True, fastmath=False, inline="always")
def _seed_test(p0x, p0y, p0z, p1x, p1y, p1z, TRI, DEG, GRID, GDIM, SEED):
    """Exact distance to the seed triangle of the segment's midpoint cell: (j0, d2, t, q, bary)."""
    ci = _cell(0.5 * (p0x + p1x), 0.5 * (p0y + p1y), 0.5 * (p0z + p1z), GRID, GDIM)
    j0 = SEED[ci]
    s0 = 0.0
    s1 = 0.0
    if not DEG[j0]:
        s0 = TRI[j0, 9] * (p0x - TRI[j0, 0]) + TRI[j0, 10] * (p0y - TRI[j0, 1]) + TRI[j0, 11] * (p0z - TRI[j0, 2])
        s1 = TRI[j0, 9] * (p1x - TRI[j0, 0]) + TRI[j0, 10] * (p1y - TRI[j0, 1]) + TRI[j0, 11] * (p1z - TRI[j0, 2])
    e2, et, eqx, eqy, eqz, eu, ev, ew = _seg_tri(
        p0x,
        p0y,
        p0z,
        p1x,
        p1y,
        p1z,
        TRI[j0, 0],
        TRI[j0, 1],
        TRI[j0, 2],
        TRI[j0, 3],
        TRI[j0, 4],
        TRI[j0, 5],
        TRI[j0, 6],
        TRI[j0, 7],
        TRI[j0, 8],
        TRI[j0, 9],
        TRI[j0, 10],
        TRI[j0, 11],
        DEG[j0],
        s0,
        s1,
        _INF,
    )
    return j0, e2, et, eqx, eqy, eqz, eu, ev, ew


@njit(cache=True, fastmath=False, inline="always")
def _box_far(p0x, p0y, p0z, p1x, p1y, p1z, R, BOX):
    return (
        min(p0x, p1x) - R > BOX[3]
        or max(p0x, p1x) + R < BOX[0]
        or min(p0y, p1y) - R > BOX[4]
        or max(p0y, p1y) + R < BOX[1]
        or min(p0z, p1z) - R > BOX[5]
        or max(p0z, p1z) + R < BOX[2]
    )


@njit(cache=True, fastmath=False, inline="always")
def _search(p0x, p0y, p0z, p1x, p1y, p1z, bound2, seed, TRI, DEG, NB, NI, stack):
    """Nearest triangle closer than ``sqrt(bound2)``: (d2, j, t, qx, qy, qz, u, v, w), j = -1 when none.

    ``seed`` is :func:`_seed_test`'s answer; the search starts from it (a
    tighter bound) when it lies within the bound.
    """
    j0, e2, et, eqx, eqy, eqz, eu, ev, ew = seed
    if e2 < bound2:
        return _nearest(p0x, p0y, p0z, p1x, p1y, p1z, e2, TRI, DEG, NB, NI, stack, j0, et, eqx, eqy, eqz, eu, ev, ew)
    return _nearest(
        p0x, p0y, p0z, p1x, p1y, p1z, bound2, TRI, DEG, NB, NI, stack, -1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    )


@njit(cache=True, fastmath=False, inline="always")
def _query_segment(
    p0x, p0y, p0z, p1x, p1y, p1z, R, mode, BOX, TRI, DEG, TPL, NB, NI, HP, CS, CU, CV, GRID, GDIM, SEED, stack
):
    """One capsule: (d2, inside, j, t, qx, qy, qz, u, v, w); j = -1 when nothing lies within R.

    Box cull; exact distance to the seed triangle; bounded search (by R, or
    the seed's distance when smaller). When the surface lies within R the
    closest point is known and inside is tested there (hull plane of the
    found triangle first). Only when nothing does is the segment clipped to
    the hull; if some of it lies in the hull, the search continues without
    a bound, since the capsule may be inside whatever its distance.
    """
    if _box_far(p0x, p0y, p0z, p1x, p1y, p1z, R, BOX):
        return _INF, False, -1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    seed = _seed_test(p0x, p0y, p0z, p1x, p1y, p1z, TRI, DEG, GRID, GDIM, SEED)
    d2, j, t, qx, qy, qz, u, v, w = _search(p0x, p0y, p0z, p1x, p1y, p1z, R * R, seed, TRI, DEG, NB, NI, stack)
    if j < 0:
        if mode == 0 or HP.shape[0] == 0 or not _reaches_hull(p0x, p0y, p0z, p1x, p1y, p1z, HP):
            return _INF, False, -1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        d2, j, t, qx, qy, qz, u, v, w = _search(p0x, p0y, p0z, p1x, p1y, p1z, _INF, seed, TRI, DEG, NB, NI, stack)
    inside = False
    if mode != 0 and d2 > 0.0 and HP.shape[0] > 0:
        sx = p0x + t * (p1x - p0x)
        sy = p0y + t * (p1y - p0y)
        sz = p0z + t * (p1z - p0z)
        inside = _in_hull(sx, sy, sz, HP, TPL[j])
        if inside and mode == 2:
            inside = _winding(sx, sy, sz, TRI, NB, NI, CS, CU, CV, stack) >= 0.5
    return d2, inside, j, t, qx, qy, qz, u, v, w


@njit(cache=True, fastmath=False, parallel=True)
def finish_rows(P0, P1, radius, TRI, DEG, TN, TID, shift, o_d, o_in, o_c, o_tri, o_t, o_q, o_b, o_s, o_n, o_pr, o_dp):
    """Derive every output field from the search record, in place (world frame).

    On entry ``o_d`` holds d2, ``o_in`` inside, ``o_tri`` the BVH triangle
    (-1: nothing within R), ``o_t`` t, ``o_q`` the local closest point and
    ``o_b`` the barycentric coordinates. On exit: distance, inside,
    in_contact, triangle (face row), segment_t, point (n, 3), barycentric
    (n, 3), segment_point (n, 3), normal (n, 3), patch_radius, depth, with
    NaN / -1 / inf where nothing lies within R. (Arrays are separate
    arguments: numba 0.68 mis-lowers unpacking this many from a tuple in a
    prange loop.)
    """
    for i in prange(P0.shape[0]):
        j = o_tri[i]
        if j < 0:
            o_d[i] = _INF
            o_in[i] = False
            o_c[i] = False
            o_t[i] = np.nan
            o_pr[i] = np.nan
            o_dp[i] = np.nan
            for k in range(3):
                o_q[i, k] = np.nan
                o_b[i, k] = np.nan
                o_s[i, k] = np.nan
                o_n[i, k] = np.nan
            continue
        r = radius[i]
        dist = np.sqrt(o_d[i])
        inside = o_in[i]
        t = o_t[i]
        o_d[i] = dist
        o_c[i] = inside or dist < r
        o_tri[i] = TID[j]
        # local segment point and closest point
        sx = P0[i, 0] - shift[0] + t * (P1[i, 0] - P0[i, 0])
        sy = P0[i, 1] - shift[1] + t * (P1[i, 1] - P0[i, 1])
        sz = P0[i, 2] - shift[2] + t * (P1[i, 2] - P0[i, 2])
        qx = o_q[i, 0]
        qy = o_q[i, 1]
        qz = o_q[i, 2]
        if DEG[j]:
            # degenerate triangle: the direction from the surface point to the segment (reversed inside)
            nx = sx - qx
            ny = sy - qy
            nz = sz - qz
            ln = np.sqrt(nx * nx + ny * ny + nz * nz)
            if ln > 0.0:
                sg = -1.0 if inside else 1.0
                nx = sg * nx / ln
                ny = sg * ny / ln
                nz = sg * nz / ln
            dplane = dist
        else:
            nx = TN[j, 0]
            ny = TN[j, 1]
            nz = TN[j, 2]
            dplane = abs(TRI[j, 9] * (sx - TRI[j, 0]) + TRI[j, 10] * (sy - TRI[j, 1]) + TRI[j, 11] * (sz - TRI[j, 2]))
        o_n[i, 0] = nx
        o_n[i, 1] = ny
        o_n[i, 2] = nz
        o_q[i, 0] = qx + shift[0]
        o_q[i, 1] = qy + shift[1]
        o_q[i, 2] = qz + shift[2]
        o_s[i, 0] = sx + shift[0]
        o_s[i, 1] = sy + shift[1]
        o_s[i, 2] = sz + shift[2]
        pr = 0.0
        if inside and dist >= r:
            pr = r
        elif dplane < r:
            pr = np.sqrt(r * r - dplane * dplane)
        o_pr[i] = pr
        dp = r - dist
        if inside:
            dp = r + dist
        o_dp[i] = dp


@njit(cache=True, fastmath=False, inline="always")
def _query_spheres(p0x, p0y, p0z, p1x, p1y, p1z, R, k, BOX, TRI, DEG, NB, NI, GRID, GDIM, SEED, stack):
    """One capsule as ``k`` spheres of reach R along its segment: the :func:`_query_segment` record, never inside.

    Sphere centres are at t = 0.5 for k = 1 and t = i / (k - 1) otherwise;
    the distance is the least centre-to-surface distance, each centre's
    search bounded by the best so far.
    """
    bd2 = R * R
    bj = -1
    bt = 0.0
    bqx = 0.0
    bqy = 0.0
    bqz = 0.0
    bu = 0.0
    bv = 0.0
    bw = 0.0
    if not _box_far(p0x, p0y, p0z, p1x, p1y, p1z, R, BOX):
        for s in range(k):
            ts = 0.5 if k == 1 else s / (k - 1.0)
            cx = p0x + ts * (p1x - p0x)
            cy = p0y + ts * (p1y - p0y)
            cz = p0z + ts * (p1z - p0z)
            if _box_far(cx, cy, cz, cx, cy, cz, np.sqrt(bd2), BOX):
                continue
            seed = _seed_test(cx, cy, cz, cx, cy, cz, TRI, DEG, GRID, GDIM, SEED)
            d2, j, t, qx, qy, qz, u, v, w = _search(cx, cy, cz, cx, cy, cz, bd2, seed, TRI, DEG, NB, NI, stack)
            if j >= 0 and d2 < bd2:
                bd2 = d2
                bj = j
                bt = ts
                bqx = qx
                bqy = qy
                bqz = qz
                bu = u
                bv = v
                bw = w
    return bd2, False, bj, bt, bqx, bqy, bqz, bu, bv, bw


@njit(cache=True, fastmath=False, parallel=True)
def query_rows(
    P0,
    P1,
    radius,
    margin,
    mode,
    k,
    BOX,
    TRI,
    DEG,
    TPL,
    NB,
    NI,
    HP,
    CS,
    CU,
    CV,
    GRID,
    GDIM,
    SEED,
    shift,
    d2_out,
    in_out,
    tri_out,
    t_out,
    q_out,
    b_out,
):
    """Search for every capsule i (segments P0[i]-P1[i], world frame): exact (``k = 0``, inside by ``mode``) or
    the paper's approximation, each capsule as ``k > 0`` spheres of its radius (nothing ever inside).

    Writes the search record (squared distance, inside, BVH triangle or -1,
    segment parameter, local closest point, barycentric coordinates); the
    last four only where a triangle was found. :func:`finish_rows` derives
    the rest. The mesh arrays are ``MeshAccel.kernel_arrays``; ``shift`` its
    origin. (Arrays are separate arguments: numba 0.68 mis-lowers unpacking
    long tuples of arrays in prange loops.)
    """
    n = P0.shape[0]
    nblocks = (n + _BLOCK - 1) // _BLOCK
    for blk in prange(nblocks):
        stack = np.empty(_STACK, dtype=np.int64)
        for i in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            p0x = P0[i, 0] - shift[0]
            p0y = P0[i, 1] - shift[1]
            p0z = P0[i, 2] - shift[2]
            p1x = P1[i, 0] - shift[0]
            p1y = P1[i, 1] - shift[1]
            p1z = P1[i, 2] - shift[2]
            R = radius[i] + margin
            if k == 0:
                d2, ins, j, t, qx, qy, qz, u, v, w = _query_segment(
                    p0x,
                    p0y,
                    p0z,
                    p1x,
                    p1y,
                    p1z,
                    R,
                    mode,
                    BOX,
                    TRI,
                    DEG,
                    TPL,
                    NB,
                    NI,
                    HP,
                    CS,
                    CU,
                    CV,
                    GRID,
                    GDIM,
                    SEED,
                    stack,
                )
            else:
                d2, ins, j, t, qx, qy, qz, u, v, w = _query_spheres(
                    p0x, p0y, p0z, p1x, p1y, p1z, R, k, BOX, TRI, DEG, NB, NI, GRID, GDIM, SEED, stack
                )
            d2_out[i] = d2
            in_out[i] = ins
            tri_out[i] = j
            if j >= 0:
                t_out[i] = t
                q_out[i, 0] = qx
                q_out[i, 1] = qy
                q_out[i, 2] = qz
                b_out[i, 0] = u
                b_out[i, 1] = v
                b_out[i, 2] = w


def query_capsules(P0, P1, radius, margin, mode, *arrays):
    """The exact search (:func:`query_rows` with k = 0); ``mode`` 0/1/2: no inside test, hull, hull then winding."""
    query_rows(P0, P1, radius, margin, mode, 0, *arrays)


def query_spheres(P0, P1, radius, margin, k, *arrays):
    """The paper's approximation (:func:`query_rows` with ``k`` > 0 spheres a capsule)."""
    query_rows(P0, P1, radius, margin, 0, k, *arrays)


@njit(cache=True, fastmath=False, parallel=True)
def winding_numbers(Q, TRI, NB, NI, CS, CU, CV, out):
    """Generalized winding number at each point of Q (local frame)."""
    n = Q.shape[0]
    nblocks = (n + _BLOCK - 1) // _BLOCK
    for blk in prange(nblocks):
        stack = np.empty(_STACK, dtype=np.int64)
        for i in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            out[i] = _winding(Q[i, 0], Q[i, 1], Q[i, 2], TRI, NB, NI, CS, CU, CV, stack)


@njit(cache=True, fastmath=False, parallel=True)
def frames_near(P0, P1, reach, cx, cy, cz, link_radius, out):
    """Per frame: can the sphere around its capsules (grown by ``reach``) meet the link's sphere?

    P0, P1 are (F, C, 3) segment ends; the hand's sphere is centred on the
    box of the frame's 2C ends. Writes ``out[f]``.
    """
    nf = P0.shape[0]
    nc = P0.shape[1]
    for f in prange(nf):
        lo0 = _INF
        lo1 = _INF
        lo2 = _INF
        hi0 = -_INF
        hi1 = -_INF
        hi2 = -_INF
        for c in range(nc):
            for P in (P0, P1):
                x = P[f, c, 0]
                y = P[f, c, 1]
                z = P[f, c, 2]
                lo0 = min(lo0, x)
                lo1 = min(lo1, y)
                lo2 = min(lo2, z)
                hi0 = max(hi0, x)
                hi1 = max(hi1, y)
                hi2 = max(hi2, z)
        mx = 0.5 * (lo0 + hi0)
        my = 0.5 * (lo1 + hi1)
        mz = 0.5 * (lo2 + hi2)
        r2 = 0.0
        for c in range(nc):
            for P in (P0, P1):
                dx = P[f, c, 0] - mx
                dy = P[f, c, 1] - my
                dz = P[f, c, 2] - mz
                r2 = max(r2, dx * dx + dy * dy + dz * dz)
        gap = np.sqrt((mx - cx) ** 2 + (my - cy) ** 2 + (mz - cz) ** 2)
        out[f] = gap <= np.sqrt(r2) + reach + link_radius
