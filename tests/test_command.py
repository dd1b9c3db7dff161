"""``sphri <verb>`` (issue 30, point 6): one dispatcher, one ``key=value`` parser; one spelling per verb (issue 53)."""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
from pathlib import Path
from typing import Literal

import forked_cli
import pytest

import sphri.command
from sphri.args import ArgsError, HelpRequested, arg, keys, parse
from sphri.command import BY_NAME, VERBS, main, parser
from sphri.config import setting
from sphri.hardware.settings import SkinLiveSettings

REPO = Path(__file__).resolve().parents[1]


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])
    return {**env, **extra}


def _python(args: list[str], cwd: Path, timeout: int = 300, **env: str) -> subprocess.CompletedProcess:
    return forked_cli.run(args, cwd, _env(**env), timeout)  # `-c` code: a fresh interpreter


# --------------------------------------------------------------------------- the parser, on a schema of every type
def _even(n: int) -> str | None:
    return None if n % 2 == 0 else "must be even"


@dataclasses.dataclass
class Toy:
    source: str = arg(positional=True, metavar="SOURCE", help="where from")
    extra: list[str] = arg([], positional=True, help="more words")
    n: int = arg(2, check=_even, help="an even count")
    rate: float = arg(0.5, help="a rate")
    log: bool = arg(True, flags={"--no-log": "false"}, help="log it")
    mode: Literal["fast", "slow"] = arg("fast", help="how")
    names: list[str] = arg(["a", "b"], help="names")
    out: Path | None = arg(None, help="where to")
    limit: int | None = arg(None, help="a limit")
    output_dir: str = arg("outputs", help="a key with an underscore")


@dataclasses.dataclass
class Composes:
    out: str = arg(metavar="DIR", help="the folder")
    overrides: list[str] = arg([], rest=True, help="config overrides")


def test_every_spelling_of_a_key_gives_the_same_typed_value():
    kv = parse(Toy, ["src", "n=4", "rate=0.25", "log=false", "mode=slow", "names=x,y", "out=o", "limit=3"])
    flags = parse(
        Toy,
        ["src", "--n", "4", "--rate=0.25", "--no-log", "--mode", "slow", "--names", "x,y", "--out", "o", "--limit=3"],
    )
    assert kv == flags
    assert kv.n == 4 and kv.rate == 0.25 and kv.log is False and kv.mode == "slow"
    assert kv.names == ["x", "y"] and kv.out == Path("o") and kv.limit == 3
    assert (
        parse(Toy, ["src", "--output-dir", "d"]).output_dir == "d" == parse(Toy, ["src", "--output_dir=d"]).output_dir
    )
    assert parse(Toy, ["src", "--log"]).log is True  # a bool flag alone is true
    assert parse(Toy, ["src", "limit=none"]).limit is None
    assert parse(Toy, ["src", "names=x", "names=y"]).names == ["x", "y"]  # a repeated list key adds
    assert parse(Toy, ["src", "n=4", "n=6"]).n == 6  # a repeated key: the last wins, as in Hydra
    words = parse(Toy, ["src", "w1", "w2", "n=8"])
    assert words.source == "src" and words.extra == ["w1", "w2"] and words.n == 8
    # defaults come from the dataclass, unchanged
    d = parse(Toy, ["src"])
    assert (d.n, d.rate, d.log, d.mode, d.names, d.out, d.limit) == (2, 0.5, True, "fast", ["a", "b"], None, None)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["src", "n=abc"], "n=abc is invalid: must be an integer"),
        (["src", "n=3"], "n=3 is invalid: must be even"),
        (["src", "rate=fast"], "rate=fast is invalid: must be a number"),
        (["src", "rate=nan"], "rate=nan is invalid: must be a number"),
        (["src", "log=maybe"], "log=maybe is invalid: must be true or false"),
        (["src", "mode=slwo"], "mode=slwo is invalid: must be one of fast, slow (did you mean slow?)"),
        (["src", "limit=many"], "limit=many is invalid: must be an integer"),
        (["src", "--n"], "--n needs a value (an even count)"),
        (["src", "nn=4"], "unknown argument 'nn' (did you mean n?); keys: source, extra, n, rate"),
        (["src", "--ratee", "1"], "unknown argument '--ratee' (did you mean rate?)"),
        ([], "missing SOURCE (where from); usage: toy SOURCE [EXTRA ...] [key=value ...]"),
    ],
)
def test_a_bad_argument_is_one_line_naming_the_key_and_what_it_allows(argv, message):
    with pytest.raises(ArgsError) as err:
        parse(Toy, argv, prog="toy")
    text = str(err.value)
    assert message in text and "\n" not in text


