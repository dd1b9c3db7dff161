"""The geometry floor: one LinkGeometry per link, its cached answers equal the plain computations, nothing recomputes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sphri.geometry.link import (
    LinkGeometry,
    closest_points,
    face_normals,
    geometry_of,
    geometry_of_arrays,
    principal_axes,
    sample_surface,
    to_trimesh,
    triangle_normals_areas,
)
from sphri.geometry.samples import neighbour_csr, sample_link
from sphri.types import Link

REPO = Path(__file__).resolve().parents[2]


def _box(name: str = "box", scale: float = 1.0) -> Link:
    """A closed 4 x 6 x 20 cm box of 12 triangles (outward winding)."""
    v = np.array([[x, y, z] for x in (0, 0.04) for y in (0, 0.06) for z in (0, 0.2)], dtype=np.float64) * scale
    f = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4]]
        + [[1, 5, 7], [1, 7, 3]],
        dtype=np.int64,
    )
    return Link(name=name, vertices=v, faces=f, watertight=True)


def test_one_geometry_per_link_and_per_equal_mesh():
    link = _box()
    g = geometry_of(link)
    assert geometry_of(link) is g
    # the same mesh loaded again (e.g. by the next job of a sweep) shares it; another name or mesh does not
    assert geometry_of(_box()) is g
    assert geometry_of(_box(name="other")) is not g
    assert geometry_of(_box(scale=2.0)) is not g
    assert geometry_of_arrays(link.vertices, link.faces) is geometry_of_arrays(link.vertices.copy(), link.faces.copy())


def test_cached_answers_equal_the_plain_computations():
    link = _box()
    g = geometry_of(link)
    unit, area = triangle_normals_areas(link.vertices, link.faces)
    np.testing.assert_array_equal(g.face_normals, unit)
    np.testing.assert_array_equal(g.face_areas, area)
    assert g.area_m2 == pytest.approx(2 * (0.04 * 0.06 + 0.04 * 0.2 + 0.06 * 0.2))
    assert face_normals(link) is g.face_normals  # shared, not recomputed
    with pytest.raises(ValueError, match="read-only"):
        g.face_normals[0, 0] = 1.0
    # samples: the same draw as an uncached geometry; each call hands out its own writable copy
    a, fa = sample_surface(link, 500, 3)
    b, fb = LinkGeometry(link.vertices, link.faces, "box", True).sample(500, 3)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(fa, fb)
    a[:] = 0.0
    np.testing.assert_array_equal(sample_surface(link, 500, 3)[0], b)
    c, w, ax = g.axes(2000, 0)
    c2, w2, ax2 = principal_axes(sample_surface(link, 2000, 0)[0])
    np.testing.assert_array_equal(c, c2)
    np.testing.assert_array_equal(w, w2)
    np.testing.assert_array_equal(ax, ax2)
    assert abs(ax[0] @ [0, 0, 1]) > 0.999  # the long axis of a 20 cm box is z (sampling noise aside)


def test_search_structures_are_built_once():
    link = _box()
    g = geometry_of(link)
    assert to_trimesh(link) is g.trimesh
    assert g.intersector("triangle") is g.intersector("triangle")
    cp, d, tri = closest_points(link, np.array([[0.02, 0.03, 0.3], [0.1, 0.03, 0.1]]))
    np.testing.assert_allclose(cp, [[0.02, 0.03, 0.2], [0.04, 0.03, 0.1]], atol=1e-12)
    np.testing.assert_allclose(d, [0.1, 0.06], atol=1e-12)
    built = []
    assert g.derived("k", lambda: built.append(1) or "v") == "v" and g.derived("k", lambda: built.append(1)) == "v"
    assert built == [1]
    with pytest.raises(ValueError, match="engine='x' is invalid"):
        g.intersector("x")


def test_surface_elements_keep_their_tree_and_graphs():
    link = _box()
    s = sample_link(link, spacing_mm=8.0, seed=1)
    assert sample_link(link, spacing_mm=8.0, seed=1) is s
    assert sample_link(link, spacing_mm=8.0, seed=2) is not s
    assert s.total_area_m2 == pytest.approx(geometry_of(link).area_m2)
    r = 2.5 * s.spacing_m
    kept = s.neighbours(r)
    assert s.neighbours(r) is kept
    for x, y in zip(kept, neighbour_csr(s, r)):
        np.testing.assert_array_equal(x, y)
    # a brute-force check of the graph: same-facing pairs within r, nearest first
    d = np.linalg.norm(s.points_m[:, None] - s.points_m[None], axis=2)
    same = s.normal @ s.normal.T > 0
    indptr, nbr, dist = kept
    for i in (0, 7, s.n - 1):
        want = np.flatnonzero((d[i] <= r) & same[i] & (np.arange(s.n) != i))
        assert sorted(nbr[indptr[i] : indptr[i + 1]]) == sorted(want)
        assert np.all(np.diff(dist[indptr[i] : indptr[i + 1]]) >= 0)
    g = s.knn_graph(10)
    assert s.knn_graph(10) is g and (g != g.T).nnz == 0
    with pytest.raises(ValueError, match="spacing_mm=0 is invalid"):
        sample_link(link, spacing_mm=0)


def test_bad_meshes_are_refused_by_name():
    v = np.zeros((4, 3))
    f = np.array([[0, 1, 2], [0, 2, 3]])
    with pytest.raises(ValueError, match="link 'flat': mesh has zero surface area"):
        geometry_of(Link(name="flat", vertices=v, faces=f, watertight=False)).check()
    with pytest.raises(ValueError, match=r"link 'bad': face indices out of range \[0, 4\)"):
        geometry_of(Link(name="bad", vertices=np.eye(4, 3), faces=np.array([[0, 1, 9]]), watertight=False)).check()


def test_the_floor_imports_no_compute_library():
    """numpy only at import: trimesh, embreex and scipy load where a method needs them."""
    code = (
        "import sys, sphri.geometry.link, sphri.geometry.samples, sphri.surface.meshutil;"
        "bad = [m for m in ('trimesh', 'embreex', 'scipy', 'numba') if m in sys.modules]; print(bad)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
