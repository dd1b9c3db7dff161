"""prepare_mesh: inside-mode resolution, caching, repairs noted, flat meshes."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.contact import capsule_mesh_query, prepare_mesh
from sphri.contact.mesh import CONVEX_TOL_M


def test_auto_picks_hull_for_convex_and_winding_otherwise(standin, torus):
    assert prepare_mesh(*standin).inside_mode == "hull"
    assert prepare_mesh(*torus).inside_mode == "winding"
    assert prepare_mesh(*standin, inside="winding").inside_mode == "winding"
    assert prepare_mesh(*torus, inside="none").inside_mode == "none"


def test_dents_deeper_than_the_tolerance_are_not_convex(standin):
    v, f = standin
    v = v.copy()
    # push the centre of the wrist cap inward: its fan now forms a dent
    cap = np.argmin(np.abs(v[:, 2] + 0.483) + np.abs(v[:, 0]) + np.abs(v[:, 1]))
    v[cap, 2] += 2 * CONVEX_TOL_M
    assert prepare_mesh(v, f).inside_mode == "winding"
    v[cap, 2] = -0.483 + 0.2 * CONVEX_TOL_M
    assert prepare_mesh(v, f).inside_mode == "hull"


def test_cache_returns_the_same_object(standin):
    v, f = standin
    a = prepare_mesh(v, f)
    assert prepare_mesh(v.copy(), f.copy()) is a
    assert prepare_mesh(v, f, inside="winding") is not a


def test_inward_faces_get_outward_normals_on_convex_hulls(standin):
    v, f = standin
    flipped = f.copy()
    flipped[:5] = flipped[:5, ::-1]
    mesh = prepare_mesh(v, flipped)
    assert any("wound inward" in n for n in mesh.notes)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    for j in range(5):
        x = v[flipped[j]].mean(axis=0)
        out = x + 0.01 * (x - centre) / np.linalg.norm(x - centre)
        q = capsule_mesh_query(v, flipped, [out], [out], 0.02)
        assert q.normal[0] @ (x - centre) > 0


def test_flat_mesh_has_no_inside():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    f = np.array([[0, 1, 2], [1, 3, 2]])
    mesh = prepare_mesh(v, f)
    assert mesh.inside_mode == "none" and any("no volume" in n for n in mesh.notes)
    q = capsule_mesh_query(v, f, [[0.5, 0.5, 0.2], [0.5, 0.5, -0.005]], [[0.5, 0.5, 0.3], [0.5, 0.5, -0.004]], 0.01)
    assert not q.inside.any() and list(q.in_contact) == [False, True]
    assert abs(q.distance[1] - 0.004) < 1e-15


def test_bad_inside_mode():
    with pytest.raises(ValueError, match="allowed values"):
        prepare_mesh(np.eye(3), np.array([[0, 1, 2]]), inside="volume")


def test_big_nonconvex_mesh_is_fast_to_prepare_and_query():
    s = trimesh.creation.icosphere(subdivisions=4, radius=0.05)
    v = np.concatenate([s.vertices, s.vertices + [0.08, 0, 0]])
    f = np.concatenate([s.faces, s.faces + len(s.vertices)])  # two overlapping balls: 10k faces
    mesh = prepare_mesh(v, f)
    assert mesh.inside_mode == "winding"
    rng = np.random.default_rng(0)
    p = rng.uniform([-0.07, -0.07, -0.07], [0.15, 0.07, 0.07], size=(2000, 3))
    q = capsule_mesh_query(v, f, p, p, 0.005)
    ball = (np.linalg.norm(p, axis=1) < 0.049) | (np.linalg.norm(p - [0.08, 0, 0], axis=1) < 0.049)
    far_out = (np.linalg.norm(p, axis=1) > 0.051) & (np.linalg.norm(p - [0.08, 0, 0], axis=1) > 0.051)
    assert q.inside[ball].all() and not q.inside[far_out].any()