def test_a_command_that_composes_a_config_passes_its_overrides_on():
    a = parse(Composes, ["out=d", "data.participants=2", "+debug=fast", "-m", "robot.links={l_arm: arm.obj}"])
    assert a.out == "d" and a.overrides == ["data.participants=2", "+debug=fast", "-m", "robot.links={l_arm: arm.obj}"]
    with pytest.raises(ArgsError, match="missing out=DIR"):
        parse(Composes, ["data.participants=2"])


def test_help_lists_every_key_with_its_type_default_and_meaning():
    with pytest.raises(HelpRequested) as h:
        parse(Toy, ["--help"], prog="toy", summary="A toy.")
    text = str(h.value)
    assert text.startswith("usage: toy SOURCE [EXTRA ...] [key=value ...]\n\nA toy.")
    for line in ("n=INT", "an even count (default 2)", "mode=fast|slow", "--no-log for log=false", "names=TEXT,..."):
        assert line in text, line
    assert max(map(len, text.splitlines())) <= 100
    assert [k.name for k in keys(Composes)] == ["out", "overrides"]


# --------------------------------------------------------------------------- the dispatcher
def test_every_verb_is_listed_with_one_line_and_loads_its_command():
    text = parser().format_help()
    for v in VERBS:
        assert f"  {v.name} " in text, v.name
        assert v.summary and "\n" not in v.summary
        if v.kind in ("args", "main", "hydra"):
            assert callable(v.load(v.target)), v.name
        if v.kind == "args":
            assert dataclasses.is_dataclass(v.load(v.schema)), v.name
    for name in ("run", "sweep", "report", "coverage", "list", "show", "validate", "cache", "store", "skin", "glove"):
        assert name in BY_NAME
    for name in ("simulate", "export", "synthesize", "stats", "warmup", "help"):
        assert name in BY_NAME


