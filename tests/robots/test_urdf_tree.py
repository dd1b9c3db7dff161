"""Whole robots from a URDF (sphri.robots.urdf_tree): robot=reachy2 (packaged), the full description in ../shared,
a lab's robot via robot=urdf robot.parts=..., and the defects a real-world URDF has."""

from __future__ import annotations

import numpy as np
import pytest
from hydra.utils import instantiate

from sphri.config import ConfigError, compose
from sphri.errors import kind_of
from sphri.robots.kinematic import axis_rotation, rpy_matrix
from sphri.robots.schema import BUILTIN
from sphri.robots.urdf_tree import RobotFileError, UrdfWholeBody, parse_urdf

#: The tree robot=reachy2 builds: link -> its parent in the tree of surface links.
REACHY2_PARENT = {
    "base_link": None,
    "back_bar_base": "base_link",
    "torso": "back_bar_base",
    "left_bar_inner": "torso",
    "right_bar_inner": "torso",
    "head": "torso",
    "antenna_left_link": "head",
    "antenna_right_link": "head",
    "l_shoulder_first_link": "torso",
    "l_elbow_arm_link": "l_shoulder_first_link",
    "l_elbow_first_link": "l_elbow_arm_link",
    "l_elbow_forearm_link": "l_elbow_first_link",
    "l_hand_palm_link": "l_elbow_forearm_link",
    "r_shoulder_first_link": "torso",
    "r_elbow_arm_link": "r_shoulder_first_link",
    "r_elbow_first_link": "r_elbow_arm_link",
    "r_elbow_forearm_link": "r_elbow_first_link",
    "r_hand_palm_link": "r_elbow_forearm_link",
}
PARTS = {
    "head",
    "antenna_l",
    "antenna_r",
    "torso_top",
    "torso_front_upper",
    "torso_front_lower",
    "torso_back_upper",
    "torso_back_lower",
    "shoulder_l",
    "shoulder_r",
    "shoulder_ball_l",
    "shoulder_ball_r",
    "upper_arm_l",
    "upper_arm_r",
    "elbow_l",
    "elbow_r",
    "wrist_l",
    "wrist_r",
    "forearm_l",
    "forearm_r",
    "gripper_l",
    "gripper_r",
    "pedestal_back",
    "pedestal_l",
    "pedestal_r",
    "base",
}


def _reachy2(*overrides):
    return instantiate(compose(["robot=reachy2", *overrides]).robot).build()


def _parents(robot):
    t = robot.tree
    return {n: (None if t.parent[i] < 0 else t.links[t.parent[i]]) for i, n in enumerate(t.links)}


