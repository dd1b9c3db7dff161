"""Skin area a hand can reach (sphri.sessions.body.reachable_elements): not facing the floor low down, not buried."""

from __future__ import annotations

import numpy as np
import trimesh

from sphri.robots.urdf_tree import UrdfWholeBody
from sphri.sessions.body import body_surface, winding_numbers

URDF = """<robot name="blocks">
  <link name="base"><collision><origin xyz="0 0 0.1"/><geometry><box size="0.4 0.4 0.2"/></geometry></collision></link>
  <link name="ball"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="shelf"><collision><geometry><box size="0.2 0.2 0.02"/></geometry></collision></link>
  <joint name="b" type="fixed"><parent link="base"/><child link="ball"/><origin xyz="0.1 0 0.2"/></joint>
  <joint name="s" type="revolute"><parent link="base"/><child link="shelf"/><origin xyz="0 0 1.0"/><axis xyz="0 0 1"/></joint>
</robot>
"""


def test_winding_number_is_one_inside_zero_outside():
    box = trimesh.creation.box(extents=[1, 2, 3])
    pts = np.array([[0, 0, 0], [0.49, 0.99, 1.49], [0.51, 0, 0], [0, 0, 1.6], [2, 2, 2]])
    w = winding_numbers(pts, box.vertices, box.faces)
    assert np.allclose(w, [1, 1, 0, 0, 0], atol=1e-6)


def test_reachable_area_drops_floor_facing_low_faces_and_buried_ones(tmp_path):
    path = tmp_path / "blocks.urdf"
    path.write_text(URDF)
    robot = UrdfWholeBody(
        path, {"base": {"link": "base"}, "ball": {"link": "ball"}, "shelf": {"link": "shelf"}}
    ).build()
    body = body_surface(robot, robot.tree.links, spacing_mm=8.0, bandwidth_mm=15.0, floor_height_m=0.3, down_cos=0.5)
    t = body.area_table().set_index("part")
    ball_area = t.loc["ball", "area_cm2"]
    # the base's bottom (40 x 40 cm at z = 0) faces the floor; the shelf's underside at 1 m does too, but a hand gets there
    assert abs(t.loc["base", "floor_facing_cm2"] - 1600) < 0.05 * 1600
    assert t.loc["shelf", "floor_facing_cm2"] == 0 and t.loc["shelf", "reachable_cm2"] == t.loc["shelf", "area_cm2"]
    # the ball sits half inside the base: half its area is buried, and the disc of the base's top inside the ball
    assert abs(t.loc["ball", "buried_cm2"] - ball_area / 2) < 0.1 * ball_area / 2
    assert abs(t.loc["base", "buried_cm2"] - np.pi * 5.0**2) < 0.25 * np.pi * 5.0**2
    total = t["area_cm2"].sum()
    assert np.isclose(t["reachable_cm2"].sum() + t["floor_facing_cm2"].sum() + t["buried_cm2"].sum(), total)
    # reachable part areas are what the study ranks and budgets with
    assert np.isclose(body.part_area_m2(reachable=True)["base"] * 1e4, t.loc["base", "reachable_cm2"])
    # a higher floor height takes the shelf's underside too
    high = body_surface(robot, robot.tree.links, spacing_mm=8.0, bandwidth_mm=15.0, floor_height_m=1.5).area_table()
    assert abs(high.set_index("part").loc["shelf", "floor_facing_cm2"] - 400) < 0.1 * 400


def test_sessions_without_a_label_are_never_counted_as_a_gesture():
    import pandas as pd

    from sphri.analysis.coverage import group_order
    from sphri.sessions.labelling import robot_overrides
    from sphri.sessions.study import UNLABELLED, session_gestures

    labelled = pd.DataFrame({"session": [0, 2, 3], "gesture": ["pat", "", "hit"]})
    g = session_gestures(5, labelled)
    assert g == ["pat", UNLABELLED, UNLABELLED, "hit", UNLABELLED]
    assert group_order(pd.Series(g), "gesture") == ["hit", "pat", UNLABELLED]  # its own group, last
    # the gesture model's own job trains on the study's robot, with its robot.* settings
    assert robot_overrides(["+experiment=scenario_study", "seed=1"]) == ["robot=reachy_full"]
    assert robot_overrides(["robot=urdf", "robot.path=/x.urdf", "+robot.parts=/p.yaml", "out=d"]) == [
        "robot=urdf",
        "robot.path=/x.urdf",
        "+robot.parts=/p.yaml",
    ]
    # a robot config of one's own: the gesture job finds it where the study did
    own = ["hydra.searchpath=[file:///my/conf]", "robot=mybot", "plugins=[mylab]", "seed=2"]
    assert robot_overrides(own) == own[:3]
