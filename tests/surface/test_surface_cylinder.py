"""Cylinder fit and its chart: accuracy, robustness, round trips, Jacobian."""

from __future__ import annotations

import logging
import os

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from sphri.config import ConfigError
from sphri.surface.charts import from_uv, jacobian, primitive_distance, to_uv
from sphri.surface.cylinder import CylinderSurface
from sphri.surface.mesh import MeshSurface
from sphri.surface.meshutil import link_from_trimesh, sample_surface
from sphri.types import Link

#: Hypothesis examples per property (SPHRI_DEEP_TESTS=1 for a deep run).
EXAMPLES = 500 if os.environ.get("SPHRI_DEEP_TESTS") else 50


@pytest.fixture(scope="module")
def cyl_map(cyl_link):
    return CylinderSurface().fit(cyl_link)


def test_fits_a_cylinder(cyl_map):
    p = cyl_map.params
    assert abs(abs(p["axis"][2]) - 1.0) < 1e-4
    # a 96-gon's area-weighted mean radius is a hair under the circumscribed 4 cm
    assert p["radius"] == pytest.approx(0.04, rel=5e-3)
    assert cyl_map.metres_per_u == pytest.approx(0.24, abs=1e-6)
    assert cyl_map.metres_per_v == pytest.approx(2 * np.pi * p["radius"])
    assert cyl_map.wrap_v and cyl_map.has_uv and cyl_map.kind == "cylinder"
    assert cyl_map.fit_residual_m < 5e-4


def test_fit_is_deterministic(cyl_link):
    a, b = CylinderSurface(seed=3).fit(cyl_link), CylinderSurface(seed=3).fit(cyl_link)
    assert a.params["radius"] == b.params["radius"]
    np.testing.assert_array_equal(a.params["axis"], b.params["axis"])


def test_uv_round_trip_on_the_primitive(cyl_map):
    rng = np.random.default_rng(0)
    uv = rng.random((500, 2))
    pts, nrm = from_uv(cyl_map, uv, return_normal=True)
    np.testing.assert_allclose(to_uv(cyl_map, pts), uv, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0)
    assert np.abs(primitive_distance(cyl_map, pts)).max() < 1e-9


@settings(max_examples=EXAMPLES, deadline=None)
@given(u=st.floats(0.05, 0.95), v=st.floats(0.0, 1.0, exclude_max=True), r=st.floats(0.6, 1.4))
def test_jacobian_matches_finite_differences(cyl_map, u, v, r):
    p0 = from_uv(cyl_map, np.array([[u, v]]))
    centre = (
        cyl_map.params["origin"] + ((p0 - cyl_map.params["origin"]) @ cyl_map.params["axis"]) * cyl_map.params["axis"]
    )
    p = centre + r * (p0 - centre)  # off the surface too: the chart is defined in space
    j = jacobian(cyl_map, p)[0]
    eps = 1e-6
    for d in range(3):
        dp = np.zeros((1, 3))
        dp[0, d] = eps
        diff = (to_uv(cyl_map, p + dp) - to_uv(cyl_map, p - dp))[0]
        diff[1] = (diff[1] + 0.5) % 1.0 - 0.5  # unwrap v across the seam
        duv = diff / (2 * eps)
        np.testing.assert_allclose(duv, j[:, d], rtol=1e-4, atol=1e-3)


def test_seam_direction(cyl_link):
    sm = CylinderSurface(seam=[0.0, 1.0, 0.0]).fit(cyl_link)
    uv = to_uv(sm, np.array([[0.0, 0.04, 0.0], [0.04, 0.0, 0.0]]))
    assert uv[0, 1] == pytest.approx(0.0, abs=1e-3) or uv[0, 1] == pytest.approx(1.0, abs=1e-3)
    assert uv[1, 1] in (pytest.approx(0.25, abs=1e-3), pytest.approx(0.75, abs=1e-3))


def test_open_ended_mesh(cyl_link):
    mesh = trimesh.creation.cylinder(radius=0.03, height=0.2, sections=64)
    side = np.abs(mesh.face_normals[:, 2]) < 0.5
    open_mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[side], process=False)
    sm = CylinderSurface().fit(link_from_trimesh(open_mesh, "open"))
    assert sm.params["radius"] == pytest.approx(0.03, rel=5e-3)
    assert sm.metres_per_u == pytest.approx(0.2, abs=1e-6)
    assert sm.fit_residual_m < 5e-4


def test_short_disc_link_gets_its_axis(caplog):
    disc = link_from_trimesh(trimesh.creation.cylinder(radius=0.05, height=0.01, sections=64), "disc")
    with caplog.at_level(logging.WARNING):
        sm = CylinderSurface().fit(disc)
    assert abs(sm.params["axis"][2]) > 0.999
    assert sm.params["radius"] == pytest.approx(0.05, rel=1e-2)
    assert any("short link" in n for n in sm.params["notes"])


def test_nearly_spherical_link_is_flagged(caplog):
    ball = link_from_trimesh(trimesh.creation.icosphere(subdivisions=3, radius=0.05), "ball")
    with caplog.at_level(logging.WARNING):
        sm = CylinderSurface().fit(ball)
    assert "nearly spherical" in caplog.text
    assert np.isfinite(sm.fit_residual_m) and sm.params["radius"] > 0


def test_poor_fit_warns_with_residual_in_mm(box_link, caplog):
    with caplog.at_level(logging.WARNING):
        sm = CylinderSurface(warn_residual_mm=1.0).fit(box_link)
    assert "poor cylinder fit" in caplog.text and "mm" in caplog.text
    assert sm.fit_residual_m > 1e-3


def test_fixed_axis_option(cyl_link):
    sm = CylinderSurface(axis="z", refine_axis=False).fit(cyl_link)
    np.testing.assert_allclose(sm.params["axis"], [0, 0, 1])


def test_bad_link_raises_naming_it():
    bad = Link("broken", np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], float), np.array([[0, 1, 2]]), False)
    with pytest.raises(ValueError, match="broken"):
        CylinderSurface().fit(bad)
    flat = Link("flat", np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float), np.array([[0, 1, 2]]), False)
    with pytest.raises(ValueError, match="flat"):
        CylinderSurface().fit(flat)


def test_mesh_surface_has_no_chart(cyl_link):
    sm = MeshSurface().fit(cyl_link)
    assert not sm.has_uv and sm.metres_per_u == 0.0
    assert sm.params["length_m"] == pytest.approx(0.24, rel=1e-3)
    with pytest.raises(ValueError, match="no 2-D chart"):
        to_uv(sm, np.zeros((1, 3)))


def test_schema_range_checks():
    with pytest.raises(ConfigError, match="surface.axis"):
        CylinderSurface(axis="w")
    with pytest.raises(ConfigError, match="surface.n_samples"):
        CylinderSurface(n_samples=10)
    with pytest.raises(ConfigError, match="surface.seam"):
        CylinderSurface(seam=[0.0, 0.0, 0.0])


@pytest.mark.shared
def test_reachy_arm_hull(arm_link):
    sm = CylinderSurface().fit(arm_link)
    assert abs(sm.params["axis"][2]) > 0.999  # long axis z
    assert sm.metres_per_u * 1e3 == pytest.approx(240.8, abs=0.5)
    assert 30e-3 < sm.params["radius"] < 45e-3
    assert sm.fit_residual_m * 1e3 < 6.0  # an elliptic, tapered hull: a few mm from a cylinder
    pts, _ = sample_surface(arm_link, 2000, 1)
    uv = to_uv(sm, pts)
    assert np.all((uv >= 0) & (uv <= 1)) and np.all(np.isfinite(uv))
