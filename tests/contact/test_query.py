"""capsule_mesh_query against the brute-force float64 reference on random and hard sets."""

from __future__ import annotations

import numpy as np
import pytest
from contact_checks import TOL_M, check_against_reference, check_fields

from sphri.contact import capsule_mesh_query, prepare_mesh, sphere_mesh_query, winding_number
from sphri.testing.contact_reference import random_capsules, reference_query, winding_direct


def test_hard_set_on_stand_in(standin):
    v, f = standin
    p0, p1, r, kind = random_capsules(v, f, 3000, seed=1)
    q, ref = check_against_reference(v, f, p0, p1, r)
    # the set really is hard: contacts, crossings and capsules wholly inside
    assert ref.in_contact.sum() > 500
    assert (ref.distance == 0).sum() > 50
    inside_far = ref.inside & (ref.distance > r)
    assert inside_far.sum() >= (kind == 2).sum() > 0
    assert q.inside[kind == 2].all()


def test_hard_set_on_real_arm_and_torso(real_arm, real_torso):
    for v, f in (real_arm, real_torso):
        assert prepare_mesh(v, f).inside_mode == "hull"  # open Unity hulls with shallow dents
        p0, p1, r, kind = random_capsules(v, f, 2000, seed=2)
        q, _ = check_against_reference(v, f, p0, p1, r)
        assert q.inside[kind == 2].all()


def test_margin_reports_exact_distances_farther_out(standin):
    v, f = standin
    p0, p1, r, _ = random_capsules(v, f, 1500, seed=3)
    q, ref = check_against_reference(v, f, p0, p1, r, margin=0.03)
    band = (ref.distance >= r) & (ref.distance < r + 0.03)
    assert band.sum() > 50 and np.isfinite(q.distance[band]).all()
    assert not q.in_contact[band & ~ref.inside].any()  # the margin widens reporting, not contact


def test_far_capsules_report_at_least_their_reach(standin):
    v, f = standin
    p0 = np.array([[1.0, 1.0, 1.0], [0.0, 0.2, -0.36], [0.0, 0.0, 0.5]])
    p1 = p0 + [0.0, 0.0, 0.05]
    q = capsule_mesh_query(v, f, p0, p1, 0.01)
    assert np.isinf(q.distance).all() and not q.in_contact.any()
    assert (q.triangle == -1).all() and np.isnan(q.point).all()


def test_nonconvex_closed_mesh_uses_winding(torus):
    v, f = torus
    mesh = prepare_mesh(v, f)
    assert mesh.inside_mode == "winding" and not mesh.convex
    rng = np.random.default_rng(4)
    c = rng.uniform(-0.12, 0.12, size=(1500, 3)) * [1, 1, 0.4]
    axis = rng.normal(size=(1500, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    half = rng.uniform(0, 0.02, size=(1500, 1))
    r = rng.uniform(0.002, 0.01, size=1500)
    q, ref = check_against_reference(v, f, c - half * axis, c + half * axis, r)
    assert ref.inside.sum() > 50
    # the hole of the torus lies inside the hull but outside the solid
    hole = capsule_mesh_query(v, f, [[0, 0, 0]], [[0, 0, 0.001]], 0.001)
    assert not hole.inside[0] and not hole.in_contact[0]


def test_inside_modes_agree_on_a_closed_convex_mesh():
    import trimesh

    box = trimesh.creation.box(extents=[0.1, 0.2, 0.3])
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    rng = np.random.default_rng(5)
    p0 = rng.uniform(-0.2, 0.2, size=(800, 3))
    p1 = p0 + rng.normal(scale=0.02, size=(800, 3))
    qh, _ = check_against_reference(v, f, p0, p1, 0.01, inside="hull")
    qw, _ = check_against_reference(v, f, p0, p1, 0.01, inside="winding")
    clear = qh.distance > 1e-9
    assert np.array_equal(qh.inside[clear], qw.inside[clear])
    assert np.array_equal(qh.in_contact, qw.in_contact)


def test_hierarchical_winding_number_matches_direct_sum(torus, standin):
    rng = np.random.default_rng(6)
    for v, f in (torus, standin):
        pts = rng.uniform(v.min(axis=0) - 0.02, v.max(axis=0) + 0.02, size=(600, 3))
        assert np.allclose(winding_number(v, f, pts), winding_direct(v, f, pts), atol=1e-10)


def test_spheres_match_reference_point_distances(standin):
    v, f = standin
    p0, p1, r, _ = random_capsules(v, f, 1500, seed=7)
    for k in (1, 3, 5):
        ts = np.array([0.5]) if k == 1 else np.linspace(0.0, 1.0, k)
        centres = (p0[:, None, :] + ts[None, :, None] * (p1 - p0)[:, None, :]).reshape(-1, 3)
        ref = reference_query(v, f, centres, centres, np.repeat(r, k), inside="none")
        dmin = ref.distance.reshape(-1, k).min(axis=1)
        s = sphere_mesh_query(v, f, p0, p1, r, k=k)
        assert np.array_equal(s.in_contact, dmin < r)
        assert not s.inside.any()
        band = dmin < r
        assert np.allclose(s.distance[band], dmin[band], atol=TOL_M, rtol=0)
        check_fields(v, f, p0, p1, r, s)


def test_spheres_miss_what_exact_finds(standin):
    v, f = standin
    p0, p1, r, kind = random_capsules(v, f, 2000, seed=8)
    exact = capsule_mesh_query(v, f, p0, p1, r)
    s = sphere_mesh_query(v, f, p0, p1, r, k=5)
    assert not (s.in_contact & ~exact.in_contact).any()  # spheres lie inside their capsule
    assert (exact.in_contact & ~s.in_contact)[kind == 2].all()  # wholly inside: missed


def test_empty_input(standin):
    v, f = standin
    q = capsule_mesh_query(v, f, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    assert q.distance.shape == (0,) and q.point.shape == (0, 3)


@pytest.mark.parametrize(
    "args, match",
    [
        (dict(p0=np.zeros((2, 2))), "p0 must have shape"),
        (dict(p1=np.zeros((3, 3))), "p1 has 3 rows"),
        (dict(p0=np.array([[np.nan, 0, 0], [0, 0, 0]])), "p0 holds NaN"),
        (dict(radius=np.array([0.01, -1.0])), "radius must be finite and >= 0"),
        (dict(radius=np.zeros(3)), "radius must be a scalar or have shape"),
        (dict(margin=-0.1), "margin"),
        (dict(inside="solid"), "inside='solid' is invalid"),
        (dict(faces=np.array([[0, 1, 99]])), "faces index vertices out of range"),
        (dict(faces=np.zeros((0, 3), dtype=int)), "faces must have shape"),
        (dict(vertices=np.full((3, 3), np.inf), faces=np.array([[0, 1, 2]])), "vertices hold NaN/inf"),
    ],
)
def test_bad_inputs_raise_clear_errors(standin, args, match):
    v, f = standin
    kw = dict(vertices=v, faces=f, p0=np.zeros((2, 3)), p1=np.ones((2, 3)), radius=0.01)
    kw.update(args)
    with pytest.raises(ValueError, match=match):
        capsule_mesh_query(**kw)
