"""Robots by config: parametric built-ins, mesh files, URDFs."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import yaml
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

import sphri.robots.schema  # noqa: F401  (registers the schemas)
from sphri.config import CONF_DIR, ConfigError
from sphri.robots.mesh import MeshRobot
from sphri.robots.parametric import ParametricRobot, loft_mesh
from sphri.robots.urdf import UrdfRobot
from sphri.robots.validate import is_closed, signed_volume
from sphri.surface.meshutil import triangle_normals_areas

BUILTINS = ("reachy", "nao_child", "service_bot")


def _compose(name: str, overrides=()):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose(config_name=f"robot/{name}", overrides=list(overrides))


def _build(cfg):
    OmegaConf.to_object(cfg.robot)  # schema range checks, as sphri.config.validate does
    return instantiate(cfg.robot).build()


@pytest.fixture(scope="module", params=BUILTINS)
def builtin(request):
    cfg = _compose(request.param)
    raw = yaml.safe_load((CONF_DIR / "robot" / f"{request.param}.yaml").read_text())
    return request.param, raw, _build(cfg)


def test_builtin_loads_with_yaml_dimensions(builtin):
    name, raw, robot = builtin
    assert robot.name == name
    assert set(robot.regions) >= {"arm", "torso"}
    for link_name, spec in raw["links"].items():
        link = robot.links[link_name]
        lo, hi = link.vertices.min(axis=0), link.vertices.max(axis=0)
        np.testing.assert_allclose(hi - lo, spec["size_m"], atol=1e-3)
        np.testing.assert_allclose((hi + lo) / 2, spec["center_m"], atol=1e-3)
        assert link.vertices.dtype == np.float64 and link.faces.dtype == np.int64
        assert 100 <= len(link.faces) <= 1000, "a few hundred faces"


def test_builtin_closed_and_outward(builtin):
    _, _, robot = builtin
    for link in robot.links.values():
        assert link.watertight and is_closed(link.faces)
        assert signed_volume(link.vertices, link.faces) > 0
        # lofts of convex sections: every face looks away from the axis through the centroid
        n, area = triangle_normals_areas(link.vertices, link.faces)
        assert np.all(area > 0)
        c = link.vertices.mean(axis=0)
        assert np.all(np.einsum("ij,ij->i", n, link.vertices[link.faces].mean(axis=1) - c) > 0)
        assert link.notes == ()


def test_reachy_matches_study_hull_frame():
    robot = _build(_compose("reachy"))
    arm = robot.link_for("arm")
    assert arm.vertices[:, 2].min() == pytest.approx(-0.483, abs=1e-3)
    assert arm.vertices[:, 2].max() == pytest.approx(-0.242, abs=1e-3)
    ext = np.ptp(robot.link_for("torso").vertices, axis=0)
    np.testing.assert_allclose(ext, [0.148, 0.346, 0.276], atol=1.5e-3)
    with pytest.raises(KeyError, match="no skin region 'leg'"):
        robot.link_for("leg")


def test_morphologies_differ():
    arms = {n: np.ptp(_build(_compose(n)).link_for("arm").vertices, axis=0) for n in BUILTINS}
    assert arms["nao_child"][2] == pytest.approx(0.105, abs=1e-3)
    assert arms["nao_child"][:2].max() < arms["reachy"][:2].min()
    assert arms["service_bot"][:2].min() > arms["reachy"][:2].max()


@settings(max_examples=50, deadline=None)
@given(
    size=st.lists(st.floats(0.01, 0.5), min_size=3, max_size=3),
    axis=st.sampled_from(["x", "y", "z"]),
    scales=st.lists(st.tuples(st.floats(0.1, 1.0), st.floats(0.1, 1.0)), min_size=2, max_size=6),
    exponent=st.floats(1.0, 6.0),
    n=st.sampled_from([8, 12, 32]),
)
def test_loft_closed_outward_exact_size(size, axis, scales, exponent, n):
    ts = np.linspace(0, 1, len(scales))
    sa = np.array([s[0] for s in scales])
    sb = np.array([s[1] for s in scales])
    sa[np.argmax(sa)] = 1.0
    sb[np.argmax(sb)] = 1.0
    profile = np.stack([ts, sa, sb], 1).tolist()
    v, f = loft_mesh(size, [0.1, -0.2, 0.3], axis, profile, exponent, n)
    assert is_closed(f)
    assert signed_volume(v, f) > 0
    np.testing.assert_allclose(np.ptp(v, axis=0), size, rtol=1e-12)
    np.testing.assert_allclose((v.max(0) + v.min(0)) / 2, [0.1, -0.2, 0.3], atol=1e-12)


def _spec(**kw):
    spec = dict(
        size_m=[0.05, 0.05, 0.2],
        center_m=[0, 0, 0],
        axis="z",
        profile=[[0.0, 1.0, 1.0], [1.0, 1.0, 1.0]],
        exponent=2.0,
        n_around=16,
    )
    spec.update(kw)
    return spec


@pytest.mark.parametrize(
    "kw, key",
    [
        (dict(size_m=[0.05, 0.0, 0.2]), r"robot\.links\.arm\.size_m"),
        (dict(axis="w"), r"robot\.links\.arm\.axis"),
        (dict(n_around=10), r"robot\.links\.arm\.n_around"),
        (dict(exponent=0.5), r"robot\.links\.arm\.exponent"),
        (dict(profile=[[0.0, 1.0, 1.0]]), r"robot\.links\.arm\.profile"),
        (dict(profile=[[0.0, 0.5, 1.0], [1.0, 0.8, 1.0]]), r"largest scale_a must be 1"),
        (dict(profile=[[0.2, 1.0, 1.0], [1.0, 1.0, 1.0]]), r"rise strictly from 0 to 1"),
        (dict(profile=[[0.0, 1.0, 1.0], [1.0, 0.0, 1.0]]), r"profile\[1\]"),
    ],
)
def test_parametric_bad_values(kw, key):
    with pytest.raises(ConfigError, match=key):
        ParametricRobot(name="r", links={"arm": _spec(**kw)}, regions={"arm": "arm"})


def test_parametric_region_must_name_link():
    with pytest.raises(ConfigError, match=r"robot\.regions\.arm.*one of the robot's links"):
        ParametricRobot(name="r", links={"l_arm": _spec()}, regions={"arm": "r_arm"})


def test_schema_checks_on_composition():
    cfg = _compose("reachy", ["robot.links.l_arm.n_around=30"])
    with pytest.raises(ConfigError, match=r"robot\.links\.l_arm\.n_around"):
        OmegaConf.to_object(cfg.robot)
    cfg = _compose("reachy", ["robot.regions.arm=elbow"])
    with pytest.raises(ConfigError, match=r"robot\.regions\.arm"):
        OmegaConf.to_object(cfg.robot)


# ---------------------------------------------------------------- mesh files


def test_mesh_robot_real_assets(shared_dir):
    root = shared_dir / "vr-gesture-dataset"
    robot = MeshRobot(
        name="m",
        links={"l_arm": "assets/arm_mesh.obj", "torso": "assets/torso_mesh.obj"},
        regions={"arm": "l_arm", "torso": "torso"},
        root=str(root),
    ).build()
    arm = robot.link_for("arm")
    assert not arm.watertight
    np.testing.assert_allclose(np.ptp(arm.vertices, axis=0), [0.0718, 0.0928, 0.2408], atol=1e-3)
    assert arm.vertices[:, 2].min() == pytest.approx(-0.4826, abs=1e-4)
    assert any("not closed" in n for n in arm.notes)
    assert any("merged" in n for n in arm.notes)
    # the hull's faces all look away from its interior after validation
    for link in robot.links.values():
        n, _ = triangle_normals_areas(link.vertices, link.faces)
        inner = link.vertices.mean(axis=0)
        assert np.all(np.einsum("ij,ij->i", n, link.vertices[link.faces].mean(axis=1) - inner) > 0)
    np.testing.assert_allclose(np.ptp(robot.link_for("torso").vertices, axis=0), [0.1484, 0.3465, 0.2764], atol=1e-3)


def _compose_reachy_vr(root):
    cfg = _compose("reachy_vr")
    full = OmegaConf.merge(OmegaConf.create({"data": {"root": root}}), cfg)
    return full


def test_reachy_vr_reads_data_root(shared_dir):
    cfg = _compose_reachy_vr(str(shared_dir / "vr-gesture-dataset"))
    robot = _build(cfg)
    assert robot.name == "reachy_vr" and set(robot.regions) == {"arm", "torso"}
    assert not robot.link_for("torso").watertight


def test_reachy_vr_without_root_says_what_to_set():
    cfg = _compose_reachy_vr(None)
    with pytest.raises(
        ConfigError, match=r"robot=reachy_vr reads its meshes from data\.root; set data=vr_gesture data\.root=PATH"
    ):
        _build(cfg)


def test_mesh_robot_missing_file_names_path(tmp_path):
    robot = MeshRobot(links={"arm": "nothing/here.obj"}, regions={"arm": "arm"}, root=str(tmp_path))
    with pytest.raises(FileNotFoundError, match=r"robot\.links\.arm: mesh file not found: .*nothing/here\.obj"):
        robot.build()
    with pytest.raises(FileNotFoundError, match="robot.root: folder not found"):
        MeshRobot(links={"arm": "a.obj"}, regions={"arm": "arm"}, root=str(tmp_path / "nope")).build()


def test_mesh_robot_unreadable_file(tmp_path):
    p = tmp_path / "bad.stl"
    p.write_bytes(b"\x00\x01garbage")
    with pytest.raises(ValueError, match=r"bad\.stl"):
        MeshRobot(links={"arm": str(p)}, regions={"arm": "arm"}).build()


def test_mesh_robot_mm_file(tmp_path):
    import trimesh

    box = trimesh.creation.box(extents=[60.0, 80.0, 240.0])  # millimetres
    box.export(tmp_path / "arm.stl")
    link = MeshRobot(links={"arm": "arm.stl"}, regions={"arm": "arm"}, root=str(tmp_path)).build().link_for("arm")
    np.testing.assert_allclose(np.ptp(link.vertices, axis=0), [0.06, 0.08, 0.24])
    assert any("millimetres" in n for n in link.notes)


def test_mesh_robot_config_requires_links():
    cfg = _compose("mesh")
    with pytest.raises(ConfigError, match=r"robot\.links=None is invalid: a mapping link name -> mesh file"):
        OmegaConf.to_object(cfg.robot)


# ---------------------------------------------------------------- URDF

_URDF = """<?xml version="1.0"?>
<robot name="toy">
  <link name="base">
    <collision><origin xyz="0 0 0.1" rpy="0 0 0"/><geometry><box size="0.2 0.3 0.4"/></geometry></collision>
  </link>
  <link name="upper">
    <visual><geometry><mesh filename="package://toy/meshes/missing_upper.stl"/></geometry></visual>
    <collision><origin xyz="0 0 -0.1" rpy="0 0 0"/><geometry><cylinder radius="0.03" length="0.2"/></geometry></collision>
  </link>
  <link name="lower">
    <visual><geometry><mesh filename="package://toy/meshes/Lower.STL" scale="0.001 0.001 0.001"/></geometry></visual>
    <collision><origin xyz="0 0 -0.05" rpy="0 0 0"/><geometry><sphere radius="0.02"/></geometry></collision>
  </link>
  <joint name="shoulder" type="fixed"><parent link="base"/><child link="upper"/><origin xyz="0 0.2 0"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/><origin xyz="0 0 -0.2"/>
    <axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


