"""Shared fixtures: ../shared (skipped when absent), temporary output dirs."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

REPO = Path(__file__).resolve().parent.parent

# Property tests draw the same examples on every run (`make test`, CI): a red run is reproducible.
# SPHRI_DEEP_TESTS=1 (`make test-all`) explores new random examples, remembered in .hypothesis/.
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile("explore" if os.environ.get("SPHRI_DEEP_TESTS") else "repeatable")
SHARED = Path(os.environ.get("SPHRI_SHARED", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared folder with the real study's assets; skips the test when absent."""
    if not (SHARED / "vr-gesture-dataset").is_dir():
        pytest.skip(f"../shared not present at {SHARED}")
    return SHARED


@pytest.fixture()
def arm_mesh_roots(tmp_path: Path) -> tuple[Path, Path]:
    """(good, bad): folders holding ``arm.obj``, the parametric Reachy arm or a file that is not a mesh.

    With ``robot=mesh robot.links={l_arm: arm.obj} robot.regions={arm: l_arm} robot.root=...``
    a job on ``bad`` passes validation and fails at the robot stage.
    """
    import trimesh

    from sphri import pipeline
    from sphri.config import compose

    good, bad = tmp_path / "good", tmp_path / "bad"
    good.mkdir()
    bad.mkdir()
    link = pipeline.build(compose(["+debug=fast"]).robot).build().link_for("arm")
    trimesh.Trimesh(link.vertices, link.faces, process=False).export(good / "arm.obj")
    (bad / "arm.obj").write_text("this is not a mesh\n")
    return good, bad
