"""sphri list|show|validate|warmup: list components, show and validate configs without running."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import forked_cli
import pytest
from time_limit import time_limit

from sphri.cli import components
from sphri.command import main


def test_list_robot_shows_builtins(capsys):
    assert main(["list", "robot"]) == 0
    out = capsys.readouterr().out
    for name in ("reachy", "reachy2", "reachy_full", "nao_child", "service_bot", "mesh", "reachy_vr", "urdf"):
        assert f"  {name} " in out
    assert main(["list", "robt"]) == 2  # a group's name is checked by the parser, with the close match
    assert "unknown group 'robt' (did you mean robot?)" in capsys.readouterr().err


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
        assert re.search(rf"^  {group} ", out, re.M), group
        for path in (CONF_DIR / group).glob("*.yaml"):
            assert re.search(rf"[ *]{path.stem}(\s|$)", out, re.M), f"{group}={path.stem} missing from --help"
    assert "_schema" not in out
    assert "quest_capsules" in out and "capsules:" not in out  # options listed, the composed config is not
    assert len(out.splitlines()) <= 50 and max(map(len, out.splitlines())) <= 100  # one screen


def test_validate_ok_and_error(capsys):
    assert main(["validate", "+robot=reachy", "layout.res=18"]) == 0
    out = capsys.readouterr().out
    assert "config OK" in out and "res=18" in out
    assert main(["validate", "noise.p=1.5"]) == 2
    assert "noise.p" in capsys.readouterr().err


def test_unknown_group():
    assert main(["list", "nope"]) == 2


def test_validate_checks_every_job_of_a_sweep_and_runs_none(tmp_path):
    import os

    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")]),
    }

    def validate(*args):
        return forked_cli.run(["-m", "sphri", "validate", *args], tmp_path, env, 300)

    bad = validate("-m", "+debug=fast", "layout.res=0,4,abc")
    assert bad.returncode == 2
    assert (
        "2 of 3 points fail validation" in bad.stderr
        and "layout.res=0" in bad.stderr
        and "layout.res=abc" in bad.stderr
    )
    ok = validate("+debug=fast", "layout.res=range(2,5)")  # sweep syntax without -m
    assert ok.returncode == 0 and "all 3 jobs compose and validate" in ok.stdout
    # an experiment's own sweep, through the sweeper, narrowed on the command line to its end resolutions
    # (every job of every experiment composes in tests/test_experiments.py, in-process and faster)
    exp = validate("+experiment=resolution_sweep", "layout.res=1,50")
    assert exp.returncode == 0 and "all 4 jobs compose and validate" in exp.stdout
    assert "model=cnn_gru layout.res=50 experiment=resolution_sweep" in exp.stdout
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
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")]),
    }
    run = subprocess.run(
        [sys.executable, "-m", "sphri", "-m", "layout=grid,hexx"], capture_output=True, text=True, env=env, timeout=120
    )
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        "sphri: invalid config: layout=hexx is invalid: no such layout option; options: density, file, grid, hex, "
        "random (did you mean hex?)"
    ]


def test_tab_completion_offers_components_not_schemas():
    import os
    import subprocess
    import sys

    env = {
        **os.environ,
        "COMP_LINE": "sphri encoder=",
        "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")]),
    }
    run = subprocess.run(
        [sys.executable, "-m", "sphri", "-sc", "query=bash"], capture_output=True, text=True, env=env, timeout=120
    )
    assert run.stdout.split() == ["encoder=coverage", "encoder=ellipse", "encoder=proximity"], run.stdout + run.stderr


def _complete(line: str, cache: Path) -> str:
    """The console script's answer to a TAB (``sphri.completion.main``, as ``sphri`` runs it)."""
    import os
    import subprocess
    import sys

    env = {
        **os.environ,
        "COMP_LINE": line,
        "XDG_CACHE_HOME": str(cache),
        "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")]),
    }
    probe = "import sys; sys.argv = ['sphri', '-sc', 'query=bash']; from sphri.completion import main; main()"
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout


def test_console_completion_answers_from_its_cache_what_hydra_answers(tmp_path: Path):
    """Issue 28: each TAB composed the whole config (1.4 s); the console script keeps Hydra's answer per
    context. The kept answer is Hydra's (a stem asked once serves every longer word), the internal
    ``debug_model`` group is not offered, and a path value is completed by Hydra, never kept."""
    from sphri import completion

    first = _complete("sphri model=cnn_gru model.", tmp_path)
    assert "model.hidden=" in first.split() and "model.lr=" in first.split()
    kept = list((tmp_path / "sphri" / "completion").iterdir())
    assert len(kept) == 1 and kept[0].read_text() == first
    kept[0].write_text("model.from_the_cache=")  # the next TAB in this context reads the cache, not Hydra
    assert _complete("sphri model=cnn_gru model.hi", tmp_path).split() == ["model.from_the_cache="]
    groups = _complete("sphri +de", tmp_path).split()
    assert "+debug=" in groups and "+debug_model=" not in groups
    (tmp_path / "data").mkdir()
    assert completion.is_path_word("sphri data.root=./da") and not completion.is_path_word("sphri data=syn")
    assert completion.split_line("sphri -m +robot=rea") == ("sphri -m ", "+robot=")
    assert completion.split_line("sphri hydra/la") == ("sphri ", "hydra/")


