"""Surface samples, contact footprints and kernel smoothing on simple meshes."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from coverage_fixtures import cylinder_link, plate_link

from sphri.surface.density import SurfaceKernel, graph_stretch, sample_link, touched_elements
from sphri.surface.meshutil import face_areas
from sphri.types import Link


@pytest.fixture(scope="module")
def plane():
    m = trimesh.creation.box(extents=(0.12, 0.12, 0.02))
    return Link("box", np.asarray(m.vertices, float), np.asarray(m.faces, np.int64), True)


@pytest.fixture(scope="module")
def plane_samples(plane):
    return sample_link(plane, spacing_mm=3.0, seed=1)


def top_point(samples, xy=(0.0, 0.0)):
    """Element nearest the top face's point (x, y)."""
    return int(samples.nearest(np.array([[xy[0], xy[1], 0.01]]), np.array([[0, 0, 1.0]]))[0])


def test_samples_cover_the_surface():
    link = cylinder_link()
    s = sample_link(link, spacing_mm=4.0, seed=0)
    area = face_areas(link).sum()
    assert s.total_area_m2 == pytest.approx(area, rel=1e-9)
    assert s.n == pytest.approx(area / 0.004**2, rel=0.01)
    # cells are Voronoi-like: mean area per element and no empty element
    assert s.area_m2.min() > 0
    assert s.area_m2.mean() == pytest.approx(area / s.n)
    np.testing.assert_allclose(np.linalg.norm(s.normal, axis=1), 1.0)
    # deterministic
    s2 = sample_link(link, spacing_mm=4.0, seed=0)
    np.testing.assert_array_equal(s.points_m, s2.points_m)
    with pytest.raises(ValueError, match="raise the spacing"):
        sample_link(link, spacing_mm=0.1, max_samples=1000)


def test_nearest_respects_normals_on_a_thin_plate():
    link = plate_link(thickness=0.002)
    s = sample_link(link, spacing_mm=3.0)
    pts = np.array([[0.01, 0.01, 0.001], [0.01, 0.01, -0.001]])
    idx = s.nearest(pts, np.array([[0, 0, 1.0], [0, 0, -1.0]]))
    assert s.normal[idx[0], 2] > 0.9 and s.normal[idx[1], 2] < -0.9


def test_patch_footprint_touches_a_disc_once_per_frame(plane, plane_samples):
    s = plane_samples
    r = 0.012
    # three capsules of one frame at the same point, one more in frame 7
    pts = np.array([[0, 0, 0.01]] * 3 + [[0.04, 0.04, 0.01]])
    nrm = np.tile([0, 0, 1.0], (4, 1))
    f, e = touched_elements(s, np.array([3, 3, 3, 7]), pts, nrm, np.full(4, r), "patch")
    assert np.all(np.diff(f) >= 0)
    assert len(set(zip(f.tolist(), e.tolist()))) == f.size  # unique pairs
    in3 = e[f == 3]
    area = s.area_m2[in3].sum()
    assert area == pytest.approx(np.pi * r**2, rel=0.2)
    assert np.all(np.linalg.norm(s.points_m[in3] - pts[0], axis=1) <= r + 1e-12)
    assert np.all(s.normal[in3, 2] > 0.9)  # only the top face
    fp, ep = touched_elements(s, np.array([3, 3, 3, 7]), pts, nrm, np.full(4, r), "point")
    assert fp.tolist() == [3, 7]
    with pytest.raises(ValueError, match="footprint"):
        touched_elements(s, np.array([1]), pts[:1], nrm[:1], np.full(1, r), "disc")
    with pytest.raises(ValueError, match="patch_radius_m"):
        touched_elements(s, np.array([1]), pts[:1], nrm[:1], None, "patch")
    e0, e1 = touched_elements(s, np.zeros(0, np.int64), np.zeros((0, 3)), None, np.zeros(0), "patch")
    assert e0.size == 0 and e1.size == 0


@pytest.mark.parametrize("kernel", ["euclidean", "geodesic"])
def test_point_mass_smooths_to_a_gaussian_of_the_bandwidth(plane_samples, kernel):
    s = plane_samples
    h = 10.0
    k = SurfaceKernel(s, bandwidth_mm=h, kernel=kernel)
    c = np.zeros(s.n)
    i = top_point(s)
    c[i] = 5.0
    rho = k.smooth(c)
    assert rho @ s.area_m2 == pytest.approx(1.0)
    d = s.points_m - s.points_m[i]
    var = np.sum(rho * s.area_m2 * d[:, 0] ** 2)
    # a 2-D Gaussian cut at 3 sigma has variance 0.9495 h^2 per axis
    assert np.sqrt(var) * 1e3 == pytest.approx(h * np.sqrt(0.9495), rel=0.05)
    assert np.all(rho[np.linalg.norm(d, axis=1) > 3 * h * 1e-3 * 1.001] == 0)


def test_geodesic_matches_euclidean_on_a_plane(plane_samples):
    s = plane_samples
    c = np.zeros(s.n)
    c[top_point(s, (0.01, -0.02))] = 1
    c[top_point(s, (-0.03, 0.02))] = 2
    a = SurfaceKernel(s, 8.0, "euclidean").smooth(c)
    b = SurfaceKernel(s, 8.0, "geodesic").smooth(c)
    assert np.sum(np.abs(a - b) * s.area_m2) < 0.12  # L1 distance of two densities (max 2)


def test_graph_stretch_is_a_modest_overestimate():
    st = graph_stretch(0.004, bandwidth_m=0.01)
    assert 1.0 <= st < 1.15


def test_geodesic_kernel_does_not_leak_through_a_thin_plate():
    link = plate_link(thickness=0.002, size=0.1)
    s = sample_link(link, spacing_mm=2.5)
    c = np.zeros(s.n)
    c[int(s.nearest(np.array([[0, 0, 0.001]]), np.array([[0, 0, 1.0]]))[0])] = 1
    bottom = s.normal[:, 2] < -0.9
    geo = SurfaceKernel(s, 6.0, "geodesic").smooth(c)
    euc = SurfaceKernel(s, 6.0, "euclidean").smooth(c)
    assert (euc * s.area_m2)[bottom].sum() > 0.3  # straight distance crosses the 2 mm wall
    assert (geo * s.area_m2)[bottom].sum() < 1e-6


def test_kernel_checks_and_batches(plane_samples):
    s = plane_samples
    k = SurfaceKernel(s, 10.0, "euclidean")
    c = np.zeros((3, s.n))
    c[0, 5] = 1
    c[2, 9] = 4
    rho = k.smooth(c)
    assert rho.shape == (3, s.n)
    np.testing.assert_allclose(rho @ s.area_m2, [1, 0, 1])
    assert abs(k.matrix - k.matrix.T).max() < 1e-15
    with pytest.raises(ValueError, match="kernel"):
        SurfaceKernel(s, 10.0, "manhattan")
    with pytest.raises(ValueError, match="bandwidth_mm"):
        SurfaceKernel(s, 0.0)
    with pytest.raises(ValueError, match="elements per row"):
        k.smooth(np.zeros(3))
