"""Box chart: the net, round trips, seam continuity, Jacobian."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.surface.box import BoxSurface
from sphri.surface.charts import box_face, from_uv, jacobian, primitive_distance, to_uv
from sphri.surface.meshutil import sample_surface


@pytest.fixture(scope="module")
def box_map(box_link):
    return BoxSurface().fit(box_link)


def test_fits_the_box(box_map):
    np.testing.assert_allclose(box_map.params["extents"], [0.30, 0.20, 0.10], atol=1e-9)
    assert abs(box_map.params["rotation"][0] @ [0, 0, 1]) == pytest.approx(1.0)
    assert box_map.metres_per_u == pytest.approx(0.30 + 2 * 0.10)
    assert box_map.metres_per_v == pytest.approx(2 * (0.20 + 0.10))
    assert box_map.fit_residual_m < 1e-9
    assert np.linalg.det(box_map.params["rotation"]) == pytest.approx(1.0)


def test_round_trip_every_face(box_link, box_map):
    pts, _ = sample_surface(box_link, 3000, 0)
    uv = to_uv(box_map, pts)
    assert np.all((uv >= 0) & (uv <= 1))
    back, nrm, valid = from_uv(box_map, uv, return_normal=True, return_valid=True)
    assert valid.all()
    np.testing.assert_allclose(back, pts, atol=1e-9)
    assert np.abs(primitive_distance(box_map, back)).max() < 1e-9
    assert set(np.unique(box_face(box_map, pts))) == set(range(6))


def test_void_cells_are_flagged(box_map):
    _, valid = from_uv(box_map, np.array([[0.02, 0.02], [0.5, 0.5]]), return_valid=True)
    assert not valid[0] and valid[1]


def test_jacobian_matches_finite_differences(box_link, box_map):
    pts, _ = sample_surface(box_link, 200, 1)
    j = jacobian(box_map, pts)
    eps = 1e-7
    rng = np.random.default_rng(2)
    checked = 0
    for i in range(len(pts)):
        face = box_face(box_map, pts[i : i + 1])[0]
        normal = box_map.params["rotation"][face // 2] * (1 if face % 2 == 0 else -1)
        t = rng.normal(size=3)
        t -= (t @ normal) * normal  # move within the face
        t /= np.linalg.norm(t)
        a, b = pts[i] + eps * t, pts[i] - eps * t
        if not (box_face(box_map, np.stack([a, b])) == face).all():
            continue
        duv = (to_uv(box_map, a[None]) - to_uv(box_map, b[None]))[0] / (2 * eps)
        if abs(duv[1]) > 1e3:  # crossed the band's seam
            continue
        np.testing.assert_allclose(duv, j[i] @ t, rtol=1e-5, atol=1e-3)
        checked += 1
    assert checked > 150


def test_band_seam_is_continuous(box_map):
    # the band starts (v = 0) at the edge between the -a2 and +a1 faces: points just either side map near 0 and 1
    rot, ext, c = box_map.params["rotation"], box_map.params["extents"], box_map.params["centre"]
    corner = c + 0.5 * ext[1] * rot[1] - 0.5 * ext[2] * rot[2]
    a = corner + 1e-4 * rot[2]  # on +a1
    b = corner - 1e-4 * rot[1]  # on -a2
    va, vb = to_uv(box_map, np.stack([a, b]))[:, 1]
    assert va < 1e-3 and vb > 1 - 1e-3


@pytest.mark.shared
def test_torso_hull(shared_dir):
    from sphri.surface.meshutil import link_from_trimesh

    mesh = trimesh.load(shared_dir / "vr-gesture-dataset/assets/torso_mesh.obj", process=False)
    link = link_from_trimesh(mesh, "torso")
    sm = BoxSurface().fit(link)
    ext = np.sort(sm.params["extents"])[::-1]
    assert ext[0] == pytest.approx(0.346, abs=0.01)
    pts, _ = sample_surface(link, 2000, 0)
    assert np.all(np.isfinite(to_uv(sm, pts)))
