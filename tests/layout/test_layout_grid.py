"""Grid and hex layouts: sizes, physical pitch, positions on the mesh, ray projection."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.config import ConfigError
from sphri.layout.common import grid_dims, row_offsets
from sphri.layout.grid import GridLayout, HexLayout
from sphri.layout.units import describe
from sphri.surface.box import BoxSurface
from sphri.surface.charts import from_uv
from sphri.surface.mesh import MeshSurface
from sphri.surface.meshutil import closest_points, face_areas, link_from_trimesh, project_along


@pytest.mark.shared
def test_paper_resolution_on_the_reachy_arm(arm_link, arm_map):
    """layout.res=18 on the 24.1 cm arm is the paper's 18 taxels per 24 cm: ~13.4 mm pitch."""
    lay = GridLayout().build(arm_link, arm_map, 18)
    d = describe(lay, arm_map)
    assert lay.grid_shape[0] == 18
    assert d["pitch_u_mm"] == pytest.approx(13.38, abs=0.05)
    assert d["taxels_per_24cm"] == pytest.approx(17.94, abs=0.05)
    # square taxels: W from the circumference
    assert lay.grid_shape[1] == round(18 * arm_map.metres_per_v / arm_map.metres_per_u)
    assert d["pitch_v_mm"] == pytest.approx(d["pitch_u_mm"], rel=0.05)
    assert d["skin_area_cm2"] == pytest.approx(face_areas(arm_link).sum() * 1e4)
    _, dist, _ = closest_points(arm_link, lay.position_m)
    assert dist.max() < 1e-6


def test_grid_shape_and_units(cyl_link, cyl_map):
    lay = GridLayout().build(cyl_link, cyl_map, 24)
    h, w = lay.grid_shape
    assert h == 24 and w == round(24 * cyl_map.metres_per_v / 0.24)
    assert lay.n_taxels == h * w and lay.uv.shape == (h * w, 2)
    assert lay.pitch_u_m == pytest.approx(0.01)
    # taxels sit on the mesh, normals point outward
    _, dist, _ = closest_points(cyl_link, lay.position_m)
    assert dist.max() < 1e-6
    radial = lay.position_m[:, :2] / np.linalg.norm(lay.position_m[:, :2], axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", lay.normal[:, :2], radial) > 0.99).all()
    # areas: the lateral cells share the side, caps fold into the end rows
    assert lay.area_m2.sum() == pytest.approx(face_areas(cyl_link).sum(), rel=1e-9)
    mid = lay.area_m2.reshape(h, w)[2:-2]
    assert mid.mean() == pytest.approx(0.01 * cyl_map.metres_per_v / w, rel=0.02)
    d = describe(lay, cyl_map)
    assert d["n_taxels"] == h * w and d["taxels_per_cm_u"] == pytest.approx(1.0)


def test_aspect_and_extreme_res(cyl_link, cyl_map):
    assert GridLayout(aspect=2.0).build(cyl_link, cyl_map, 24).grid_shape == (
        24,
        round(24 * cyl_map.metres_per_v / 0.24 / 2),
    )
    one = GridLayout().build(cyl_link, cyl_map, 1)
    assert one.grid_shape == (1, 1) and one.n_taxels == 1
    big = GridLayout().build(cyl_link, cyl_map, 200)
    assert big.grid_shape[0] == 200 and np.isfinite(big.position_m).all()
    for bad in (0, 1001, 2.5):
        with pytest.raises(ValueError, match="res"):
            GridLayout().build(cyl_link, cyl_map, bad)


def test_hex_rows_are_shifted(cyl_link, cyl_map):
    lay = HexLayout().build(cyl_link, cyl_map, 12)
    h, w = lay.grid_shape
    off = row_offsets(lay.uv, lay.grid_shape)
    np.testing.assert_allclose(off, np.where(np.arange(h) % 2 == 1, 0.5, 0.0), atol=1e-9)
    assert (h, w) == grid_dims(cyl_map, 12, hex_rows=True)
    # equilateral lattice: in-row spacing = row spacing * 2 / sqrt(3)
    assert lay.pitch_v_m == pytest.approx(lay.pitch_u_m * 2 / np.sqrt(3), rel=0.1)


@pytest.mark.parametrize("res", [3, 6, 12, 18, 30, 50])
def test_hex_matches_the_grids_taxel_count(cyl_link, cyl_map, res):
    grid = GridLayout().build(cyl_link, cyl_map, res)
    hexa = HexLayout().build(cyl_link, cyl_map, res)
    assert abs(hexa.n_taxels - grid.n_taxels) <= 0.02 * grid.n_taxels + 1
    # the same area per taxel: the hex nearest-neighbour spacing is sqrt(2/sqrt(3)) ~ 1.075 x the grid pitch
    h, w = hexa.grid_shape
    assert cyl_map.metres_per_v / w == pytest.approx(grid.pitch_u_m * np.sqrt(2 / np.sqrt(3)), rel=0.12)


def test_grid_needs_a_chart(cyl_link):
    with pytest.raises(ValueError, match="layout.grid needs a surface with a 2-D chart"):
        GridLayout().build(cyl_link, MeshSurface().fit(cyl_link), 18)


def test_box_grid_marks_void_cells():
    link = link_from_trimesh(trimesh.creation.box(extents=(0.1, 0.2, 0.3)), "box")
    sm = BoxSurface().fit(link)
    lay = GridLayout().build(link, sm, 15)
    _, valid = from_uv(sm, lay.uv, return_valid=True)
    assert (lay.area_m2[~valid] == 0).all() and (lay.area_m2[valid] > 0).mean() > 0.9
    assert lay.area_m2.sum() == pytest.approx(face_areas(link).sum())
    assert lay.pitch_u_m == pytest.approx(0.3 / 15, rel=0.05)  # res counts along the long side
    assert np.isfinite(lay.position_m).all()


def test_embree_matches_pure_python_rays():
    """Embree works in float32: its hits must agree with trimesh's float64 ray_triangle."""
    link = link_from_trimesh(trimesh.creation.capsule(height=0.2, radius=0.035, count=[24, 24]), "capsule")
    rng = np.random.default_rng(0)
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    pts = d * 0.05
    a, fa, ha = project_along(link, pts, d, max_dist_m=0.5, use_embree=True)
    b, fb, hb = project_along(link, pts, d, max_dist_m=0.5, use_embree=False)
    assert ha.all() and hb.all()
    np.testing.assert_allclose(a, b, atol=1e-5)
    _, dist, _ = closest_points(link, a)
    assert dist.max() < 1e-5


def test_schema_range_checks():
    with pytest.raises(ConfigError, match="layout.aspect"):
        GridLayout(aspect=0.0)
    with pytest.raises(ConfigError, match="layout.seed"):
        HexLayout(seed=-1)
