"""robot=reachy_full: a whole Reachy as a kinematic tree with named body parts."""

from __future__ import annotations

import numpy as np
import pytest
from hydra.utils import instantiate

from sphri import pipeline
from sphri.cache import StageCache
from sphri.cli import components
from sphri.config import ConfigError, compose


@pytest.fixture(scope="module")
def robot():
    return instantiate(compose(["robot=reachy_full"]).robot).build()


def test_listed_and_has_every_body_part(robot):
    assert "reachy_full" in [n for n, _ in components("robot")]
    for part in (
        "head",
        "shoulder_l",
        "shoulder_r",
        "upper_arm_r",
        "forearm_l",
        "wrist_r",
        "gripper_l",
        "gripper_r",
        "torso_front_upper",
        "torso_back_lower",
        "pedestal",
        "base",
    ):
        assert part in robot.regions
    assert robot.regions["torso_front"] == "torso"  # a group on one link is a region too
    assert all(link.watertight for link in robot.links.values())


def test_joints_move_only_their_subtree(robot):
    links = list(robot.tree.links)
    rest = robot.link_poses(np.zeros((1, 3)))[0]
    bent = robot.link_poses(np.zeros((1, 3)), {"l_elbow_pitch": np.array([-1.2])})[0]
    moved = {n for i, n in enumerate(links) if not np.allclose(rest[i], bent[i])}
    assert moved == {"forearm_l", "wrist_l", "gripper_l"}
    # the forearm turns about the elbow: its frame origin stays put
    i = links.index("forearm_l")
    assert np.allclose(rest[i, :3, 3], bent[i, :3, 3])


def test_base_pose_moves_everything_rigidly(robot):
    rest = robot.rest_poses()
    moved = robot.link_poses(np.array([[1.0, -0.5, np.pi / 2]]))[0]
    rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(moved[:, :3, 3], rest[:, :3, 3] @ rz.T + [1.0, -0.5, 0.0])
    assert np.allclose(moved[:, :3, :3], np.einsum("ij,ljk->lik", rz, rest[:, :3, :3]))
    with pytest.raises(ValueError, match="no joint"):
        robot.link_poses(np.zeros((1, 3)), {"l_knee": np.zeros(1)})


def test_parts_split_the_torso_by_side_and_height(robot):
    from sphri.surface.density import sample_link

    s = sample_link(robot.links["torso"], 10.0)
    lab = robot.part_labels("torso", s.points_m, s.normal)
    assert set(lab) == {"torso_top", "torso_front_upper", "torso_front_lower", "torso_back_upper", "torso_back_lower"}
    front = np.isin(lab, ["torso_front_upper", "torso_front_lower"])
    back = np.isin(lab, ["torso_back_upper", "torso_back_lower"])
    assert (s.normal[front, 0] > 0).all() and (s.normal[back, 0] <= 0).all()
    # the top face is its own part, no longer counted as the upper back (issue 27)
    top = lab == "torso_top"
    assert (s.normal[top, 2] > 0.5).all() and top.sum() > 0.05 * len(lab)
    assert not ((s.normal[:, 2] > 0.5) & (s.points_m[:, 2] >= -0.03) & (lab != "torso_top")).any()


def test_groups_are_regroupable_and_checked():
    r = instantiate(
        compose(
            ["robot=reachy_full", "+robot.groups.hands=[gripper_l,gripper_r]", "robot.groups.shoulders=[shoulder_l]"]
        ).robot
    ).build()
    assert r.groups["hands"] == ("gripper_l", "gripper_r") and r.groups["shoulders"] == ("shoulder_l",)
    assert "hands" not in r.regions and r.regions["shoulders"] == "shoulder_l"  # a region must lie on one link
    with pytest.raises(ConfigError, match=r"robot.groups.hands.*unknown body part"):
        compose(["robot=reachy_full", "+robot.groups.hands=[gripper_x]"])
    with pytest.raises(ConfigError, match=r"robot.parts.head.link='hed'"):
        compose(["robot=reachy_full", "robot.parts.head.link=hed"])
    with pytest.raises(ConfigError, match=r"robot.links.neck.parent='tors'"):
        compose(["robot=reachy_full", "robot.links.neck.parent=tors"])


def test_resolution_study_runs_on_a_body_part(tmp_path):
    cfg = compose(
        [
            "robot=reachy_full",
            "data.regions=[upper_arm_l]",
            "+debug=fast",
            "tracking.enabled=false",
            f"cache.dir={tmp_path}",
        ]
    )
    result = pipeline.run(cfg, StageCache(tmp_path))
    assert len(result.cv.folds) == 3
    assert 0.0 <= result.summary()["accuracy_mean"] <= 1.0