def test_help_and_unknown_verbs(capsys):
    for spelling in (["help"], ["--help"], ["-h"]):
        assert main(spelling) == 0
        assert "verbs:" in capsys.readouterr().out
    assert main(["repot", "DIR"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sphri: unknown verb 'repot' (did you mean report")
    assert "verbs: run, sweep, report" in err[0]
    assert main(["validat"]) == 2 and "(did you mean validate" in capsys.readouterr().err
    assert main(["help", "warmpu"]) == 2  # a verb's help asked for by a wrong name: the same line, not the list
    out, err = capsys.readouterr()
    assert not out and err.startswith("sphri: unknown verb 'warmpu' (did you mean warmup") and err.count("\n") == 1


@pytest.mark.parametrize(
    "argv, verb, rest",
    [
        ([], "run", []),  # no verb is a job
        (["+debug=fast", "layout.res=6"], "run", ["+debug=fast", "layout.res=6"]),  # an override: `run`
        (["-m", "layout.res=2,4"], "run", ["-m", "layout.res=2,4"]),
        (["--cfg", "job"], "run", ["--cfg", "job"]),
        (["sweep", "layout.res=2,4"], "sweep", ["layout.res=2,4"]),
        (["--help"], "help", []),
        (["help", "list"], "help", ["list"]),
        (["list", "--groups", "-h", "--", "x"], "list", ["--groups", "-h", "--", "x"]),  # unchanged to the verb
        (["report", "DIR", "--n-boot", "-1", "--no-log"], "report", ["DIR", "--n-boot", "-1", "--no-log"]),
    ],
)
def test_argparse_picks_the_verb_and_the_verb_gets_the_rest_unchanged(argv, verb, rest, monkeypatch):
    called = []
    monkeypatch.setattr(sphri.command, "call", lambda v, args: called.append((v.name, args)) or 0)
    assert main(argv) == 0 and called == [(verb, rest)]


def test_each_verb_answers_help_through_the_dispatcher(capsys):
    """Every verb's arguments from ``sphri VERB --help``, through the one parser (the hardware verbs: each
    command's settings with their help lines)."""
    for v in VERBS:
        if v.kind in ("hydra", "help"):
            continue
        assert main([v.name, "--help"]) == 0, v.name
        out = capsys.readouterr().out
        assert out.startswith(f"usage: sphri {v.name}"), (v.name, out[:200])
    assert main(["help", "report"]) == 0 and "n_boot=INT" in capsys.readouterr().out
    assert main(["skin", "--help"]) == 0
    out = capsys.readouterr().out  # both commands, each setting with its docstring and default
    assert "usage: sphri skin record port=TEXT out=TEXT" in out and "usage: sphri skin live port=TEXT model=TEXT" in out
    assert "stride=INT                  Frames between sliding-window predictions" in out
    assert main(["simulate", "glove", "--help"]) == 0
    assert "ack_drop_rate=NUMBER" in capsys.readouterr().out


def test_cheap_verbs_run_for_real(tmp_path, capsys):
    assert main(["list", "robot"]) == 0
    assert "  reachy2 " in capsys.readouterr().out
    assert main(["show", "noise=crosstalk", "noise.alpha=0.3"]) == 0
    assert "[changed; default 0.1]" in capsys.readouterr().out
    assert main(["show", "--group", "nosuch"]) == 2
    assert main(["validate", "+robot=reachy", "layout.res=18"]) == 0
    assert "config OK" in capsys.readouterr().out
    assert main(["validate", "noise.p=1.5"]) == 2
    assert "noise.p" in capsys.readouterr().err
    (tmp_path / "cache" / "data").mkdir(parents=True)
    assert main(["cache", "info", f"dir={tmp_path / 'cache'}"]) == 0
    assert "data           0 entries" in capsys.readouterr().out
    db = tmp_path / "mlflow.db"
    db.write_text("not a database")
    assert main(["store", "check", str(db)]) == 1
    assert "is not an MLflow store (not a SQLite database" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, line",
    [
        (["cache", "infoo"], "sphri cache: action=infoo is invalid: must be one of info, clear (did you mean info?)"),
        (["cache", "info", "dir"], "sphri cache: no stage ['dir'] in outputs/cache"),
        (["cache", "clear", "older_than_days=soon"], "sphri cache: older_than_days=soon is invalid: must be a number"),
        (["report", "DIR", "n_boot=-1"], "sphri report: n_boot=-1 is invalid: must be >= 0"),
        (["report", "DIR", "--ci"], "sphri report: --ci needs a value (interval coverage)"),
        (["report"], "sphri report: missing SOURCE"),
        (["synthesize", "data.participants=2"], "sphri synthesize: missing out=DIR (the folder to write)"),
        (["synthesize", "out=d", "what=both"], "sphri synthesize: what=both is invalid: must be one of gestures"),
        (["stats", "cost_threshold=2"], "sphri stats: cost_threshold=2 is invalid: must be in (0, 1]"),
        (["store", "fix", "x.db"], "sphri store: action=fix is invalid: must be one of check, repair"),
        (["derive-reachy2", "src=x", "faces=0"], "sphri derive-reachy2: faces=0 is invalid: must be > 0"),
        (["list", "--groups"], "sphri list: --groups needs a value"),
        (["warmup", "now"], "sphri warmup: unexpected argument 'now'"),
        (["skin", "live", "port=p", "model=m", "stride=-1"], "sphri skin: stride=-1 is invalid: must be in [0, 10000]"),
        (["skin", "recrd"], "sphri skin: unknown command 'recrd' (did you mean record?); commands: record, live"),
        (["skin", "record", "port=p", "robot=reachy"], "sphri skin: unknown argument 'robot'"),
        (["glove", "replay", "--pulse-ms", "0"], "sphri glove: pulse_ms=0 is invalid: must be in [1, 65535]"),
        (["simulate", "skin", "corrupt_rate=x"], "sphri simulate: corrupt_rate=x is invalid: must be a number"),
        (["export", "+debug=fast"], "sphri export: missing out=TEXT (Model file to write"),
        (["export", "out=m", "mlflow=maybe"], "sphri export: mlflow=maybe is invalid: must be true or false"),
        (["coverage", "capture=0"], "sphri coverage: capture=0.0 is invalid: must be in (0, 1]"),
    ],
)
def test_a_wrong_type_or_a_missing_value_is_one_line_and_exit_2(argv, line, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "outputs" / "cache").mkdir(parents=True)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(line), err


# --------------------------------------------------------------------------- the console script, one spelling per verb
#: The modules that run under ``python -m``: the package (``python -m sphri VERB``) and two maintainer tools
#: that regenerate documentation (no verb: ``docs/development.md``).
MODULE_COMMANDS = {"sphri/__main__.py", "sphri/docs_gen.py", "sphri/data/recording_schema.py"}


def test_a_verb_has_one_spelling_no_module_is_a_command_of_its_own():
    """``sphri VERB`` (``python -m sphri VERB``) is a verb's one spelling (issue 53): no module of sphri but the
    package and the maintainer tools has a ``__main__`` block or is a package's ``__main__.py``."""
    package = REPO / "sphri"
    found = {
        p.relative_to(REPO).as_posix()
        for p in package.rglob("*.py")
        if p.name == "__main__.py" or re.search(r"^if __name__ == .__main__.:", p.read_text(), re.M)
    }
    assert found == MODULE_COMMANDS


def test_python_m_sphri_takes_a_verb_like_the_console_script(tmp_path):
    """``python -m sphri VERB`` is ``sphri VERB`` (an unknown verb too); overrides, ``run``, ``-m`` and Hydra's flags
    go to Hydra as before."""
    verb = _python(["-m", "sphri", "list", "noise"], tmp_path)
    assert verb.returncode == 0 and "  crosstalk " in verb.stdout
    unknown = _python(["-m", "sphri", "lists"], tmp_path)  # a word that is no verb nor override: as `sphri lists`
    assert unknown.returncode == 2 and unknown.stderr.startswith("sphri: unknown verb 'lists' (did you mean list")
    skin = _python(["-m", "sphri", "skin", "live", "port=p", "model=m", "stride=-1"], tmp_path)
    assert skin.returncode == 2 and skin.stderr.strip() == "sphri skin: stride=-1 is invalid: must be in [0, 10000]"
    for argv in (["+debug=fast", "layout.res=abc"], ["run", "+debug=fast", "layout.res=abc"]):
        bad = _python(["-m", "sphri", *argv, f"output_dir={tmp_path / 'o'}"], tmp_path)
        assert bad.returncode == 2 and bad.stderr.strip().startswith("sphri: invalid config: layout.res"), bad.stderr
    cfg = _python(["-m", "sphri", "--cfg", "job", "+debug=fast", "layout.res=6"], tmp_path)  # Hydra's own flag
    assert cfg.returncode == 0 and "res: 6" in cfg.stdout, cfg.stderr[-2000:]
    assert "`python -m sphri ...` is the same as `sphri ...`" in _python(["-m", "sphri", "--help"], tmp_path).stdout
    assert not (tmp_path / "o").exists()


def _console(args: list[str], cwd: Path, timeout: int = 600, **env: str) -> subprocess.CompletedProcess:
    """The ``sphri`` console script (``sphri.completion:main``, as pip's wrapper runs it)."""
    probe = "import sys; from sphri.completion import main; sys.argv[0] = 'sphri'; sys.exit(main())"
    return _python(["-c", probe, *args], cwd, timeout, **env)


def test_console_script_runs_a_job_with_or_without_the_run_verb(tmp_path):
    job = _console(["run", "+debug=fast", "tracking.enabled=false", f"output_dir={tmp_path / 'out'}"], tmp_path)
    assert job.returncode == 0, (job.stdout + job.stderr)[-3000:]
    assert "accuracy" in job.stdout
    bad = _console(["+debug=fast", "layout.res=abc", f"output_dir={tmp_path / 'o2'}"], tmp_path)
    assert bad.returncode == 2 and bad.stderr.strip().startswith("sphri: invalid config: layout.res"), bad.stderr
    sweep = _console(["sweep", "+debug=fast", "layout.res=0,4", f"output_dir={tmp_path / 'o3'}"], tmp_path)
    assert sweep.returncode == 2 and "layout.res=0" in sweep.stderr, sweep.stderr[-2000:]  # swept: -m was added
    assert not (tmp_path / "o3" / "mlflow.db").exists()
    verbs = _console(["help"], tmp_path)
    assert verbs.returncode == 0 and "  validate " in verbs.stdout


def test_the_console_script_imports_only_the_standard_library():
    """The first word of every TAB reads the verb table: ``sphri.completion`` and ``sphri.command`` (with its
    parser) must not pull in Hydra, numpy or yaml."""
    probe = (
        "import sys; import sphri.completion, sphri.command, sphri.args; "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'hydra', 'omegaconf', 'numpy', 'yaml', 'torch'}))"
    )
    out = _python(["-c", probe], REPO)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stdout + out.stderr