@pytest.fixture()
def toy_urdf(tmp_path):
    import trimesh

    (tmp_path / "meshes").mkdir()
    trimesh.creation.box(extents=[30.0, 30.0, 100.0]).export(tmp_path / "meshes" / "lower.stl")  # mm, lower-case name
    p = tmp_path / "toy.urdf"
    p.write_text(_URDF)
    return p


def test_urdf_primitives_collision(toy_urdf):
    robot = UrdfRobot(
        path=str(toy_urdf), links=["base", "upper", "lower"], regions={"arm": "upper", "torso": "base"}
    ).build()
    base = robot.links["base"]
    np.testing.assert_allclose(base.vertices.min(axis=0), [-0.1, -0.15, -0.1])
    np.testing.assert_allclose(base.vertices.max(axis=0), [0.1, 0.15, 0.3])
    upper = robot.link_for("arm")
    np.testing.assert_allclose(upper.vertices[:, 2].min(), -0.2)
    assert upper.watertight and signed_volume(upper.vertices, upper.faces) > 0
    assert np.ptp(robot.links["lower"].vertices, axis=0) == pytest.approx([0.04, 0.04, 0.04], abs=2e-3)


def test_urdf_visual_fallback_and_resolution(toy_urdf, caplog):
    with caplog.at_level(logging.WARNING, logger="sphri.robots.urdf"):
        robot = UrdfRobot(
            path=str(toy_urdf), links=["upper", "lower"], regions={"arm": "upper"}, geometry="visual"
        ).build()
    assert "missing_upper.stl" in caplog.text and "collision primitive" in caplog.text
    assert any("collision primitive" in n for n in robot.links["upper"].notes)
    lower = robot.links["lower"]  # Lower.STL resolved to meshes/lower.stl; URDF scale 0.001 -> metres
    np.testing.assert_allclose(np.ptp(lower.vertices, axis=0), [0.03, 0.03, 0.1])
    assert any("matched by file name" in n for n in lower.notes)


