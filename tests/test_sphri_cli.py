"""python -m sphri.cli: list components, validate configs without running."""

from __future__ import annotations

from sphri.cli import components, main


def test_list_robot_shows_builtins(capsys):
    assert main(["list", "robot"]) == 0
    out = capsys.readouterr().out
    for name in ("reachy", "nao_child", "service_bot", "mesh", "reachy_vr", "urdf"):
        assert f"  {name} " in out


def test_every_component_has_a_description():
    for group in ("encoder", "model", "layout", "noise"):
        for name, desc in components(group):
            assert desc, f"conf/{group}/{name}.yaml has neither a comment line nor a _target_"


def test_validate_ok_and_error(capsys):
    assert main(["validate", "+robot=reachy", "encoder.res=18"]) == 0
    out = capsys.readouterr().out
    assert "config OK" in out and "res=18" in out
    assert main(["validate", "noise.p=1.5"]) == 2
    assert "noise.p" in capsys.readouterr().err


def test_unknown_group():
    assert main(["list", "nope"]) == 2
