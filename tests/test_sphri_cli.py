"""python -m sphri.cli: list components, validate configs without running."""

from __future__ import annotations

from pathlib import Path

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


def test_validate_checks_every_job_of_a_sweep_and_runs_none(tmp_path):
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]),
                                                       os.environ.get("PYTHONPATH", "")])}

    def validate(*args):
        return subprocess.run([sys.executable, "-m", "sphri.cli", "validate", *args], capture_output=True, text=True,
                              cwd=tmp_path, env=env, timeout=300)

    bad = validate("-m", "+debug=fast", "encoder.res=0,4,abc")
    assert bad.returncode == 2
    assert "2 of 3 points fail validation" in bad.stderr and "encoder.res=0" in bad.stderr and "encoder.res=abc" in bad.stderr
    ok = validate("+debug=fast", "encoder.res=range(2,5)")  # sweep syntax without -m
    assert ok.returncode == 0 and "all 3 jobs compose and validate" in ok.stdout
    # an experiment's own sweep, through the sweeper, narrowed on the command line to its end resolutions
    # (every job of every experiment composes in tests/test_experiments.py, in-process and faster)
    exp = validate("+experiment=resolution_sweep", "encoder.res=1,50")
    assert exp.returncode == 0 and "all 4 jobs compose and validate" in exp.stdout
    assert "model=cnn_gru encoder.res=50 experiment=resolution_sweep" in exp.stdout
    assert list(tmp_path.iterdir()) == []  # nothing ran, nothing was written


def test_a_misspelt_component_lists_the_real_options_not_the_schemas():
    import os
    import subprocess
    import sys

    import pytest

    from sphri.config import ConfigError, compose

    with pytest.raises(ConfigError) as err:
        compose(["encoder=elipse"])
    msg = str(err.value)
    assert "encoder=elipse is invalid" in msg and "did you mean ellipse?" in msg and "_schema" not in msg
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]),
                                                       os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, "-m", "sphri", "-m", "layout=grid,hexx"], capture_output=True, text=True,
                         env=env, timeout=120)
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        "sphri: invalid config: layout=hexx is invalid: no such layout option; options: density, file, grid, hex, "
        "random (did you mean hex?)"]


def test_tab_completion_offers_components_not_schemas():
    import os
    import subprocess
    import sys

    env = {**os.environ, "COMP_LINE": "sphri encoder=",
           "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, "-m", "sphri", "-sc", "query=bash"], capture_output=True, text=True,
                         env=env, timeout=120)
    assert run.stdout.split() == ["encoder=coverage", "encoder=ellipse", "encoder=proximity"], run.stdout + run.stderr


def _within(seconds: int):
    """A harness time limit (SIGALRM), not a speed assertion: a hang fails the test instead of the suite."""
    import contextlib
    import signal

    @contextlib.contextmanager
    def limit():
        def fire(signum, frame):
            raise TimeoutError(f"did not return within {seconds} s")

        old = signal.signal(signal.SIGALRM, fire)
        signal.alarm(seconds)
        try:
            yield
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, old)

    return limit()


def test_show_returns_for_every_option_of_every_group_in_100_columns(capsys):
    """`cli show` with no arguments and `show GROUP=OPTION` for every option return, every line fits
    100 columns (the hand's 19 capsules used to print 2,700-character lines, and a head wider than
    the width made textwrap loop forever), and a config that does not run as it stands is still shown,
    with a note saying why."""
    from sphri.config import DEFAULT_GROUPS

    calls = [[]] + [
        [f"{'+' if group == 'robot' else ''}{group}={name}"]
        for group in DEFAULT_GROUPS
        for name, _ in components(group)
    ]
    for args in calls:
        with _within(60):
            assert main(["show", *args]) == 0, args
        out = capsys.readouterr().out
        assert out.strip(), args
        wide = [line for line in out.splitlines() if len(line) > 100]
        assert not wide, (args, wide[:2])
    main(["show", "layout=random"])
    out = capsys.readouterr().out
    assert "layout: RandomLayout" in out and "note: this config does not run as it stands" in out


def test_row_never_hangs_on_a_head_wider_than_the_width():
    from sphri.cli import _row

    with _within(10):
        text = _row("x" * 120, "  starts with spaces and is long enough to wrap " * 3)
    assert text.startswith("x" * 120) and all(len(line) <= 100 for line in text.splitlines()[1:])
