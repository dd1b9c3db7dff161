"""Parity inside tests by ray casting (Embree) against the winding-number and hull definitions."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.contact import capsule_mesh_query, winding_number
from sphri.geometry.link import geometry_of_arrays

#: Directions (unit, irrational components) of the parity rays of :func:`_inside_by_rays`.
PARITY_DIRECTIONS = np.array(
    [
        [0.5773502691896258, 0.5773502691896257, 0.5773502691896259],
        [-0.2672612419124244, 0.5345224838248488, -0.8017837257372732],
        [0.8728715609439696, -0.2182178902359924, -0.4364357804719848],
    ]
)


def _inside_by_rays(v, f, pts) -> np.ndarray:
    """(P,) bool: majority vote of crossing parity along :data:`PARITY_DIRECTIONS` (closed meshes only)."""
    rmi = geometry_of_arrays(v, f).intersector("embree")
    votes = np.zeros(pts.shape[0], dtype=np.int64)
    for d in PARITY_DIRECTIONS:
        idx_ray = rmi.intersects_id(pts, np.broadcast_to(d, pts.shape).copy(), multiple_hits=True)[1]
        votes += np.bincount(np.asarray(idx_ray, dtype=np.int64), minlength=pts.shape[0]) % 2
    return votes >= 2


@pytest.mark.skipif(not getattr(trimesh.ray, "has_embree", False), reason="embreex is not installed")
def test_parity_inside_agrees_with_winding_and_hull_on_closed_meshes(torus):
    rng = np.random.default_rng(2)
    box = trimesh.creation.box(extents=[0.1, 0.2, 0.3])
    for v, f in ((np.asarray(box.vertices), np.asarray(box.faces)), torus):
        p = rng.uniform(v.min(axis=0) - 0.02, v.max(axis=0) + 0.02, size=(4000, 3))
        q = capsule_mesh_query(v, f, p, p, 0.0)
        clear = q.distance > 1e-6  # parity is unreliable on the surface
        rays = _inside_by_rays(v, f, p)
        assert np.array_equal(rays[clear], q.inside[clear])
        assert np.array_equal(rays[clear], (winding_number(v, f, p) >= 0.5)[clear])