def test_urdf_merge_uses_joints(toy_urdf):
    kw = dict(path=str(toy_urdf), links=["upper"], regions={"arm": "upper"}, merge={"upper": ["lower"]})
    straight = UrdfRobot(**kw).build().links["upper"]
    bent = UrdfRobot(**kw, joints={"elbow": np.pi / 2}).build().links["upper"]
    assert straight.vertices[:, 2].min() == pytest.approx(-0.27, abs=1e-3)  # sphere 0.05 below the elbow
    assert bent.vertices[:, 2].min() == pytest.approx(-0.22, abs=1e-3)  # swung to the side
    assert any("merged link 'lower'" in n for n in bent.notes)


def test_urdf_errors(toy_urdf, tmp_path):
    with pytest.raises(FileNotFoundError, match=r"robot\.path: URDF file not found: .*nope\.urdf"):
        UrdfRobot(path=str(tmp_path / "nope.urdf"), links=["a"], regions={"arm": "a"}).build()
    with pytest.raises(ConfigError, match=r"robot.links: 'hand' is not a link of .*toy"):
        UrdfRobot(path=str(toy_urdf), links=["hand"], regions={"arm": "hand"}).build()
    with pytest.raises(ConfigError, match=r"robot\.joints: \['knee'\]"):
        UrdfRobot(
            path=str(toy_urdf),
            links=["upper"],
            regions={"arm": "upper"},
            joints={"knee": 1.0},
            merge={"upper": ["lower"]},
        ).build()
    with pytest.raises(ConfigError, match=r"robot\.geometry"):
        UrdfRobot(path=str(toy_urdf), links=["upper"], regions={"arm": "upper"}, geometry="inertial")
    with pytest.raises(ConfigError, match=r"robot\.merge\.lower"):
        UrdfRobot(path=str(toy_urdf), links=["upper"], regions={"arm": "upper"}, merge={"lower": ["upper"]})