def _tab(line: str, cache: Path) -> list[str]:
    """What the console script's TAB query (``sphri -sc query=bash`` with ``COMP_LINE``) prints, its words
    (in a forked process: whether a cached answer imports anything heavy is checked in a fresh one below)."""
    probe = "import sys; from sphri.completion import main; sys.exit(main())"
    run = _python(["-c", probe, "-sc", "query=bash"], REPO, 300, COMP_LINE=line, XDG_CACHE_HOME=str(cache))
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout.split()


def test_tab_completes_verbs_first_then_what_each_verb_takes(tmp_path):
    first = _tab("sphri ", tmp_path)
    assert {v.name for v in VERBS} <= set(first) and "encoder=" in first  # a verb, or an override of `run`
    assert "+debug=" in _tab("sphri +de", tmp_path)
    assert _tab("sphri encoder=", tmp_path) == ["encoder=coverage", "encoder=ellipse", "encoder=proximity"]  # no verb
    report = _tab("sphri report DIR ", tmp_path)
    assert {"n_boot=", "marks=auto", "marks=false", "mlflow=", "formats="} <= set(report)
    assert "encoder=" not in report  # report takes no config overrides
    assert {"info", "clear", "dir="} <= set(_tab("sphri cache ", tmp_path))
    hydra = ["encoder=coverage", "encoder=ellipse", "encoder=proximity"]
    assert _tab("sphri run encoder=", tmp_path) == hydra
    assert set(hydra) <= set(_tab("sphri validate encoder=", tmp_path))  # validate takes overrides
    assert {"json=", "cost_threshold=", "encoder="} <= set(_tab("sphri stats ", tmp_path))
    assert "report" in _tab("sphri help ", tmp_path)
    # asked again, the verbs come from the cache: nothing heavy is imported
    probe = (
        "import sys; from sphri.completion import answer; words = answer('sphri '); "
        "print('report' in words.split(), 'hydra' in sys.modules)"
    )
    again = _python(["-c", probe], REPO, 300, XDG_CACHE_HOME=str(tmp_path))
    assert again.stdout.split() == ["True", "False"], again.stdout + again.stderr


