"""``sphri robot check``: parts, areas, skipped links and a picture; link names checked against the URDF with
"did you mean" by ``sphri validate`` and at run time."""

from __future__ import annotations

import logging
import re

import pytest

from sphri.command import main as sphri_main
from sphri.config import ConfigError, compose
from sphri.robots.urdf import UrdfRobot

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

SMALL_URDF = """<?xml version="1.0"?>
<robot name="small">
  <link name="base"><collision><origin xyz="0 0 0.05"/><geometry><box size="0.4 0.2 0.1"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0 0 0.15"/><geometry><box size="0.1 0.1 0.3"/></geometry></collision></link>
  <link name="tool_frame"/>
  <link name="camera"><visual><geometry><mesh filename="package://small/meshes/camera.stl"/></geometry></visual></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/></joint>
  <joint name="tip" type="fixed"><parent link="arm"/><child link="tool_frame"/><origin xyz="0 0 0.3"/></joint>
  <joint name="cam" type="fixed"><parent link="base"/><child link="camera"/></joint>
</robot>
"""


@pytest.fixture
def small(tmp_path):
    urdf = tmp_path / "small.urdf"
    urdf.write_text(SMALL_URDF)
    parts = tmp_path / "parts.yaml"
    parts.write_text(
        "parts:\n  arm_top: {link: arm, z_min: 0.2}\n  arm: {link: arm}\n  base: {link: base}\n"
        "groups:\n  whole_arm: [arm_top, arm]\n"
    )
    return urdf, parts


def _areas(text: str) -> dict[str, float]:
    return {m[1]: float(m[2].replace(",", "")) for m in re.finditer(r"^  (\w+) +([\d,]+) cm\^2", text, re.M)}


def test_check_prints_parts_areas_skipped_links_and_draws_them(small, tmp_path, capsys, caplog):
    urdf, parts = small
    png = tmp_path / "parts.png"
    with caplog.at_level(logging.WARNING, logger="sphri.figures"):
        assert sphri_main(["robot", "check", str(urdf), f"parts={parts}", f"out={png}", "spacing_mm=5"]) == 0
    assert not [r for r in caplog.records if r.name == "sphri.figures"], "the picture has no layout problem"
    out = capsys.readouterr().out
    areas = _areas(out)
    # boxes: the base 0.4 x 0.2 x 0.1 m (2,800 cm^2); the arm 0.1 x 0.1 x 0.3 m (1,400 cm^2), its top 10 cm a part
    assert list(areas) == ["arm_top", "arm", "base"], out
    assert areas["base"] == pytest.approx(2800, rel=0.02)
    assert areas["arm_top"] == pytest.approx(100 + 4 * 100, rel=0.05)
    assert areas["arm_top"] + areas["arm"] == pytest.approx(1400, rel=0.02)
    assert re.search(r"group whole_arm: arm_top, arm \(1,[34]\d\d cm\^2\)", out), out
    assert "skipped links (2):" in out
    assert re.search(r"a frame without geometry.*\(1\): tool_frame", out), out
    assert re.search(r"visual mesh 'package://small/meshes/camera.stl' not found .*: camera", out), out
    assert "4 links: 2 with a surface, 2 skipped" in out
    assert png.read_bytes()[:8] == PNG_MAGIC and not png.with_suffix(".pdf").exists()


def test_check_without_parts_makes_each_link_a_part(small, tmp_path, capsys):
    urdf, _ = small
    assert sphri_main(["robot", "check", str(urdf), f"out={tmp_path / 'p.png'}"]) == 0
    assert list(_areas(capsys.readouterr().out)) == ["base", "arm"]


@pytest.mark.parametrize(
    "args, match",
    [
        (["nope.urdf"], r"nope.urdf: no such file \(give a URDF file, or a robot config that reads one: .*reachy2"),
        (["{bad}"], r"bad.urdf: not a well-formed URDF"),
        (["{urdf}", "parts={unknown}"], r"robot.parts.top.link: 'armm' \(did you mean arm\?\) is not a link of"),
        (["{urdf}", "parts={tmp}/none.yaml"], r"body-part file not found: .*none.yaml"),
        (["reachy"], r"robot config 'reachy' .* does not read a URDF"),
        (["{urdf}", "spacing_mm=0"], r"spacing_mm"),
    ],
)
def test_check_bad_inputs_are_one_line_exit_2(small, tmp_path, capsys, args, match):
    urdf, _ = small
    bad = tmp_path / "bad.urdf"
    bad.write_text(SMALL_URDF[:200])
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text("parts:\n  top: {link: armm}\n")
    names = {"urdf": urdf, "bad": bad, "unknown": unknown, "tmp": tmp_path}
    argv = [a.format(**names) for a in args]
    assert sphri_main(["robot", "check", *argv, f"out={tmp_path / 'x.png'}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sphri robot"), err
    assert re.search(match, err[0]), err[0]


def test_check_the_packaged_robot(tmp_path, capsys):
    png = tmp_path / "reachy2.png"
    assert sphri_main(["robot", "check", "reachy2", f"out={png}"]) == 0
    out = capsys.readouterr().out
    areas = _areas(out)
    assert len(areas) == 26 and areas["base"] == pytest.approx(13400, rel=0.01)
    assert areas["torso_top"] == pytest.approx(727, rel=0.03)
    assert sum(areas.values()) == pytest.approx(30524, rel=0.01)
    assert "96 links: 18 with a surface, 78 skipped" in out
    assert "a frame without geometry (dummy, camera or tip frame) (61):" in out
    assert "excluded (robot.exclude) (9):" in out
    assert png.read_bytes()[:8] == PNG_MAGIC


def test_validate_names_the_closest_link_of_the_urdf(capsys):
    assert sphri_main(["validate", "robot=reachy2", "robot.links=[l_elbw_arm_link]"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "robot.links: 'l_elbw_arm_link' (did you mean l_elbow_arm_link?) is not a link of" in err[0]
    assert sphri_main(["validate", "robot=reachy2", "robot.exclude=[lidr_link]"]) == 2
    assert "did you mean lidar_link?" in capsys.readouterr().err


def test_run_time_error_names_the_closest_link(small):
    urdf, _ = small
    with pytest.raises(ConfigError, match=r"robot.links: 'arn' \(did you mean arm\?\) is not a link of .*small.urdf"):
        UrdfRobot(path=str(urdf), links=["arn"], regions={"a": "arn"}).build()
    cfg = compose(["robot=urdf", f"robot.path={urdf}", "robot.links=[bse]", "robot.regions={arm: bse}"])
    from sphri.config import check_inputs

    with pytest.raises(ConfigError, match=r"did you mean base\?"):
        check_inputs(cfg)
