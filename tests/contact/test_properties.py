"""Properties of the exact query (hypothesis): tangency, edges, vertices, degenerate input,
invariance under rigid motions, scaling, monotonicity in the radius."""

from __future__ import annotations

import os

import numpy as np
from contact_checks import TOL_M, check_against_reference, check_fields
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from sphri.contact import capsule_mesh_query
from sphri.testing.contact_reference import arm_stand_in, random_capsules

V, F = arm_stand_in()
#: ``make test-all`` (SPHRI_DEEP_TESTS=1) runs ten times as many examples.
SCALE_SET = settings(max_examples=200 if os.environ.get("SPHRI_DEEP_TESTS") else 20, deadline=None)
seeds = st.integers(min_value=0, max_value=2**31 - 1)


def _face_frame(j):
    a, b, c = V[F[j]]
    n = np.cross(b - a, c - a)
    return a, b, c, n / np.linalg.norm(n)


@SCALE_SET
@given(seed=seeds, h=st.floats(0.0005, 0.03))
def test_capsule_tangent_to_a_face(seed, h):
    rng = np.random.default_rng(seed)
    j = int(rng.integers(len(F)))
    a, b, c, n = _face_frame(j)
    w = rng.dirichlet(np.ones(3)) * 0.6 + 0.4 / 3  # well inside the face
    foot = w @ np.stack([a, b, c])
    along = (b - a) / np.linalg.norm(b - a)
    length = 0.2 * min(np.linalg.norm(b - a), np.linalg.norm(c - a))
    p0 = foot + h * n - 0.5 * length * along
    p1 = foot + h * n + 0.5 * length * along
    q = capsule_mesh_query(V, F, [p0], [p1], [h], margin=0.01)
    assert abs(q.distance[0] - h) < 1e-12 and q.triangle[0] == j
    assert np.allclose(q.normal[0], n, atol=1e-12)
    assert abs(q.patch_radius[0]) < 1e-5  # the sphere just touches the plane
    eps = 1e-9
    assert capsule_mesh_query(V, F, [p0], [p1], [h + eps]).in_contact[0]
    assert not capsule_mesh_query(V, F, [p0], [p1], [h - eps]).in_contact[0]


@SCALE_SET
@given(seed=seeds, where=st.sampled_from(["vertex", "edge"]), length=st.floats(0.0, 0.07))
def test_capsules_touching_vertices_and_edges(seed, where, length):
    rng = np.random.default_rng(seed)
    j = int(rng.integers(len(F)))
    a, b, c, _ = _face_frame(j)
    touch = a if where == "vertex" else a + rng.uniform(0.1, 0.9) * (b - a)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    # one end on the surface: distance 0, in contact, depth = radius. Whether a
    # point within rounding (~1e-18 m) of the boundary counts as inside is not
    # defined in floating point; the depth is the radius either way.
    q, _ = check_against_reference(V, F, [touch], [touch + length * u], [0.01])
    assert q.distance[0] < 1e-12 and q.in_contact[0]
    assert abs(q.depth[0] - 0.01) < 1e-12
    assert not q.inside[0] or q.distance[0] < 1e-15
    # the same capsule moved off along a random direction: agrees with the reference
    off = touch + rng.normal(scale=0.01, size=3)
    check_against_reference(V, F, [off], [off + length * u], [0.01], margin=0.02)


@SCALE_SET
@given(seed=seeds)
def test_zero_length_segments(seed):
    p0, p1, r, _ = random_capsules(V, F, 100, seed=seed)
    mid = 0.5 * (p0 + p1)
    q, ref = check_against_reference(V, F, mid, mid, r)
    # a point capsule is a sphere: the one-sphere approximation is then exact
    from sphri.contact import sphere_mesh_query

    s = sphere_mesh_query(V, F, mid, mid, r, k=1)
    assert np.array_equal(q.in_contact & ~q.inside, s.in_contact & ~q.inside)
    fin = np.isfinite(s.distance)
    assert np.allclose(q.distance[fin], s.distance[fin], atol=1e-15)


@SCALE_SET
@given(seed=seeds, above=st.floats(0.001, 0.04), below=st.floats(0.001, 0.02))
def test_segments_through_the_surface(seed, above, below):
    rng = np.random.default_rng(seed)
    j = int(rng.integers(len(F)))
    a, b, c, n = _face_frame(j)
    foot = rng.dirichlet(np.ones(3)) @ np.stack([a, b, c])
    tilt = n + 0.3 * rng.normal(size=3)
    tilt /= np.linalg.norm(tilt)
    if tilt @ n < 0.2:
        tilt = n
    q, _ = check_against_reference(V, F, [foot + above * tilt], [foot - below * tilt], [0.01])
    assert q.distance[0] < 1e-12 and q.in_contact[0] and not q.inside[0]
    assert abs(q.depth[0] - 0.01) < 1e-12


@SCALE_SET
@given(seed=seeds)
def test_capsules_deep_inside(seed):
    p0, p1, r, kind = random_capsules(V, F, 60, seed=seed, near_fraction=0.0, inside_fraction=1.0)
    q, _ = check_against_reference(V, F, p0, p1, r)
    assert q.inside.all() and q.in_contact.all()
    assert (q.distance > r).all() and np.allclose(q.depth, r + q.distance)
    assert np.allclose(q.patch_radius, r)