def _offered(line: str) -> list[str]:
    """What TAB offers after ``line`` for a verb that needs no Hydra answer (computed here, no cache)."""
    from sphri.completion import _compute

    return _compute(line).split()


def _key_words(settings: type) -> list[str]:
    """``key=`` and ``key=choice`` of every key of ``settings``, as the parser reads them."""
    return [w for k in keys(settings) for w in (f"{k.name}=", *(f"{k.name}={c}" for c in k.choices()))]


def test_tab_completes_the_hardware_verbs_from_the_settings_their_parser_reads():
    """skin, glove, simulate and export read their settings through ``read_settings``: TAB offers the
    command word first, then the keys of that command's settings dataclass, choices included."""
    from sphri.hardware import glove, simulate, skin
    from sphri.hardware.settings import SkinRecordSettings

    assert _offered("sphri skin ") == ["record", "live"]
    live = _offered("sphri skin live ")
    assert live == _key_words(SkinLiveSettings) and {"model=", "stride=", "allow_remote=true"} <= set(live)
    assert _offered("sphri skin record port=/dev/ttyACM0 ") == _key_words(SkinRecordSettings)
    assert _offered("sphri skin recrod ") == []  # nothing fits after a wrong command word
    assert _offered("sphri glove ") == list(glove.COMMANDS) == ["replay"]
    assert _offered("sphri simulate ") == list(simulate.COMMANDS) == ["skin", "glove"]
    assert _offered("sphri simulate glove ") == _key_words(simulate.COMMANDS["glove"][0])
    assert {BY_NAME[v].load(BY_NAME[v].schema) is m.COMMANDS for v, m in [("skin", skin), ("glove", glove)]} == {True}


