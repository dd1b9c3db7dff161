"""A surface kind is one chart class registered under its name: layouts, coverage maps and
placement text use it without any change to sphri (no `kind ==` switches on surfaces)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from sphri.surface import charts
from sphri.surface.charts import CylinderChart, chart_of, register_chart
from sphri.surface.cylinder import CylinderSurface
from sphri.surface.meshutil import link_from_trimesh


class MirroredChart(CylinderChart):
    """A test-only kind: the cylinder's chart with v running the other way round."""

    every_cell_valid = True

    def to_uv(self, surface, p):
        uv = super().to_uv(surface, p)
        uv[:, 1] = np.mod(1.0 - uv[:, 1], 1.0)
        return uv

    def jacobian(self, surface, p):
        j = super().jacobian(surface, p)
        j[:, 1, :] *= -1.0
        return j

    def from_uv(self, surface, uv):
        flipped = np.column_stack([uv[:, 0], np.mod(1.0 - uv[:, 1], 1.0)])
        return super().from_uv(surface, flipped)

    def describe_uv(self, u, v, around):
        return f"mirrored h {u[0]:.2f}-{u[1]:.2f}"


@pytest.fixture(scope="module")
def mirrored():
    register_chart("mirrored_cylinder", MirroredChart())
    link = link_from_trimesh(trimesh.creation.cylinder(radius=0.04, height=0.24, sections=96), "cyl")
    cyl = CylinderSurface(axis="z", refine_axis=False).fit(link)
    return link, cyl, dataclasses.replace(cyl, kind="mirrored_cylinder")


def test_a_registered_chart_serves_layouts_maps_and_placement_text(mirrored, tmp_path):
    from sphri.analysis.placement import region_text
    from sphri.layout.grid import GridLayout

    link, cyl, mir = mirrored
    assert isinstance(chart_of(mir), MirroredChart)
    a = GridLayout().build(link, cyl, 6)
    b = GridLayout().build(link, mir, 6)
    assert b.grid_shape == a.grid_shape and b.n_taxels == a.n_taxels
    np.testing.assert_allclose(b.area_m2.sum(), a.area_m2.sum(), rtol=1e-6)
    # the same taxel positions, the columns in the other order around the link
    pa = a.position_m.reshape(*a.grid_shape, 3)
    pb = b.position_m.reshape(*b.grid_shape, 3)
    np.testing.assert_allclose(np.sort(pb.reshape(-1, 3), axis=0), np.sort(pa.reshape(-1, 3), axis=0), atol=1e-9)
    uv = charts.to_uv(mir, pb.reshape(-1, 3))
    np.testing.assert_allclose(uv, b.uv, atol=1e-9)
    part = {"area_cm2": 1.0, "centroid_mm": (0, 0, 0), "u_range": (0.1, 0.2), "v_range": (0.3, 0.4)}
    assert region_text(part, mir.kind).endswith("mirrored h 0.10-0.20")


def test_an_unknown_kind_names_the_registry():
    with pytest.raises(ValueError, match="no registered chart.*register_chart"):
        chart_of("cone")
