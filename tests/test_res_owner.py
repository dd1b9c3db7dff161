"""``layout.res`` has one owner: the layout group's base schema declares it and its check, every layout is
given it, the chain reads it through ``sphri.layout.schema.layout_res``; ``encoder.res`` is read as
``layout.res`` for one release, saying so once per process, in a run, a sweep and a sweeper's params."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

import sphri.config
from sphri.config import ConfigError, build, compose, normalize_overrides
from sphri.layout.schema import DEFAULT_RES, check_res, layout_res

ROOT = Path(__file__).resolve().parents[1]
SPHRI = ROOT / "sphri"


def test_only_the_owner_reads_cfg_layout_res():
    readers = [
        f"{p.relative_to(SPHRI.parent)}:{i}"
        for p in sorted(SPHRI.rglob("*.py"))
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if re.search(r"cfg\.(layout|encoder)\.res\b", line)
    ]
    assert not readers, readers  # layout_res reads the node it is given


@pytest.mark.parametrize("layout", ["grid", "hex", "random", "file"])
def test_every_layout_has_res_and_no_encoder_does(layout):
    cfg = compose([f"layout={layout}", "layout.res=7", "encoder=coverage"], check=False)
    assert layout_res(cfg) == 7 and cfg.layout.res == 7 and "res" not in cfg.encoder
    if layout != "file":  # a file layout needs its file to be built
        assert build(cfg.layout).res == 7
    for encoder in ("ellipse", "coverage", "proximity"):
        assert "res" not in compose([f"encoder={encoder}"], check=False).encoder


def test_the_one_check_names_layout_res_and_who_read_it():
    with pytest.raises(ConfigError, match=r"^layout\.res=0 is invalid: must be an integer in \[1, 1000\]$"):
        compose(["layout.res=0"])
    with pytest.raises(ConfigError, match=r"layout\.res=2\.5 is invalid: must be an integer.*\(read by layout\.grid\)"):
        check_res(2.5, "layout.grid")
    assert check_res(18.0) == 18


def test_a_plugin_layout_without_a_schema_gets_the_default_resolution():
    cfg = compose([])
    OmegaConf.set_struct(cfg, False)
    cfg.layout = OmegaConf.create({"_target_": "labext.skin.VertexLayout"})
    assert layout_res(cfg) == DEFAULT_RES


@pytest.fixture
def fresh_alias(monkeypatch):
    """A process that has not yet said the deprecation line."""
    monkeypatch.setattr(sphri.config, "_renamed_said", set())


def test_encoder_res_is_layout_res_and_says_so_once(fresh_alias, capsys):
    from sphri.pipeline import config_hash, make_pipeline, open_cache

    assert normalize_overrides(["+robot=reachy", "encoder.res=18", "-m"]) == ["robot=reachy", "layout.res=18", "-m"]
    assert normalize_overrides(["encoder.res=1,2", "++encoder.res=3", "~encoder.res", "encoder.resx=1"]) == [
        "layout.res=1,2",
        "++layout.res=3",
        "~layout.res",
        "encoder.resx=1",
    ]
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "sphri: encoder.res is deprecated, write layout.res (encoder.res is read as layout.res for one release)"
    ]
    old, new = compose(["+robot=reachy", "encoder.res=18"]), compose(["+robot=reachy", "layout.res=18"])
    assert capsys.readouterr().err == ""  # once per process
    assert old == new and config_hash(old) == config_hash(new)
    keys = [make_pipeline(c, open_cache(c)).key(stage) for c in (old, new) for stage in ("layout", "encode")]
    assert keys[:2] == keys[2:]
    assert make_pipeline(compose(["+robot=reachy", "layout.res=17"]), open_cache(old)).key("layout") != keys[0]


def test_the_command_line_says_the_deprecation_once():
    """``python -m sphri ... encoder.res=...`` (here ``sphri validate``, which composes like a run) prints the
    line once and runs the job of ``layout.res``."""
    code = "import sys; from sphri.command import main; sys.exit(main(['validate', '-m', '+debug=fast', 'encoder.res=2,3']))"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stderr.count("encoder.res is deprecated, write layout.res") == 1, out.stderr[-2000:]
    assert "layout.res=2" in out.stdout + out.stderr and "layout.res=3" in out.stdout + out.stderr


def test_a_sweep_of_the_old_key_sweeps_the_layout(tmp_path):
    """``-m encoder.res=1,2``: two jobs, at ``layout.res`` 1 and 2 (the sweeper reads the rewritten overrides),
    and the line once."""
    import forked_cli

    out = tmp_path / "out"
    args = ["-m", "sphri", "-m", "+debug=fast", "encoder.res=1,2", f"output_dir={out}", "hydra/launcher=serial"]
    proc = forked_cli.run(args, tmp_path, {**os.environ, "PYTHONUNBUFFERED": "1"}, 600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stderr.count("encoder.res is deprecated") == 1, proc.stderr[-3000:]
    assert "2 of 2 jobs finished" in proc.stdout, proc.stdout[-3000:]
    overrides = sorted(p.read_text() for p in (out / "multirun").glob("*/*/*/.hydra/overrides.yaml"))
    assert len(overrides) == 2 and "layout.res=1" in overrides[0] and "layout.res=2" in overrides[1], overrides


def test_a_report_reads_the_resolution_under_either_name():
    from sphri.report.grouping import res_param, varying_params

    assert res_param({"layout.res": "4"}) == "4" and res_param({"encoder.res": "5"}) == "5"
    assert res_param({}, "?") == "?"
    runs = [{"encoder.res": "4", "model": "rf"}, {"layout.res": "6", "model": "rf"}]
    assert varying_params(runs) == []


def test_show_of_the_old_key_shows_its_group_and_the_owners(fresh_alias, capsys):
    """``sphri show encoder.res=7``: the encoder group, and the layout group that holds the value."""
    from sphri.command import main

    assert main(["show", "encoder.res=7"]) == 0
    out = capsys.readouterr()
    groups = [line.split(":")[0] for line in out.out.splitlines() if line and not line.startswith(" ")]
    assert {"encoder", "layout"} <= set(groups), out.out
    assert re.search(r"^  res +7 ", out.out, re.M) and "[changed; default 18]" in out.out, out.out
    assert "encoder.res is deprecated, write layout.res" in out.err