def _part_area_cm2(robot, part):
    spec = next(p for p in robot.parts if p.name == part)
    link = robot.links[spec.link]
    tri = link.vertices[link.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    lab = robot.part_labels(spec.link, tri.mean(axis=1), cross / np.maximum(2 * area[:, None], 1e-300))
    return float(area[lab == part].sum()) * 1e4


@pytest.fixture(scope="module")
def packaged():
    return _reachy2()


def test_packaged_reachy2_tree_parts_and_skipped_report(packaged):
    r = packaged
    assert _parents(r) == REACHY2_PARENT
    assert {p.name for p in r.parts} == PARTS
    # every part holds surface; left and right agree (the description is symmetric)
    areas = {p: _part_area_cm2(r, p) for p in PARTS}
    assert all(a > 50 for a in areas.values()), areas
    for side in ("shoulder", "shoulder_ball", "upper_arm", "elbow", "forearm", "wrist", "gripper", "antenna"):
        a, b = areas[f"{side}_l"], areas[f"{side}_r"]
        assert abs(a - b) < 0.03 * max(a, b), (side, a, b)
    skipped = dict(r.skipped)
    assert len(r.tree.links) + len(skipped) == 96  # every link of the file is in the tree or named as skipped
    assert skipped["r_shoulder_dummy_link1"].startswith("a frame without geometry")
    assert skipped["tof_camera_optical"].startswith("a frame without geometry")
    assert skipped["drivewhl1_link"] == "excluded (robot.exclude)"
    assert skipped["l_hand_distal_link"].startswith("merged into 'l_hand_palm_link'")
    # the 20 actuated joints; the gripper's mimic joints are not among them
    assert {"l_shoulder_pitch", "l_elbow_pitch", "neck_yaw", "tripod_joint", "antenna_left"} <= set(r.tree.joint_names)
    assert "r_hand_finger_proximal_mimic" not in r.tree.joint_names


def test_packaged_reachy2_rest_pose_and_joints_move_the_right_links(packaged):
    r = packaged
    names = list(r.tree.links)
    rest = r.rest_poses()

    def top(name, poses=rest):
        link = r.links[name]
        m = poses[names.index(name)]
        return link.vertices @ m[:3, :3].T + m[:3, 3]

    head = top("head")
    assert 1.20 < head[:, 2].max() < 1.25  # Reachy 2 head top about 1.23 m
    assert top("antenna_left_link")[:, 2].max() > head[:, 2].max()  # antennas above the head
    grip = top("l_hand_palm_link")
    assert grip[:, 2].max() < top("torso")[:, 2].min() + 0.05 and grip[:, 1].mean() > 0.2  # left arm hangs at +y
    # shoulder pitch < 0 lifts the arm forward (+x); the prismatic tripod joint raises everything above the base
    fwd = r.link_poses(np.zeros((1, 3)), {"l_shoulder_pitch": np.array([-1.2])})[0]
    assert fwd[names.index("l_hand_palm_link"), 0, 3] > rest[names.index("l_hand_palm_link"), 0, 3] + 0.3
    assert np.allclose(fwd[names.index("r_hand_palm_link")], rest[names.index("r_hand_palm_link")])
    up = r.link_poses(np.zeros((1, 3)), {"tripod_joint": np.array([0.1])})[0]
    assert np.allclose(up[names.index("head"), :3, 3] - rest[names.index("head"), :3, 3], [0, 0, 0.1])
    assert np.allclose(up[names.index("base_link")], rest[names.index("base_link")])
    # the side bars follow the tripod through their mimic joints (tilt about y: their frames move)
    assert not np.allclose(up[names.index("left_bar_inner"), :3, :3], rest[names.index("left_bar_inner"), :3, :3])


@pytest.mark.shared
def test_full_reachy2_description_from_shared(shared_dir, packaged):
    urdf = shared_dir / "robots" / "reachy2" / "reachy2.urdf"
    if not urdf.is_file():
        pytest.skip(f"no Reachy 2 description at {urdf}")
    model = parse_urdf(urdf)
    assert len(model.links) == 96 and model.root == "base_link"
    assert model.joint_of["r_elbow_forearm_link"].parent == "r_elbow_fix_link"
    assert model.joint_of["head"].parent == "neck_out_link"
    assert model.joint_of["r_hand_proximal_mimic_link"].mimic == ("r_hand_finger_proximal", 1.0, 0.0)
    full = _reachy2("robot.builtin=null", f"robot.path={urdf}")
    assert _parents(full) == REACHY2_PARENT
    assert dict(full.skipped).keys() == dict(packaged.skipped).keys()
    assert len(full.links["antenna_left_link"].faces) > 5 * len(packaged.links["antenna_left_link"].faces)
    # the packaged derivative keeps the surface (decimation error is a few mm at most) and the rest pose
    for part in PARTS:
        a, b = _part_area_cm2(full, part), _part_area_cm2(packaged, part)
        assert abs(a - b) < 0.05 * a + 5, (part, a, b)
    assert np.allclose(full.rest_poses(), packaged.rest_poses())
    # the source's statement: mobile base 13,399 cm^2, torso collider 4,550 cm^2
    for link, cm2 in (("base_link", 13399), ("torso", 4550)):
        lk = full.links[link]
        tri = lk.vertices[lk.faces]
        got = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum() * 1e4
        assert abs(got - cm2) < 0.01 * cm2, (link, got)


# ----------------------------------------------------------------- a lab's robot: robot=urdf robot.parts=...

LAB_URDF = """<?xml version="1.0"?>
<robot name="lab">
  <!-- <link name="commented_out"/> -->
  <link name="base"><visual><geometry><mesh filename="package://lab_description/meshes/box.stl"/></geometry></visual>
    <collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.2" length="0.2"/></geometry></collision></link>
  <link name="slider"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="${name}_dummy"/>
  <link name="dummy"/>
  <link name="arm"><collision><geometry><mesh filename="file://$(find lab_description)/meshes/box.stl"/></geometry></collision></link>
  <link name="twin"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <link name="lost"><collision><geometry><mesh filename="package://gone/meshes/nothing.stl"/></geometry></collision></link>
  <link name="floating_bit"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <link name="arm"/>
  <joint name="lift" type="prismatic"><parent link="base"/><child link="slider"/><origin xyz="0 0 0.5"/><axis xyz="0 0 1"/></joint>
  <joint name="fix" type="fixed"><parent link="slider"/><child link="dummy"/><origin xyz="0.1 0 0" rpy="0 0 1.5707963267948966"/></joint>
  <joint name="tilt" type="revolute"><parent link="dummy"/><child link="arm"/><origin xyz="0 0.2 0"/><axis xyz="1 1 0"/></joint>
  <joint name="twin_j" type="revolute"><parent link="dummy"/><child link="twin"/><axis xyz="0 0 1"/><mimic joint="tilt" multiplier="-2" offset="0.1"/></joint>
  <joint name="lost_j" type="fixed"><parent link="base"/><child link="lost"/></joint>
  <gazebo reference="base"><material>Gazebo/Grey</material></gazebo>
</robot>
"""


@pytest.fixture
def lab(tmp_path):
    import trimesh

    root = tmp_path / "ws"
    (root / "lab_description" / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=[0.3, 0.2, 0.1]).export(root / "lab_description" / "meshes" / "box.stl")
    urdf = tmp_path / "robot" / "lab.urdf"
    urdf.parent.mkdir()
    urdf.write_text(LAB_URDF)
    parts = tmp_path / "parts.yaml"
    parts.write_text(
        "parts:\n  base: {link: base}\n  lift: {link: slider}\n  arm_top: {link: arm, side: +z, min_cos: 0.5}\n"
        "  arm: {link: arm}\n  twin: {link: twin}\ngroups:\n  arm_all: [arm_top, arm]\nrest: {tilt: 0.3}\n"
    )
    return urdf, root, parts


def test_lab_urdf_with_parts_file_builds_tree_and_names_what_it_skipped(lab):
    urdf, root, parts = lab
    cfg = compose(
        ["robot=urdf", f"robot.path={urdf}", f"robot.parts={parts}", f"robot.mesh_root={root}", "robot.geometry=auto"]
    )
    r = instantiate(cfg.robot).build()
    assert list(r.tree.links) == ["base", "slider", "arm", "twin"]
    assert _parents(r) == {"base": None, "slider": "base", "arm": "slider", "twin": "slider"}
    skipped = dict(r.skipped)
    assert skipped["${name}_dummy"] == "unexpanded xacro name"
    assert skipped["arm"].startswith("repeated link name")
    assert skipped["dummy"].startswith("a frame without geometry")
    assert "package://gone/meshes/nothing.stl" in skipped["lost"] and "not found under" in skipped["lost"]
    assert skipped["floating_bit"].startswith("not connected to the root link 'base'")
    assert "commented_out" not in skipped
    # geometry auto: the base's visual mesh (package:// resolved under mesh_root) wins over its collision cylinder
    assert np.allclose(np.ptp(r.links["base"].vertices, axis=0), [0.3, 0.2, 0.1])
    assert r.regions["arm_all"] == "arm" and r.regions["twin"] == "twin"
    # kinematics against a hand computation: prismatic lift, fixed frame (skipped) folded in, tilt about (1,1,0)/sqrt2
    q, lift = 0.7, 0.05
    poses = r.link_poses(np.array([[1.0, 2.0, 0.5]]), {"tilt": np.array([q]), "lift": np.array([lift])})[0]
    world = np.eye(4)
    world[:3, :3] = axis_rotation(np.array([0, 0, 1.0]), np.array(0.5))
    world[:3, 3] = [1.0, 2.0, 0.0]
    slider = world.copy()
    slider[:3, 3] += world[:3, :3] @ [0, 0, 0.5 + lift]
    dummy = slider @ _tf([0.1, 0, 0], rpy_matrix([0, 0, np.pi / 2]))
    arm = (
        dummy
        @ _tf([0, 0.2, 0], np.eye(3))
        @ _tf([0, 0, 0], axis_rotation(np.array([1, 1, 0.0]) / np.sqrt(2), np.array(q)))
    )
    twin = dummy @ _tf([0, 0, 0], axis_rotation(np.array([0, 0, 1.0]), np.array(-2 * q + 0.1)))
    names = list(r.tree.links)
    assert np.allclose(poses[names.index("slider")], slider)
    assert np.allclose(poses[names.index("arm")], arm)
    assert np.allclose(poses[names.index("twin")], twin)  # the mimic joint follows tilt
    # the rest pose comes from the parts file
    rest_twin = r.rest_poses()[names.index("twin")]
    expect = (
        _tf([0, 0, 0.5], np.eye(3))
        @ _tf([0.1, 0, 0], rpy_matrix([0, 0, np.pi / 2]))
        @ _tf([0, 0, 0], axis_rotation(np.array([0, 0, 1.0]), np.array(-2 * 0.3 + 0.1)))
    )
    assert np.allclose(rest_twin, expect)


def _tf(xyz, rot):
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = xyz
    return m


def test_bad_descriptions_are_one_line_errors_naming_the_file(lab, tmp_path, study_error_line):
    urdf, root, parts = lab
    text = BUILTIN["reachy2"].read_text()
    cut = tmp_path / "truncated.urdf"
    cut.write_text(text[: len(text) // 2])
    with pytest.raises(RobotFileError, match=r"truncated.urdf: not a well-formed URDF .*line \d+") as err:
        _reachy2("robot.builtin=null", f"robot.path={cut}")
    assert kind_of(err.value) == "robot file error"
    # the plain URDF robot too (yourdfpy alone would load the first half of the file as a smaller robot)
    from sphri.robots.urdf import UrdfRobot

    cut2 = tmp_path / "cut2.urdf"
    cut2.write_text(LAB_URDF[: LAB_URDF.index('<link name="lost"')])
    with pytest.raises(RobotFileError, match=r"cut2.urdf: not a well-formed URDF"):
        UrdfRobot(path=str(cut2), links=["base"], regions={"torso": "base"}).build()
    with pytest.raises(FileNotFoundError, match=r"robot.mesh_root: folder not found: .*nowhere"):
        UrdfWholeBody(urdf, parts, mesh_root=tmp_path / "nowhere").build()
    bad = tmp_path / "bad.urdf"
    bad.write_text(LAB_URDF.replace('xyz="0 0 0.5"', 'xyz="0 zero 0.5"'))
    with pytest.raises(RobotFileError, match=r"bad.urdf: joint 'lift' origin xyz='0 zero 0.5' is not 3 numbers"):
        UrdfWholeBody(bad, parts, mesh_root=root).build()
    with pytest.raises(ConfigError, match=r"robot.parts.arm.link: 'nope' is not a link of .*lab.urdf"):
        UrdfWholeBody(urdf, {"arm": {"link": "nope"}}, mesh_root=root).build()
    with pytest.raises(ConfigError, match=r"robot.parts.arm.link: 'slidr' \(did you mean slider\?\) is not a link"):
        UrdfWholeBody(urdf, {"arm": {"link": "slidr"}}, mesh_root=root).build()
    with pytest.raises(
        ConfigError, match=r"robot.parts.cam.link='dummy' has no surface in .*: a frame without geometry"
    ):
        UrdfWholeBody(urdf, {"cam": {"link": "dummy"}}, mesh_root=root).build()
    with pytest.raises(ConfigError, match=r"robot.exclude: 'nope' is not a link of"):
        UrdfWholeBody(urdf, parts, mesh_root=root, exclude=["nope"]).build()
    ypath = tmp_path / "broken.yaml"
    ypath.write_text("parts: [unclosed\n")
    with pytest.raises(RobotFileError, match=r"broken.yaml: not valid YAML"):
        UrdfWholeBody(urdf, str(ypath))
    # the command line prints one line naming the file, no traceback
    error = study_error_line("robot=reachy2", "robot.builtin=null", f"robot.path={cut}")
    assert "robot file error" in error and str(cut) in error, error


def test_scenario_study_accepts_urdf_robots_with_parts_only(lab):
    urdf, root, parts = lab
    compose(["+experiment=scenario_study", "robot=reachy2"])
    compose(["+experiment=scenario_study", "robot=urdf", f"robot.path={urdf}", f"robot.parts={parts}"])
    with pytest.raises(ConfigError, match=r"kinematic tree"):
        compose(
            [
                "+experiment=scenario_study",
                "robot=urdf",
                f"robot.path={urdf}",
                "robot.links=[base]",
                "robot.regions={torso: base}",
            ]
        )
    with pytest.raises(ConfigError, match=r"robot.path"):
        compose(["robot=urdf", "robot.links=[base]", "robot.regions={torso: base}"])


# ----------------------------------------------------------------- the packaged derivative


def test_vertex_clustering_keeps_within_the_face_budget_and_near_the_surface():
    import trimesh

    from sphri.robots.reachy2_derivative import decimate_to, surface_error_mm

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.05)  # 20,480 faces
    small = decimate_to(sphere, 2000)
    assert 1000 < len(small.faces) <= 2000
    err = surface_error_mm(sphere, small)
    assert err["max_mm"] < 2.5 and err["mean_mm"] < 0.5
    assert decimate_to(small, 5000).faces.shape == small.faces.shape  # within the budget: unchanged


@pytest.mark.shared
@pytest.mark.slow
def test_derivative_regenerates_byte_identically_from_shared(shared_dir, tmp_path):
    from sphri.robots.reachy2_derivative import derive

    src = shared_dir / "robots" / "reachy2"
    if not (src / "reachy2.urdf").is_file():
        pytest.skip(f"no Reachy 2 description at {src}")
    derive(src, tmp_path)
    shipped = BUILTIN["reachy2"].parent
    for p in sorted(shipped.rglob("*")):
        if p.is_file():
            assert (tmp_path / p.relative_to(shipped)).read_bytes() == p.read_bytes(), p.name
