"""Ray casting: Embree's float32 hits against trimesh's float64 ray_triangle, and parity
inside tests against the winding-number and hull definitions."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.contact import capsule_mesh_query, winding_number
from sphri.contact.rays import first_hits, has_embree, inside_by_rays

needs_embree = pytest.mark.skipif(not has_embree(), reason="embreex is not installed")


def _rays(v, n, seed):
    rng = np.random.default_rng(seed)
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    ext = v.max(axis=0) - v.min(axis=0)
    o = c + rng.normal(size=(n, 3)) * ext.max()
    d = c + rng.normal(size=(n, 3)) * 0.3 * ext - o
    return o, d


@needs_embree
@pytest.mark.parametrize("mesh", ["standin", "torus"])
def test_embree_hits_match_ray_triangle(mesh, request):
    v, f = request.getfixturevalue(mesh)
    o, d = _rays(v, 3000, seed=0)
    e = first_hits(v, f, o, d, engine="embree")
    t = first_hits(v, f, o, d, engine="triangle")
    hit_e, hit_t = e.triangle >= 0, t.triangle >= 0
    assert hit_t.sum() > 1000
    # hit or miss may differ only for rays grazing the silhouette (float32)
    assert (hit_e != hit_t).sum() <= 3
    both = hit_e & hit_t
    same = both & (e.triangle == t.triangle)
    assert same.sum() >= 0.99 * both.sum()
    # on the same triangle the float64 refinement reproduces ray_triangle exactly
    assert np.allclose(e.distance[same], t.distance[same], rtol=0, atol=1e-12)
    # on a neighbouring triangle (a shared edge) the hit point agrees to float32 precision
    assert np.allclose(e.point[both], t.point[both], atol=1e-5)
    # hits lie on their triangles
    b = e.barycentric[hit_e]
    assert (b > -1e-5).all() and np.allclose(b.sum(axis=1), 1.0)
    corners = v[f[e.triangle[hit_e]]]
    assert np.allclose(np.einsum("nk,nkd->nd", b, corners), e.point[hit_e], atol=1e-12)


def test_ray_triangle_engine_without_embree(standin):
    v, f = standin
    o, d = _rays(v, 200, seed=1)
    t = first_hits(v, f, o, d, engine="triangle")
    assert (t.triangle >= 0).sum() > 50
    with pytest.raises(ValueError, match="engine='laser' is invalid"):
        first_hits(v, f, o, d, engine="laser")
    with pytest.raises(ValueError, match="non-zero"):
        first_hits(v, f, o[:1], np.zeros((1, 3)))


@needs_embree
def test_parity_inside_agrees_with_winding_and_hull_on_closed_meshes(torus):
    rng = np.random.default_rng(2)
    box = trimesh.creation.box(extents=[0.1, 0.2, 0.3])
    for v, f in ((np.asarray(box.vertices), np.asarray(box.faces)), torus):
        p = rng.uniform(v.min(axis=0) - 0.02, v.max(axis=0) + 0.02, size=(4000, 3))
        q = capsule_mesh_query(v, f, p, p, 0.0)
        clear = q.distance > 1e-6  # parity is unreliable on the surface
        rays = inside_by_rays(v, f, p)
        assert np.array_equal(rays[clear], q.inside[clear])
        assert np.array_equal(rays[clear], (winding_number(v, f, p) >= 0.5)[clear])
