"""Mountable surface: no rotating joint shell, no rod, nothing too small is ranked first or placed."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sphri.config import ConfigError
from sphri.robots.schema import check_part_specs
from sphri.robots.urdf_tree import UrdfWholeBody
from sphri.sessions.body import rest_surface
from sphri.sessions.placement import greedy_parts, mountable_parts, part_width_mm, placement_table, rank_parts

URDF = """<robot name="blocks">
  <link name="base"><collision><origin xyz="0 0 0.6"/><geometry><box size="0.4 0.4 0.4"/></geometry></collision></link>
  <link name="ball"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="rod"><collision><geometry><cylinder radius="0.005" length="0.2"/></geometry></collision></link>
  <link name="tab"><collision><geometry><box size="0.03 0.03 0.03"/></geometry></collision></link>
  <joint name="b" type="revolute"><parent link="base"/><child link="ball"/><origin xyz="0 0.25 0.7"/>
    <axis xyz="0 1 0"/></joint>
  <joint name="r" type="fixed"><parent link="base"/><child link="rod"/><origin xyz="0 0 0.95"/></joint>
  <joint name="t" type="fixed"><parent link="base"/><child link="tab"/><origin xyz="0.3 0 0.6"/></joint>
</robot>
"""


@pytest.fixture(scope="module")
def blocks(tmp_path_factory):
    path = tmp_path_factory.mktemp("blocks") / "blocks.urdf"
    path.write_text(URDF)
    parts = {
        "ball": {"link": "ball", "mountable": False},
        "rod": {"link": "rod"},
        "tab": {"link": "tab"},
        "base": {"link": "base"},
    }
    robot = UrdfWholeBody(path, parts).build()
    body = rest_surface(robot, robot.tree.links, spacing_mm=5.0)
    return robot, body


def areas(body) -> dict[str, float]:
    return {p: float(body.samples.area_m2[body.part == p].sum()) for p in body.parts}


def test_width_of_a_rod_a_plate_and_a_ball():
    rod = trimesh.creation.cylinder(radius=0.005, height=0.2).sample(4000, seed=0)
    # a rod of 10 mm bent along a 0.3 m radius over 40 degrees: its bounding box is 20 mm deep, it is still a rod
    rng = np.random.default_rng(0)
    t, a = rng.uniform(-0.35, 0.35, 8000), rng.uniform(0, 2 * np.pi, 8000)
    r = 0.3 + 0.005 * np.cos(a)
    bent = np.stack([r * np.sin(t), 0.005 * np.sin(a), r * np.cos(t)], axis=1)
    plate = trimesh.creation.box(extents=[0.2, 0.1, 0.002]).sample(4000, seed=0)
    ball = trimesh.creation.icosphere(4, radius=0.04).sample(4000, seed=0)
    assert part_width_mm(rod) == pytest.approx(10.0, abs=1.0)
    assert np.ptp(bent[:, 2]) > 0.02 and part_width_mm(bent) < 15.0
    assert part_width_mm(plate) == pytest.approx(100.0, abs=3.0)
    assert part_width_mm(ball) == pytest.approx(80.0 * np.sqrt(3) / 2, abs=4.0)  # the chord at the median slice


def test_parts_not_mountable_are_listed_with_the_reason(blocks):
    robot, body = blocks
    reach = areas(body)
    t = mountable_parts(body, robot, reach, min_diameter_mm=20.0, min_patch_cm2=60.0).set_index("part")
    assert t.loc["ball", "reason"].startswith("rotating joint")
    assert t.loc["rod", "reason"].startswith("narrower than min_diameter_mm=20")
    assert t.loc["rod", "width_mm"] == pytest.approx(10.0, abs=1.5)
    assert t.loc["tab", "reason"].startswith("smaller than min_patch_cm2=60")  # a 3 cm cube: 54 cm^2
    assert t.loc["base", "mountable"] and t.loc["base", "reason"] == ""


def test_no_excluded_part_is_ranked_first_or_placed(blocks):
    robot, body = blocks
    reach = areas(body)
    t = mountable_parts(body, robot, reach, min_diameter_mm=20.0, min_patch_cm2=30.0)
    parts = t["part"].tolist()
    area = t["reachable_cm2"].to_numpy() * 1e-4
    excluded = {p: r for p, r in zip(parts, t["reason"]) if r}
    # the small ball and the rod take most contact per cm^2; the base the most contact
    rng = np.random.default_rng(0)
    m = np.zeros((200, len(parts)), dtype=bool)
    for name, share in (("ball", 0.4), ("rod", 0.3), ("tab", 0.1), ("base", 0.6)):
        m[:, parts.index(name)] = rng.random(200) < share
    allowed = np.array([p not in excluded for p in parts])
    assert set(excluded) == {"ball", "rod"}
    ranking = rank_parts(m, parts, area, excluded)
    assert ranking["part"].tolist()[:2] == ["tab", "base"] and set(ranking["part"].tolist()[2:]) == {"ball", "rod"}
    chosen = [parts[j] for j in greedy_parts(m, area, 1.0, allowed)]
    assert chosen[0] == ranking["part"].iat[0] and not set(chosen) & set(excluded)
    table = placement_table(
        m, np.array(["A", "B"] * 100), np.repeat(["p1", "p2"], 100), ["A", "B"], parts, area, 1.0, allowed
    )
    for row in table.itertuples():
        assert not set(row.parts.split(";")) & set(excluded)
    # without the mountable criterion a part no skin can go on is the first choice
    assert parts[greedy_parts(m, area, 1.0)[0]] in excluded


@pytest.mark.parametrize("value", ["no", 0, "false"])
def test_a_mountable_flag_that_is_not_a_boolean_is_refused(value):
    with pytest.raises(ConfigError, match=r"robot.parts.ball.mountable=.* is invalid: true or false"):
        check_part_specs({"ball": {"link": "ball", "mountable": value}}, {"ball": None})


def test_reachy2s_orbita_joints_are_marked_not_mountable():
    from hydra.utils import instantiate

    from sphri.config import compose

    cfg = compose(["data=synthetic_sessions", "robot=reachy2"])
    spec = instantiate(cfg.robot)
    marked = {p.name for p in spec.build().parts if not p.mountable}
    assert marked == {"shoulder_ball_l", "shoulder_ball_r", "elbow_l", "elbow_r", "wrist_l", "wrist_r"}
