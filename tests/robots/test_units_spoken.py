"""Units and damage spoken: a mesh or a layout in other units than the settings say is refused with the
measured size and the setting to change; a much-damaged mesh is warned with its numbers."""

from __future__ import annotations

import logging
import subprocess
from pathlib import Path

import forked_cli
import numpy as np
import pytest
import trimesh

from sphri.robots.validate import MeshError, load_mesh_file, make_link


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return forked_cli.run(["-m", *args], cwd, None, 300)


def _arm_cm(path: Path) -> Path:
    """A 24 cm arm (6 x 8 x 24 cm) written in centimetres."""
    trimesh.creation.capsule(height=18.0, radius=3.0).export(path)
    return path


def test_a_mesh_in_centimetres_is_refused_naming_robot_units(tmp_path: Path):
    """A cm mesh was "taken as millimetres, scaled by 0.001" and the run completed with a 2.4 cm arm."""
    mesh = _arm_cm(tmp_path / "arm.stl")
    robot = ["robot=mesh", f"robot.links={{l_arm: {mesh}}}", "robot.regions={arm: l_arm}"]
    proc = _run(["sphri", "+debug=fast", *robot, f"output_dir={tmp_path / 'o'}", "cache.enabled=false"], tmp_path)
    forked_cli.one_line(proc, 1, "mesh error", str(mesh), "24 across", "2.4 cm as millimetres", "robot.units=cm")
    assert "stage robot   computed" not in proc.stdout + proc.stderr


def test_declared_centimetres_are_scaled_to_metres(tmp_path: Path):
    link = load_mesh_file(_arm_cm(tmp_path / "arm.stl"), "arm", units="cm")
    assert np.isclose(np.ptp(link.vertices, axis=0).max(), 0.24)


@pytest.mark.parametrize(
    "units, size, words",
    [
        ("m", 24.0, ("24 m with robot.units=m", "2 cm to 3 m", "robot.units")),  # a cm mesh declared metres
        ("mm", 10.0, ("0.01 m with robot.units=mm", "2 cm to 3 m")),  # a 1 cm link
    ],
)
def test_a_link_outside_a_robots_sizes_is_refused_with_its_size(tmp_path: Path, units: str, size: float, words):
    path = tmp_path / "link.stl"
    trimesh.creation.box(extents=(size / 4, size / 3, size)).export(path)
    with pytest.raises(MeshError) as err:
        load_mesh_file(path, "arm", units=units)
    assert all(w in str(err.value) for w in words), str(err.value)


def test_a_mesh_with_half_its_faces_removed_is_warned_with_the_numbers(caplog):
    """A mesh with half its faces removed ran without a word."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.05)
    faces = np.asarray(sphere.faces)[::2]
    with caplog.at_level(logging.WARNING, logger="sphri.robots.validate"):
        link = make_link("arm", np.asarray(sphere.vertices), faces, units="m")
    assert not link.watertight
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any("boundary edges (holes)" in m and "%" in m and "damaged" in m for m in warned), warned


def test_a_layout_file_in_millimetres_without_scale_is_refused_naming_layout_scale(tmp_path: Path):
    """A layout in mm without `scale` ran with pitch 0.0 mm at chance."""
    from sphri.config import compose
    from sphri.layout.common import LayoutFileError
    from sphri.layout.file import FileLayout
    from sphri.pipeline import build
    from sphri.surface.mesh import MeshSurface

    cfg = compose(["+debug=fast"])
    link = build(cfg.robot).build().link_for("arm")
    pts, tri = trimesh.sample.sample_surface_even(trimesh.Trimesh(link.vertices, link.faces), 200, seed=0)
    nrm = trimesh.Trimesh(link.vertices, link.faces).face_normals[tri]
    path = tmp_path / "skin.npz"
    np.savez(path, position_m=pts * 1000.0, normal=nrm)  # millimetres under the metres' name
    surface = MeshSurface().fit(link)
    with pytest.raises(LayoutFileError) as err:
        FileLayout(path=str(path)).build(link, surface, 18)
    assert "layout.scale=1" in str(err.value) and "0.001 for mm" in str(err.value), str(err.value)
    good = FileLayout(path=str(path), scale=0.001).build(link, surface, 18)
    assert good.n_taxels > 100
