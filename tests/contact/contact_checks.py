"""Checks shared by the contact tests: field-by-field validation and reference agreement."""

from __future__ import annotations

import numpy as np

from sphri.contact import capsule_mesh_query, prepare_mesh
from sphri.testing.contact_reference import compare, reference_query

#: Distances must match the reference to this (metres); the issue asks 1e-9.
TOL_M = 1e-9


def check_fields(v, f, p0, p1, r, q, margin=0.0):
    """Every field of a :class:`ContactQuery` is consistent with its geometry."""
    p0 = np.asarray(p0, dtype=np.float64)
    p1 = np.asarray(p1, dtype=np.float64)
    r = np.broadcast_to(np.asarray(r, dtype=np.float64), (p0.shape[0],))
    scale = 1.0 + np.abs(v).max()
    tol = 1e-12 * scale
    has = q.triangle >= 0
    within = (q.distance < r + margin) | q.inside
    assert (has[within]).all(), "a capsule within reach has no closest point"
    assert np.array_equal(q.in_contact, (q.distance < r) | q.inside)
    assert not (q.inside & (q.distance <= 0)).any(), "a capsule on the surface cannot be inside"
    assert np.isinf(q.distance[~has]).all() and np.isnan(q.point[~has]).all()
    assert (q.distance[~has] >= (r + margin)[~has]).all()
    if not has.any():
        return
    tri = q.triangle[has]
    assert tri.min() >= 0 and tri.max() < f.shape[0]
    corners = v[f[tri]]
    bary = q.barycentric[has]
    assert (bary >= -1e-9).all() and np.allclose(bary.sum(axis=1), 1.0, atol=1e-9)
    assert np.allclose(np.einsum("nk,nkd->nd", bary, corners), q.point[has], atol=1e-9 * scale)
    t = q.segment_t[has]
    assert ((t >= 0) & (t <= 1)).all()
    seg = p0[has] + t[:, None] * (p1[has] - p0[has])
    assert np.allclose(seg, q.segment_point[has], atol=tol)
    gap = np.linalg.norm(q.point[has] - q.segment_point[has], axis=1)
    assert np.allclose(gap, q.distance[has], atol=tol)
    # normals: unit, and along the face's normal for non-degenerate faces
    cr = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area2 = np.linalg.norm(cr, axis=1)
    good = area2 > 1e-9 * (np.linalg.norm(corners[:, 1] - corners[:, 0], axis=1) ** 2 + 1e-300)
    n = q.normal[has]
    assert np.allclose(np.abs(np.einsum("ij,ij->i", n[good], cr[good] / area2[good, None])), 1.0, atol=1e-9)
    # depth and patch radius, from their definitions
    rr = r[has]
    d = q.distance[has]
    ins = q.inside[has]
    assert np.allclose(q.depth[has], np.where(ins, rr + d, rr - d), atol=tol)
    unit = cr / np.where(area2 > 0, area2, 1)[:, None]
    dplane = np.abs(np.einsum("ij,ij->i", q.segment_point[has] - corners[:, 0], unit))
    dplane = np.where(good, dplane, d)
    want = np.where(ins & (d >= rr), rr, np.sqrt(np.maximum(rr**2 - dplane**2, 0.0)))
    assert np.allclose(q.patch_radius[has][good | ins], want[good | ins], atol=1e-9)
    assert (q.depth[q.in_contact] > 0).all()


def check_against_reference(v, f, p0, p1, r, margin=0.0, inside="auto"):
    """Run the fast query and the reference; assert exact agreement. Returns (query, reference)."""
    q = capsule_mesh_query(v, f, p0, p1, r, margin, inside=inside)
    mode = prepare_mesh(v, f, inside=inside).inside_mode
    ref = reference_query(v, f, p0, p1, r, inside=mode)
    r = np.broadcast_to(np.asarray(r, dtype=np.float64), ref.distance.shape)
    c = compare(q, ref, r, tol_m=TOL_M)
    assert c["contact_disagreements"] == 0, c
    assert c["inside_disagreements"] == 0, c
    assert c["distance_over_tol"] == 0, c
    band = ref.distance < r + margin
    assert np.allclose(q.distance[band], ref.distance[band], atol=TOL_M, rtol=0)
    check_fields(v, f, p0, p1, r, q, margin)
    return q, ref