def test_urdf_mesh_without_fallback_names_path(tmp_path):
    p = tmp_path / "r.urdf"
    p.write_text(
        '<robot name="r"><link name="a"><collision><geometry>'
        '<mesh filename="package://r/meshes/gone.stl"/></geometry></collision></link></robot>'
    )
    with pytest.raises(FileNotFoundError, match=r"link 'a'.*package://r/meshes/gone\.stl.*tried .*gone\.stl"):
        UrdfRobot(path=str(p), links=["a"], regions={"arm": "a"}).build()


def test_urdf_yaml_composes(toy_urdf):
    cfg = _compose(
        "urdf",
        [
            f"robot.path={toy_urdf}",
            "robot.links=[upper,base]",
            "robot.regions={arm:upper,torso:base}",
            "robot.joints={elbow:1.5707963}",
            "robot.merge={upper:[lower]}",
        ],
    )
    robot = _build(cfg)
    assert set(robot.links) == {"upper", "base"}
    assert robot.links["upper"].vertices[:, 2].min() == pytest.approx(-0.22, abs=1e-3)
    cfg = _compose(
        "urdf",
        [f"robot.path={toy_urdf}", "robot.links=[upper]", "robot.regions={arm:upper}", "robot.joints={elbow:fast}"],
    )
    with pytest.raises(ConfigError, match=r"robot\.joints\.elbow"):
        OmegaConf.to_object(cfg.robot)


def test_mesh_yaml_composes(tmp_path):
    import trimesh

    trimesh.creation.box(extents=[0.05, 0.06, 0.2]).export(tmp_path / "arm.obj")
    cfg = _compose("mesh", [f"robot.links={{l_arm: {tmp_path / 'arm.obj'}}}", "robot.regions={arm: l_arm}"])
    robot = _build(cfg)
    np.testing.assert_allclose(np.ptp(robot.link_for("arm").vertices, axis=0), [0.05, 0.06, 0.2])