@SCALE_SET
@given(seed=seeds)
def test_degenerate_triangles(seed):
    rng = np.random.default_rng(seed)
    extra_v = np.array([[0.0, 0.0, -0.30], [0.0, 0.0, -0.35], [0.0, 0.0, -0.40], [0.06, 0.0, -0.36]])
    v = np.concatenate([V, extra_v])
    k = V.shape[0]
    bad = np.array(
        [
            [k, k + 1, k + 2],  # collinear: a segment inside the arm
            [k + 3, k + 3, k + 3],  # a point outside the arm
            [k + 1, k + 1, k + 2],  # repeated vertex
            [0, 0, 1],
        ]
    )
    f = np.concatenate([F, bad])
    p0, p1, r, _ = random_capsules(V, F, 150, seed=seed)
    # also aim at the stray point and the inner segment
    probe = extra_v[rng.integers(4, size=40)] + rng.normal(scale=0.01, size=(40, 3))
    p0 = np.concatenate([p0, probe])
    p1 = np.concatenate([p1, probe + rng.normal(scale=0.02, size=(40, 3))])
    r = np.concatenate([r, np.full(40, 0.012)])
    check_against_reference(v, f, p0, p1, r)
    # a point capsule 5 mm outside the stray point: that zero-area face is the nearest
    x = extra_v[3] + [0.005, 0.0, 0.0]
    q, _ = check_against_reference(v, f, [x], [x], [0.01])
    assert q.triangle[0] == len(F) + 1 and abs(q.distance[0] - 0.005) < 1e-15
    assert np.allclose(q.normal[0], [1.0, 0.0, 0.0]) and abs(q.patch_radius[0] - np.sqrt(0.01**2 - 0.005**2)) < 1e-15


@SCALE_SET
@given(seed=seeds, offset=st.sampled_from([1000.0, -1000.0, 1e4]))
def test_coordinates_offset_far_from_the_origin(seed, offset):
    p0, p1, r, _ = random_capsules(V, F, 150, seed=seed)
    base = capsule_mesh_query(V, F, p0, p1, r)
    o = np.array([offset, -0.7 * offset, 0.3 * offset])
    # vertices and capsules rounded to float64 at the offset, as a user would hold them
    moved = capsule_mesh_query(V + o, F, p0 + o, p1 + o, r)
    tol = 1e-15 * abs(offset) * 64 + TOL_M
    fin = np.isfinite(base.distance)
    assert np.array_equal(fin, np.isfinite(moved.distance))
    assert np.allclose(moved.distance[fin], base.distance[fin], atol=tol, rtol=0)
    clear = np.abs(base.distance - r) > tol
    assert np.array_equal(moved.in_contact[clear], base.in_contact[clear])
    check_against_reference(V + o, F, p0 + o, p1 + o, r)


@SCALE_SET
@given(seed=seeds)
def test_float32_inputs_are_computed_in_float64(seed):
    p0, p1, r, _ = random_capsules(V, F, 300, seed=seed)
    v32, a32, b32, r32 = V.astype(np.float32), p0.astype(np.float32), p1.astype(np.float32), r.astype(np.float32)
    q32 = capsule_mesh_query(v32, F.astype(np.int32), a32, b32, r32)
    q64 = capsule_mesh_query(
        v32.astype(np.float64), F, a32.astype(np.float64), b32.astype(np.float64), r32.astype(np.float64)
    )
    assert q32.distance.dtype == np.float64
    assert np.array_equal(q32.distance, q64.distance) and np.array_equal(q32.in_contact, q64.in_contact)


@SCALE_SET
@given(seed=seeds)
def test_invariant_under_rigid_motion(seed):
    rng = np.random.default_rng(seed)
    rot = Rotation.random(random_state=seed).as_matrix()
    shift = rng.uniform(-2, 2, size=3)
    p0, p1, r, _ = random_capsules(V, F, 400, seed=seed)
    a = capsule_mesh_query(V, F, p0, p1, r)
    b = capsule_mesh_query(V @ rot.T + shift, F, p0 @ rot.T + shift, p1 @ rot.T + shift, r)
    fin = np.isfinite(a.distance)
    assert np.array_equal(fin, np.isfinite(b.distance))
    assert np.allclose(a.distance[fin], b.distance[fin], atol=TOL_M, rtol=0)
    clear = np.abs(a.distance - r) > TOL_M
    assert np.array_equal(a.in_contact[clear], b.in_contact[clear])
    deep = a.distance > TOL_M
    assert np.array_equal(a.inside[deep], b.inside[deep])
    # closest points move with the mesh
    both = fin & (a.distance > TOL_M)
    assert np.allclose(a.point[both] @ rot.T + shift, b.point[both], atol=1e-6)


@SCALE_SET
@given(seed=seeds, s=st.floats(0.05, 20.0))
def test_scaling_scales_distances(seed, s):
    p0, p1, r, _ = random_capsules(V, F, 300, seed=seed)
    a = capsule_mesh_query(V, F, p0, p1, r)
    b = capsule_mesh_query(V * s, F, p0 * s, p1 * s, r * s)
    fin = np.isfinite(a.distance)
    assert np.array_equal(fin, np.isfinite(b.distance))
    assert np.allclose(b.distance[fin], s * a.distance[fin], rtol=1e-9, atol=1e-12 * s)
    clear = np.abs(a.distance - r) > 1e-9 * (1 + r)
    assert np.array_equal(a.in_contact[clear], b.in_contact[clear])


@SCALE_SET
@given(seed=seeds, grow=st.floats(0.0, 0.02))
def test_a_larger_radius_never_removes_a_contact(seed, grow):
    p0, p1, r, _ = random_capsules(V, F, 400, seed=seed)
    small = capsule_mesh_query(V, F, p0, p1, r)
    large = capsule_mesh_query(V, F, p0, p1, r + grow)
    assert not (small.in_contact & ~large.in_contact).any()
    check_fields(V, F, p0, p1, r + grow, large)
