"""python -m sphri.cli: list components, validate configs without running."""

from __future__ import annotations

from sphri.cli import components, main


def test_list_robot_shows_builtins(capsys):
    assert main(["list", "robot"]) == 0
    out = capsys.readouterr().out
    for name in ("reachy", "nao_child", "service_bot", "mesh", "reachy_vr", "urdf"):
        assert f"  {name} " in out


def test_every_component_has_a_sentence_description():
    """Every file of every group says what it is in words (not its class path), whole sentences."""
    from sphri.config import DEFAULT_GROUPS

    for group in DEFAULT_GROUPS:
        for name, desc in components(group):
            assert desc and not desc.startswith("sphri."), f"conf/{group}/{name}.yaml has no comment describing it"
            assert desc[-1] not in ":,;(", f"conf/{group}/{name}.yaml: description cut mid-sentence: {desc!r}"


def test_help_lists_groups_not_schemas_or_the_config(capsys):
    import re
    import sys

    from sphri import __main__ as entry
    from sphri.config import CONF_DIR, DEFAULT_GROUPS

    argv = sys.argv
    sys.argv = ["sphri", "--help"]
    try:
        entry.main()
    finally:
        sys.argv = argv
    out = capsys.readouterr().out
    for group in DEFAULT_GROUPS:
        assert f"  {group}:" in out
        for path in (CONF_DIR / group).glob("*.yaml"):
            assert re.search(rf"[ *]{path.stem} ", out), f"{group}={path.stem} missing from --help"
    assert "_schema" not in out
    assert "quest_capsules" in out and "capsules:" not in out  # options listed, the composed config is not
    assert len(out.splitlines()) < 200


def test_validate_ok_and_error(capsys):
    assert main(["validate", "+robot=reachy", "encoder.res=18"]) == 0
    out = capsys.readouterr().out
    assert "config OK" in out and "res=18" in out
    assert main(["validate", "noise.p=1.5"]) == 2
    assert "noise.p" in capsys.readouterr().err


def test_unknown_group():
    assert main(["list", "nope"]) == 2


def test_validate_checks_every_job_of_a_sweep_and_runs_none(tmp_path, capsys, monkeypatch):
    from sphri.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["validate", "-m", "+debug=fast", "encoder.res=0,4,abc"]) == 2
    err = capsys.readouterr().err
    assert "2 of 3 points fail validation" in err and "encoder.res=0" in err and "encoder.res=abc" in err
    assert main(["validate", "+debug=fast", "encoder.res=range(2,5)"]) == 0  # sweep syntax without -m
    assert "all 3 jobs compose and validate" in capsys.readouterr().out
    assert main(["validate", "+experiment=resolution_sweep"]) == 0
    assert "all 100 jobs compose and validate" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []  # nothing ran, nothing was written