def test_reachy2021_urdf_fallback(shared_dir, caplog):
    path = shared_dir / "robots" / "reachy2021" / "reachy.URDF"
    with caplog.at_level(logging.WARNING, logger="sphri.robots.urdf"):
        robot = UrdfRobot(
            path=str(path),
            links=["l_upper_arm", "torso", "l_shoulder"],
            regions={"arm": "l_upper_arm", "torso": "torso"},
            geometry="visual",
        ).build()
    assert "upper_arm.dae" in caplog.text and "torso.dae" in caplog.text
    arm = robot.link_for("arm")  # collision cylinder r 0.04, length 0.25, centre z -0.16
    np.testing.assert_allclose(np.ptp(arm.vertices, axis=0), [0.08, 0.08, 0.25], atol=1e-3)
    assert arm.vertices[:, 2].min() == pytest.approx(-0.285, abs=1e-6)
    assert arm.watertight
    shoulder = robot.links["l_shoulder"]  # shoulder.dae is present: a real mesh
    assert len(shoulder.faces) > 1000 and not any("primitive" in n for n in shoulder.notes)
    collision = UrdfRobot(path=str(path), links=["l_upper_arm"], regions={"arm": "l_upper_arm"}).build()
    np.testing.assert_allclose(collision.links["l_upper_arm"].vertices, arm.vertices)


def test_icub_urdf(shared_dir):
    path = shared_dir / "robots" / "icub" / "iCubGazeboV2_5_model.urdf"
    robot = UrdfRobot(
        path=str(path), links=["r_forearm", "chest"], regions={"arm": "r_forearm", "torso": "chest"}
    ).build()
    # bounding boxes from SOURCE.txt (binary STL in mm, URDF scale 0.001)
    np.testing.assert_allclose(np.ptp(robot.link_for("arm").vertices, axis=0), [0.146, 0.074, 0.110], atol=1.5e-3)
    np.testing.assert_allclose(np.ptp(robot.link_for("torso").vertices, axis=0), [0.242, 0.233, 0.278], atol=1.5e-3)
    with pytest.raises(FileNotFoundError, match=r"sim_sea_2-5_r_elbow_prt-binary\.stl"):
        UrdfRobot(path=str(path), links=["r_upper_arm"], regions={"arm": "r_upper_arm"}).build()


def test_poppy_urdf(shared_dir):
    path = shared_dir / "robots" / "poppy_humanoid" / "Poppy_Humanoid.URDF"
    robot = UrdfRobot(
        path=str(path), links=["l_upper_arm", "l_forearm", "chest"], regions={"arm": "l_upper_arm", "torso": "chest"}
    ).build()
    arm = robot.link_for("arm")
    assert 0.10 < np.ptp(arm.vertices, axis=0).max() < 0.16  # upper arm about 0.148 m joint to joint
    assert arm.watertight and signed_volume(arm.vertices, arm.faces) > 0
    assert any("matched by file name" in n for n in robot.links["l_forearm"].notes)  # .STL vs .stl


def test_kinematic_schema_checks_without_the_implementation():
    """The schema holds a whole robot's checks (sphri.robots.schema is the bottom of the package): composing
    robot=reachy_full refuses a bad tree, part or rest pose without importing sphri.robots.kinematic, and the
    component raises the same message for the same bad value."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from sphri.config import ConfigError, compose\n"
        "for bad in (['+robot.rest.nope=1.0'], ['robot.links.neck.parent=head'], ['robot.parts.torso_top.side=+w']):\n"
        "    try:\n"
        "        compose(['robot=reachy_full', *bad])\n"
        "    except ConfigError as exc:\n"
        "        print(str(exc).split(';')[0])\n"
        "print(sorted(m for m in sys.modules if m.startswith('sphri.robots.')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True).stdout
    assert out.splitlines() == [
        "robot.rest: unknown joint(s) ['nope']",
        "robot.links: the parents of ['neck', 'head'] form a cycle",
        "robot.parts.torso_top.side='+w' is invalid: allowed values: ['+x', '-x', '+y', '-y', '+z', '-z'] or null",
        "['sphri.robots.schema']",
    ]
    from sphri.config import compose as compose_sphri
    from sphri.robots.kinematic import KinematicRobot

    cfg = OmegaConf.to_container(compose_sphri(["robot=reachy_full"]).robot)
    cfg["links"]["neck"]["parent"] = "head"
    with pytest.raises(ConfigError, match=r"^robot.links: the parents of \['neck', 'head'\] form a cycle$"):
        KinematicRobot(cfg["name"], cfg["links"], cfg["parts"], cfg["groups"], cfg["rest"])
