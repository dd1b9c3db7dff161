"""Fixtures of the encoder tests: a cylinder link, its chart and grids."""

from __future__ import annotations

import pytest
import trimesh

from sphri.layout.grid import GridLayout
from sphri.surface.cylinder import CylinderSurface
from sphri.surface.meshutil import link_from_trimesh


@pytest.fixture(scope="module")
def cyl_link():
    """A closed cylinder, radius 4 cm, length 24 cm along z (like the Reachy arm)."""
    return link_from_trimesh(trimesh.creation.cylinder(radius=0.04, height=0.24, sections=128), "cyl")


@pytest.fixture(scope="module")
def cyl_map(cyl_link):
    return CylinderSurface(axis="z", refine_axis=False).fit(cyl_link)


@pytest.fixture(scope="module")
def grids(cyl_link, cyl_map):
    """Grid layouts keyed by res."""
    return {res: GridLayout().build(cyl_link, cyl_map, res) for res in (1, 6, 18, 50, 200)}
