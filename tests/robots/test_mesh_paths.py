"""A URDF's mesh paths stay inside the robot's folder (the URDF's folder, or ``robot.mesh_root``):
``package://u/../../etc/passwd`` was opened, and ``package://u/...`` was looked up in the URDF's parent
folder first, so a copy of a robot folder silently used the original's meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from sphri.robots.urdf import UrdfRobot, mesh_files
from sphri.robots.urdf_tree import MeshResolver, RobotFileError, UrdfWholeBody

ESCAPE = "package://u/" + "../" * 40 + "etc/passwd"


def urdf_with(folder: Path, mesh: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "u.urdf"
    path.write_text(
        f'<robot name="u"><link name="arm"><collision><geometry><mesh filename="{mesh}"/></geometry>'
        "</collision></link></robot>"
    )
    return path


@pytest.mark.parametrize("mesh", [ESCAPE, "file:///etc/passwd", "/etc/passwd", "link"])
def test_a_mesh_path_leaving_the_robot_folder_is_refused_naming_it(mesh, tmp_path):
    robot = tmp_path / "robot"
    if mesh == "link":  # a file inside the folder that is a link to one outside it
        (tmp_path / "outside").mkdir()
        trimesh.creation.box().export(tmp_path / "outside" / "arm.stl")
        (robot / "meshes").mkdir(parents=True)
        (robot / "meshes" / "arm.stl").symlink_to(tmp_path / "outside" / "arm.stl")
        mesh = "package://u/meshes/arm.stl"
    urdf = urdf_with(robot, mesh)
    with pytest.raises(RobotFileError) as err:
        UrdfRobot(path=str(urdf), links=["arm"], regions={"arm": "arm"}).build()
    text = str(err.value)
    assert str(urdf) in text and repr(mesh) in text and f"outside the robot's folder {robot}" in text, text
    with pytest.raises(RobotFileError, match="outside the robot's folder"):
        UrdfWholeBody(urdf, {"arm": {"link": "arm"}}).build()
    with pytest.raises(RobotFileError, match="outside the robot's folder"):
        MeshResolver(robot).resolve(mesh)


def test_a_copied_robot_folder_uses_its_own_meshes(tmp_path):
    original = urdf_with(tmp_path / "u", "package://u/meshes/arm.stl")
    (original.parent / "meshes").mkdir()
    trimesh.creation.box(extents=[0.1, 0.1, 0.1]).export(original.parent / "meshes" / "arm.stl")
    copy = urdf_with(tmp_path / "u_copy", "package://u/meshes/arm.stl")
    (copy.parent / "meshes").mkdir()
    trimesh.creation.box(extents=[0.3, 0.2, 0.1]).export(copy.parent / "meshes" / "arm.stl")  # edited in the copy
    arm = UrdfRobot(path=str(copy), links=["arm"], regions={"arm": "arm"}, units="m").build().links["arm"]
    assert np.ptp(arm.vertices, axis=0) == pytest.approx([0.3, 0.2, 0.1])
    assert mesh_files(copy) == [copy.parent / "meshes" / "arm.stl"]  # the cache key follows the copy's file


def test_meshes_outside_the_urdf_folder_need_mesh_root(tmp_path):
    """A ROS layout (``pkg/urdf/u.urdf``, meshes in ``pkg/meshes``) reads its meshes with robot.mesh_root=pkg."""
    urdf = urdf_with(tmp_path / "pkg" / "urdf", "package://pkg/meshes/arm.stl")
    (tmp_path / "pkg" / "meshes").mkdir()
    trimesh.creation.box(extents=[0.3, 0.2, 0.1]).export(tmp_path / "pkg" / "meshes" / "arm.stl")
    with pytest.raises(FileNotFoundError, match=r"package://pkg/meshes/arm\.stl"):
        UrdfRobot(path=str(urdf), links=["arm"], regions={"arm": "arm"}).build()
    kw = {"links": ["arm"], "regions": {"arm": "arm"}, "units": "m", "mesh_root": str(tmp_path / "pkg")}
    arm = UrdfRobot(path=str(urdf), **kw).build().links["arm"]
    assert np.ptp(arm.vertices, axis=0) == pytest.approx([0.3, 0.2, 0.1])