@dataclasses.dataclass
class LiveWithGain(SkinLiveSettings):
    gain: str = setting("low", choices=("low", "high"))
    """Amplifier gain of the skin."""


def test_a_setting_added_to_a_hardware_schema_is_parsed_helped_and_completed_with_no_other_edit(monkeypatch, capsys):
    from sphri.hardware import skin

    monkeypatch.setitem(skin.COMMANDS, "live", (LiveWithGain, False))
    assert {"gain=", "gain=low", "gain=high"} <= set(_offered("sphri skin live "))
    assert "gain=" not in _offered("sphri skin record ")
    assert main(["skin", "live", "--help"]) == 0
    assert "gain=low|high" in capsys.readouterr().out
    assert main(["skin", "live", "port=loop://", "model=m", "gain=mid"]) == 2
    assert "gain" in capsys.readouterr().err


def test_tab_completes_the_hardware_verbs_that_take_overrides_with_hydras_too(tmp_path):
    from sphri.export.train import TrainExportSettings
    from sphri.hardware.settings import GloveReplaySettings

    replay = _tab("sphri glove replay port=loop:// ", tmp_path)
    assert set(_key_words(GloveReplaySettings)) <= set(replay) and {"trigger=onset", "encoder="} <= set(replay)
    assert {"encoder=coverage", "encoder=ellipse"} <= set(_tab("sphri glove replay encoder=", tmp_path))
    export = _tab("sphri export ", tmp_path)
    assert set(_key_words(TrainExportSettings)) <= set(export) and {"out=", "model=", "encoder="} <= set(export)


def test_tab_offers_the_group_names_where_a_bare_word_is_a_group():
    """``sphri list``'s groups are declared with ``arg(choices=...)``: TAB offers them for every further word."""
    from sphri.config import DEFAULT_GROUPS

    for line in ("sphri list ", "sphri list robot "):
        offered = _offered(line)
        assert offered[: len(DEFAULT_GROUPS)] == list(DEFAULT_GROUPS) and "groups=encoder" in offered, line
