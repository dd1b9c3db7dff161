"""Coverage (grid and 3-D) and proximity encoders."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.config import ConfigError
from sphri.encode.coverage import CoverageEncoder
from sphri.encode.ellipse import EllipseEncoder
from sphri.encode.proximity import ProximityEncoder
from sphri.layout.poisson import RandomLayout
from sphri.surface.mesh import MeshSurface
from sphri.surface.meshutil import link_from_trimesh
from sphri.testing.synthetic_contacts import make_contacts, synthetic_contacts
from sphri.types import Layout


@pytest.fixture(scope="module")
def plate():
    """A 20 x 20 x 2 cm plate (top face at z = +1 cm) with a hand-made 3 x 3 taxel layout on top."""
    link = link_from_trimesh(trimesh.creation.box(extents=(0.2, 0.2, 0.02)), "plate")
    xy = np.array([(x, y) for x in (-0.02, 0.0, 0.02) for y in (-0.02, 0.0, 0.02)])
    pos = np.column_stack([xy, np.full(9, 0.01)])
    lay = Layout(
        kind="file",
        position_m=pos,
        normal=np.tile([0.0, 0, 1], (9, 1)),
        area_m2=np.full(9, np.pi * 0.005**2),
        uv=None,
        grid_shape=None,
        pitch_u_m=0.02,
        pitch_v_m=0.02,
    )
    return link, MeshSurface().fit(link), lay


def test_grid_coverage_is_the_ellipse_fraction(cyl_link, cyl_map, grids):
    c = synthetic_contacts(cyl_link, 200, seed=2)
    fi = np.arange(200)
    cov = CoverageEncoder().encode(c, cyl_link, cyl_map, grids[18], fi)
    frac = EllipseEncoder(binary=False).encode(c, cyl_link, cyl_map, grids[18], fi)
    assert cov.values.dtype == np.float32 and cov.grid_shape == grids[18].grid_shape
    np.testing.assert_array_equal(cov.values, frac.values)
    assert cov.values.min() >= 0 and cov.values.max() <= 1 and np.isfinite(cov.values).all()


def test_3d_coverage_fractions(plate):
    link, sm, lay = plate
    up = np.array([0.0, 0, 1])
    # frame 0: patch (r = 1 cm) centred on taxel 4 covers its 5 mm disc fully, neighbours 2 cm away not at all
    # frame 1: concentric patch of half the taxel radius covers a quarter of it
    # frame 2: the same patch on the plate's far side (normal -z) is not sensed
    # frame 3: two overlapping patches are not counted twice
    pts = np.array([[0, 0, 0.01], [0, 0, 0.01], [0, 0, -0.01], [0, 0, 0.01], [0.001, 0, 0.01]])
    nrm = np.array([up, up, -up, up, up])
    c = make_contacts([0, 1, 2, 3, 3], pts, nrm, [0.01, 0.0025, 0.01, 0.0025, 0.0025], n_frames=4)
    v = CoverageEncoder(samples_per_taxel=256).encode(c, link, sm, lay, np.arange(4)).values
    assert v.dtype == np.float32 and v.shape == (4, 9)
    assert v[0, 4] == 1.0 and v[0, [0, 1, 2, 3, 5, 6, 7, 8]].sum() == 0
    assert v[1, 4] == pytest.approx(0.25, abs=0.03)
    assert not v[2].any()
    assert v[1, 4] < v[3, 4] < 2 * v[1, 4]


def test_3d_coverage_on_random_layout(cyl_link, cyl_map):
    lay = RandomLayout().build(cyl_link, cyl_map, 12)
    c = synthetic_contacts(cyl_link, 100, seed=3)
    v = CoverageEncoder().encode(c, cyl_link, cyl_map, lay, np.arange(100))
    assert v.values.shape == (100, lay.n_taxels) and v.grid_shape is None
    touched = np.unique(c.frame)
    assert v.values[touched].sum(axis=1).min() > 0
    assert not v.values[np.setdiff1d(np.arange(100), touched)].any()


def test_proximity_range_depth_and_side(plate):
    link, sm, lay = plate
    up = np.array([0.0, 0, 1])
    # capsule sphere radius 8 mm above taxel 4 with its surface at 3 mm (frame 0), 7 mm (frame 1),
    # pressed 2 mm in (frame 2), and under the plate (frame 3)
    heights = [0.011, 0.015, 0.006]
    rows = []
    for f, hgt in enumerate(heights):
        rows.append((f, [0, 0, 0.01], up, hgt))
    c = make_contacts(
        [r[0] for r in rows] + [3],
        [r[1] for r in rows] + [[0, 0, -0.01]],
        [r[2] for r in rows] + [-up],
        [0.001] * 4,
        n_frames=4,
    )
    # place the spheres explicitly: segment point above the taxel, radius 8 mm
    c.segment_point_m = np.array([[0, 0, 0.01 + h] for h in heights] + [[0, 0, -0.016]])
    c.distance_m = np.abs(c.segment_point_m[:, 2]) - 0.01
    c.inside = np.zeros(4, dtype=bool)
    c.depth_m = 0.008 - c.distance_m
    b = ProximityEncoder(sensing_distance_m=0.005).encode(c, link, sm, lay, np.arange(4)).values
    assert b.dtype == np.uint8
    assert b[0, 4] == 1 and b[1, 4] == 0 and b[2, 4] == 1 and b[3].sum() == 0
    d = (
        ProximityEncoder(sensing_distance_m=0.005, intensity="depth", depth_scale_m=0.01)
        .encode(c, link, sm, lay, np.arange(4))
        .values
    )
    assert d.dtype == np.float32
    assert d[0, 4] == pytest.approx((0.005 - 0.003) / 0.015)
    assert d[2, 4] == pytest.approx((0.005 + 0.002) / 0.015)
    assert d[1, 4] == 0 and d[3].sum() == 0


def test_proximity_any_layout(cyl_link, cyl_map, grids):
    c = synthetic_contacts(cyl_link, 100, seed=5)
    g = ProximityEncoder().encode(c, cyl_link, cyl_map, grids[18], np.arange(100))
    assert g.grid_shape == grids[18].grid_shape and g.values.any()
    msm = MeshSurface().fit(cyl_link)
    lay = RandomLayout().build(cyl_link, msm, 18)
    r = ProximityEncoder().encode(c, cyl_link, msm, lay, np.arange(100))
    assert r.values.shape == (100, lay.n_taxels) and r.geometry.uv is None
    # a farther range senses at least as much
    far = ProximityEncoder(sensing_distance_m=0.02).encode(c, cyl_link, msm, lay, np.arange(100))
    assert (far.values >= r.values).all() and far.values.sum() > r.values.sum()


@pytest.mark.parametrize(
    "cls, bad",
    [
        (ProximityEncoder, {"intensity": "pressure"}),
        (ProximityEncoder, {"sensing_distance_m": -1.0}),
        (CoverageEncoder, {"samples_per_taxel": 0}),
    ],
)
def test_schema_checks(cls, bad):
    (key,) = bad
    with pytest.raises(ConfigError, match=f"encoder.{key}"):
        cls(**bad)


def test_proximity_matches_brute_force(cyl_link, cyl_map):
    """The voxel hash misses nothing: same readings as checking every taxel against every capsule."""
    lay = RandomLayout(seed=3).build(cyl_link, cyl_map, 18)
    c = synthetic_contacts(cyl_link, 60, seed=6)
    sd, ds = 0.006, 0.01
    got = (
        ProximityEncoder(sensing_distance_m=sd, intensity="depth", depth_scale_m=ds)
        .encode(c, cyl_link, cyl_map, lay, np.arange(60))
        .values
    )
    radius = np.where(c.inside, c.depth_m - c.distance_m, c.depth_m + c.distance_m)
    want = np.zeros_like(got)
    for k in range(c.n_contacts):
        d = np.linalg.norm(lay.position_m - c.segment_point_m[k], axis=1) - radius[k]
        ok = (d <= sd) & (lay.normal @ c.normal[k] > 0)
        val = np.clip((sd - d) / (sd + ds), 0, 1) * ok
        want[c.frame[k]] = np.maximum(want[c.frame[k]], val)
    np.testing.assert_allclose(got, want, atol=1e-6)
    assert got.any()
