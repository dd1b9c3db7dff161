"""Meshes shared by the contact tests (checks live in contact_checks.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.testing.contact_reference import arm_stand_in


@pytest.fixture(scope="session")
def standin():
    """The parametric stand-in of the study's arm hull (convex, open): (vertices, faces)."""
    return arm_stand_in()


@pytest.fixture(scope="session")
def real_arm(shared_dir):
    """The real study's arm hull (Unity OBJ, open, 2 faces wound inward)."""
    m = trimesh.load(shared_dir / "vr-gesture-dataset" / "assets" / "arm_mesh.obj", process=False)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="session")
def real_torso(shared_dir):
    m = trimesh.load(shared_dir / "vr-gesture-dataset" / "assets" / "torso_mesh.obj", process=False)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


@pytest.fixture(scope="session")
def torus():
    """A closed, non-convex mesh (inside resolves to the winding number)."""
    t = trimesh.creation.torus(major_radius=0.08, minor_radius=0.03, major_sections=24, minor_sections=12)
    return np.asarray(t.vertices, dtype=np.float64), np.asarray(t.faces, dtype=np.int64)