def test_console_completion_starts_afresh_when_a_config_file_changes():
    from sphri import completion

    before = completion.fingerprint()
    conf = completion._conf_dirs()[0] / "config.yaml"
    st = conf.stat()
    try:
        os.utime(conf, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
        assert completion.fingerprint() != before
    finally:
        os.utime(conf, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert completion.fingerprint() == before


def _within(seconds: int):
    """A harness time limit (SIGALRM), not a speed assertion: a hang fails the test instead of the suite."""
    return time_limit(seconds, "the call")


def test_show_returns_for_every_option_of_every_group_in_100_columns(capsys):
    """`cli show` with no arguments and `show GROUP=OPTION ...` with every option return, every line fits
    100 columns (the hand's 19 capsules used to print 2,700-character lines, and a head wider than
    the width made textwrap loop forever), and a config that does not run as it stands is still shown,
    with a note saying why."""
    from sphri.config import DEFAULT_GROUPS

    # every option of every group, one option of each group per call (a composition each: 0.4-0.8 s);
    # experiments and sensitivity presets set other groups' keys, so they share calls only with each
    # other (beside a filter or noise choice they often do not compose, and each option then goes alone)
    options = {
        group: [f"{'+' if group == 'robot' else ''}{group}={n}" for n, _ in components(group)]
        for group in DEFAULT_GROUPS
    }
    presets = {group: options.pop(group) for group in ("experiment", "sensitivity")}

    def rows(opts: dict[str, list[str]]) -> list[list[str]]:
        return [[names[i] for names in opts.values() if i < len(names)] for i in range(max(map(len, opts.values())))]

    calls = [[], *rows(options), *rows(presets)]
    assert sum(map(len, calls)) == sum(map(len, [*options.values(), *presets.values()]))
    while calls:
        args = calls.pop(0)
        with _within(60):
            code = main(["show", *args])
        out = capsys.readouterr().out
        if code != 0 and len(args) > 1:  # options of two groups that do not compose together: each alone
            calls[:0] = [[one] for one in args]
            continue
        assert code == 0, args
        assert out.strip(), args
        wide = [line for line in out.splitlines() if len(line) > 100]
        assert not wide, (args, wide[:2])
    main(["show", "layout=random"])
    out = capsys.readouterr().out
    assert "layout: RandomLayout" in out and "note: this config does not run as it stands" in out


def test_show_takes_a_bare_group_name_as_that_group(capsys):
    """`sphri show tracking` is `sphri show group=tracking` (Hydra's parser used to reject the bare word:
    "missing EQUAL"), beside overrides too."""
    from sphri.command import main as sphri

    assert sphri(["show", "group=tracking"]) == 0
    by_key = capsys.readouterr().out
    assert by_key.startswith("tracking: ") and "\nencoder: " not in by_key
    assert sphri(["show", "tracking"]) == 0
    assert capsys.readouterr().out == by_key
    assert sphri(["show", "encoder", "noise", "encoder=coverage"]) == 0
    out = capsys.readouterr().out
    assert [line.split(":")[0] for line in out.splitlines() if not line.startswith(" ")] == ["encoder", "noise"]
    assert out.startswith("encoder: CoverageEncoder")


@pytest.mark.parametrize(
    ("word", "hint"), [("trackng", " (did you mean tracking?)"), ("encodr", " (did you mean encoder?)"), ("xyz", "")]
)
def test_show_a_bare_word_that_names_no_group_is_one_line_with_the_close_groups(word, hint, capsys):
    from sphri.command import main as sphri
    from sphri.stages import STAGE_GROUPS

    assert sphri(["show", word]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.splitlines() == [
        f"sphri show: unknown group {word!r}{hint}; group is one of: {', '.join(STAGE_GROUPS)}"
    ]


def test_row_never_hangs_on_a_head_wider_than_the_width():
    from sphri.cli import _row

    with _within(10):
        text = _row("x" * 120, "  starts with spaces and is long enough to wrap " * 3)
    assert text.startswith("x" * 120) and all(len(line) <= 100 for line in text.splitlines()[1:])


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    import os

    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}  # as a user runs it: not verbose
    return forked_cli.run(["-m", "sphri", *args], cwd, env, 600)


def test_an_unknown_key_or_a_wrong_type_is_one_line_with_or_without_plus(tmp_path):
    """Hydra's own message was six lines with a wrong hint ("use +model.lr=0.1", which fails too)."""
    for args, want in (
        (["model.lr=0.1"], "model.lr is not a known key"),
        (["+model.lr=0.1"], "model.lr is not a known key"),
        (["model.n_estimator=5"], "(did you mean n_estimators?)"),
        (["layout.res=abc"], "layout.res is invalid"),
    ):
        proc = _run([*args, "+debug=fast", f"output_dir={tmp_path}"], tmp_path)
        assert proc.returncode == 2, (args, proc.stderr)
        lines = (proc.stdout + proc.stderr).strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("sphri: invalid config: ") and want in lines[0], (args, lines)
        assert "HYDRA_FULL_ERROR" not in proc.stderr and "+model.lr" not in proc.stderr
    assert not (tmp_path / "mlflow.db").exists()


def test_a_missing_input_path_fails_validation_and_starts_nothing(tmp_path):
    proc = _run(["validate", "data=vr_gesture", f"data.root={tmp_path / 'nope'}"], tmp_path)
    assert proc.returncode == 2 and "data.root=" in proc.stderr and "no such folder" in proc.stderr
    proc = _run(["data=vr_gesture", f"data.root={tmp_path / 'nope'}", f"output_dir={tmp_path / 'out'}"], tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("no such folder") == 1, proc.stderr  # said once
    assert not (tmp_path / "out" / "mlflow.db").exists()  # no FAILED run left behind
    proc = _run(["validate", "-m", "data=vr_gesture", f"data.root={tmp_path / 'nope'},{tmp_path}"], tmp_path)
    assert proc.returncode == 2 and "1 of 2 points fail validation" in proc.stderr


def test_a_failing_job_in_a_sweep_is_one_line_with_its_log_and_the_console_is_quiet(tmp_path, failing_mesh_sweep):
    proc = _run([*failing_mesh_sweep, f"output_dir={tmp_path / 'out'}", "tracking.enabled=false"], tmp_path)
    assert proc.returncode == 1
    console = proc.stdout + proc.stderr
    assert "Traceback" not in console and "stage noise" not in console, console[-3000:]
    (failed,) = [ln for ln in console.splitlines() if "FAILED:" in ln and "log: " in ln]
    log_file = Path(failed.rsplit("log: ", 1)[1].strip())
    text = log_file.read_text()
    assert "Traceback" in text and "stage " in text  # the job's log file keeps the stages and the traceback


def test_warmup_reports_what_it_compiled_and_fails_in_one_line(monkeypatch: pytest.MonkeyPatch, capsys):
    import subprocess

    from sphri import cli

    calls = []

    def fake(cmd, **kwargs):
        calls.append(cmd)
        out = "[..][sphri.pipeline][INFO] - compiled 8 numba kernels in 31.6 s (once: later runs load them)\n"
        return subprocess.CompletedProcess(cmd, 0, stdout=out, stderr="")

    monkeypatch.setattr(subprocess, "run", fake)
    assert main(["warmup"]) == 0
    assert len(calls) == 3  # two lanes side by side: the order between them is not fixed
    (chain,) = [c for c in calls if "+debug=fast" in c and "-m" not in c[3:]]
    assert "tracking.enabled=false" in chain
    # the components the debug chain does not use, in one serial sweep; and the study's analysis kernels
    (sweep,) = [c for c in calls if "-m" in c[3:]]
    assert "hydra/launcher=serial" in sweep and set(cli.WARMUP_SWEEP) <= set(sweep)
    assert [c for c in calls if "warm_analysis_kernels()" in c[-1]]
    assert "compiled 8 numba kernels in 31.6 s" in capsys.readouterr().out
    # the chain comes before the analysis kernels in its lane; the sweep has a lane of its own
    lanes = cli.warmup_lanes("/tmp/x")
    assert [len(lane) for lane in lanes] == [2, 1] and "warm_analysis_kernels()" in lanes[0][1][-1]

    monkeypatch.setattr(
        subprocess,
        "run",
        lambda cmd, **kw: subprocess.CompletedProcess(cmd, 1, stdout="", stderr="Traceback ...\nValueError: boom\n"),
    )
    assert main(["warmup"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sphri: warmup failed") and "ValueError: boom" in err[0]


def test_warmup_runs_its_two_lanes_side_by_side(monkeypatch: pytest.MonkeyPatch):
    """The first command of each lane waits (10 s at most) until the other lane's first command has
    started: run one after the other, the barrier breaks and warmup fails."""
    import subprocess
    import threading

    from sphri import cli

    barrier = threading.Barrier(2, timeout=10)
    firsts = tuple(lane[0][-1].split("=")[0] + "=" for lane in cli.warmup_lanes("TMP"))
    assert firsts == ("hydra.run.dir=", "hydra.sweep.dir=")

    def fake(cmd, **kwargs):
        if cmd[-1].startswith(firsts):
            barrier.wait()
        return subprocess.CompletedProcess(cmd, 0, stdout="", stderr="")

    monkeypatch.setattr(subprocess, "run", fake)
    assert main(["warmup"]) == 0


def test_the_analysis_kernels_warm_on_tiny_inputs():
    """What `sphri warmup` runs last, for real: every scenario-study kernel is called and returns."""
    from sphri.cli import warm_analysis_kernels

    warm_analysis_kernels()
