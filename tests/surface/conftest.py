"""Fixtures of the surface tests: primitive meshes as Links, the real arm hull."""

from __future__ import annotations

import pytest
import trimesh

from sphri.surface.meshutil import link_from_trimesh


@pytest.fixture(scope="module")
def cyl_link():
    """A closed cylinder, radius 4 cm, length 24 cm along z (centred at 0)."""
    return link_from_trimesh(trimesh.creation.cylinder(radius=0.04, height=0.24, sections=96), "cyl")


@pytest.fixture(scope="module")
def box_link():
    """A 30 x 20 x 10 cm box, axes along z, y, x (long axis z)."""
    return link_from_trimesh(trimesh.creation.box(extents=(0.10, 0.20, 0.30)), "box")


@pytest.fixture(scope="module")
def arm_link(shared_dir):
    """The VR study's Reachy arm hull (open, convex, 24.1 cm along z)."""
    mesh = trimesh.load(shared_dir / "vr-gesture-dataset/assets/arm_mesh.obj", process=False)
    return link_from_trimesh(mesh, "arm")
