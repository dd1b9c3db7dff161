"""Fixtures of the layout tests: links and fitted surfaces."""

from __future__ import annotations

import pytest
import trimesh

from sphri.surface.cylinder import CylinderSurface
from sphri.surface.meshutil import link_from_trimesh


@pytest.fixture(scope="module")
def cyl_link():
    """A closed cylinder, radius 4 cm, length 24 cm along z."""
    return link_from_trimesh(trimesh.creation.cylinder(radius=0.04, height=0.24, sections=96), "cyl")


@pytest.fixture(scope="module")
def cyl_map(cyl_link):
    return CylinderSurface().fit(cyl_link)


@pytest.fixture(scope="module")
def arm_link(shared_dir):
    mesh = trimesh.load(shared_dir / "vr-gesture-dataset/assets/arm_mesh.obj", process=False)
    return link_from_trimesh(mesh, "arm")


@pytest.fixture(scope="module")
def arm_map(arm_link):
    return CylinderSurface().fit(arm_link)
