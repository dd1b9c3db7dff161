"""``sphri coverage``: argument split, settings checks, a run logged to MLflow."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from sphri import coverage as cli
from sphri.args import ArgsError
from sphri.config import ConfigError
from sphri.types import Robot


def test_split_args_routes_each_key():
    ov, settings, run = cli.split_args(
        ["+debug=fast", "data.regions=[torso]", "by=gesture", "out=/x", "coverage.bandwidth_mm=8", "--mlflow", "false"]
    )
    assert ov == ["+debug=fast", "data.regions=[torso]"]
    assert (settings.by, settings.bandwidth_mm) == ("gesture", 8.0)
    assert (run.out, run.mlflow) == ("/x", False)
    with pytest.raises(ArgsError, match="coverage.nope"):
        cli.split_args(["coverage.nope=1"])
    with pytest.raises(ArgsError, match="^mlflow=maybe is invalid: must be true or false$"):
        cli.split_args(["mlflow=maybe"])


@pytest.mark.parametrize(
    "arg,line",
    [
        ("bandwidth_mm=abc", "bandwidth_mm=abc is invalid: must be a number"),
        ("kernel=manhattan", "kernel='manhattan' is invalid: allowed values: "),
        ("capture=1.5", "capture=1.5 is invalid: must be in (0, 1]"),
        ("n_permutations=5", "n_permutations=5 is invalid: must be in [99, "),
        ("exact_max=25", "exact_max=25 is invalid: must be in [0, 20]"),
        ("formats=[png,jpg]", "coverage.formats=['png', 'jpg'] is invalid: must be one or more of png, pdf, svg"),
        ("formats=[]", "coverage.formats=[] is invalid: must be one or more of png, pdf, svg"),
    ],
)
def test_bad_settings_name_the_key(arg, line):
    with pytest.raises(ArgsError) as err:
        cli.load_settings([arg])
    assert str(err.value).startswith(line), str(err.value)


def test_settings_defaults_and_overrides():
    s = cli.load_settings(["by=scenario", "bandwidth_mm=8", "render=false"])
    assert s.by == "scenario" and s.bandwidth_mm == 8.0 and s.render is False and s.capture == 0.9


def test_main_reports_config_errors(capsys):
    assert cli.main(["kernel=manhattan"]) == 2
    assert capsys.readouterr().err.startswith("sphri coverage: kernel='manhattan' is invalid")
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "bandwidth_mm=NUMBER" in out and "mlflow=true|false" in out and "overrides" in out


class FakePipeline:
    def __init__(self, study, surface):
        self.values = {
            "data": study.dataset,
            "contact": study.contacts,
            "surface": surface,
            "robot": Robot("handmade", {"cyl": study.link}, {"arm": "cyl"}),
        }

    def get(self, name):
        return self.values[name]


def fake_cfg(tmp_path: Path):
    groups = {
        g: {"_target_": f"sphri.fake.{g}"}
        for g in ("robot", "contact", "surface", "layout", "encoder", "noise", "filter", "window", "model", "cv")
    }
    return OmegaConf.create(
        {
            "seed": 0,
            "output_dir": str(tmp_path),
            "cache": {"dir": str(tmp_path / "cache"), "enabled": False},
            "data": {"_target_": "sphri.fake.data", "regions": ["arm"]},
            "tracking": {
                "_target_": "sphri.tracking.mlflow_tracker.MlflowTracker",
                "enabled": True,
                "uri": None,
                "experiment": "sphri",
                "artifacts": True,
                "retries": 2,
            },
            **groups,
        }
    )


def test_run_writes_region_files_and_logs_an_mlflow_run(study, tmp_path, monkeypatch):
    from mlflow.tracking import MlflowClient

    from sphri.surface.cylinder import CylinderSurface
    from sphri.tracking.mlflow_tracker import default_uri

    surface = CylinderSurface().fit(study.link)
    seen = []

    def compose(overrides):
        seen.append(list(overrides))
        return fake_cfg(tmp_path)

    monkeypatch.setattr(cli, "compose", compose)
    monkeypatch.setattr("sphri.pipeline.make_pipeline", lambda cfg, cache: FakePipeline(study, surface))
    settings = cli.load_settings(["render=false", "n_projections=32", "heldout=false"])
    res = cli.run(["+debug=fast", "data.regions=[arm,torso]"], settings, tmp_path / "cov")
    assert seen[1] == ["+debug=fast", "data.regions=[arm]"]  # one composition per region
    assert (tmp_path / "cov" / "arm" / "density_all.npz").is_file()
    assert (tmp_path / "cov" / "arm" / "swd_pairs.csv").is_file()
    assert "poke: covering" in (tmp_path / "cov" / "recommendation.txt").read_text()
    assert json.loads((tmp_path / "cov" / "settings.json").read_text())["coverage"]["by"] == "gesture"
    client = MlflowClient(default_uri(tmp_path))
    run = client.get_run(res.mlflow_run_id)
    assert run.info.status == "FINISHED"
    assert run.data.tags["sphri.kind"] == "coverage"
    assert run.data.params["coverage.by"] == "gesture"
    assert 0 < run.data.metrics["arm/area_share_at_capture/poke"] < 0.05
    assert run.data.metrics["arm/n_significant_pairs"] == 3
    artifacts = {a.path for a in client.list_artifacts(res.mlflow_run_id, "arm")}
    assert "arm/density_poke.npz" in artifacts and "arm/summary.json" in artifacts


def test_formats_png_writes_each_figure_as_png_alone(study, tmp_path, monkeypatch):
    """``formats=png`` (a quick look): every figure of the run is a PNG, none a PDF or SVG; the default writes all three."""
    from sphri.surface.cylinder import CylinderSurface

    surface = CylinderSurface().fit(study.link)
    monkeypatch.setattr(cli, "compose", lambda overrides: fake_cfg(tmp_path))
    monkeypatch.setattr("sphri.pipeline.make_pipeline", lambda cfg, cache: FakePipeline(study, surface))
    assert cli.load_settings([]).formats == ["png", "pdf", "svg"]
    settings = cli.load_settings(["formats=png", "views=1", "n_projections=32", "heldout=false"])
    res = cli.run(["data.regions=[arm]"], settings, tmp_path / "cov", log_mlflow=False)
    suffixes = {p.suffix for p in res.files["arm"]}
    assert ".png" in suffixes and not suffixes & {".pdf", ".svg"}, sorted(suffixes)
    on_disk = {p.suffix for p in (tmp_path / "cov" / "arm").iterdir()}
    assert ".png" in on_disk and not on_disk & {".pdf", ".svg"}, sorted(on_disk)


@pytest.mark.parametrize(
    "arg,hint",
    [
        ("by=scenario", "set experiment.scenario_study.by instead"),
        ("formats=png", "set experiment.scenario_study.figure_formats instead"),
        ("marks=false", "it has no such setting (its settings: conf/experiment/scenario_study.yaml)"),
    ],
)
def test_the_scenario_study_refuses_a_link_setting_it_would_ignore(tmp_path, capsys, arg, hint):
    """With +experiment=scenario_study the link analysis' settings are not read: one line names the key and
    where the study's own setting is, and nothing is written."""
    argv = ["+experiment=scenario_study", "+debug=fast", f"output_dir={tmp_path}", arg, f"out={tmp_path / 'o'}"]
    assert cli.main([*argv, "mlflow=false"]) == 2
    err = capsys.readouterr().err.strip()
    key = arg.split("=")[0]
    assert err.startswith(f"sphri coverage: coverage.{key}=") and err.endswith(hint), err
    assert "\n" not in err and not any((tmp_path / "o").iterdir() if (tmp_path / "o").exists() else [])


def test_overwrite_replaces_out_whole_and_the_run_logs_only_its_own_files(study, tmp_path, monkeypatch):
    """``overwrite=true``: an earlier run's files in ``out`` are gone once this run's are written, none of them is
    among this run's files or MLflow artifacts, and no temporary folder is left beside ``out``."""
    from mlflow.tracking import MlflowClient

    from sphri.surface.cylinder import CylinderSurface
    from sphri.tracking.mlflow_tracker import default_uri

    surface = CylinderSurface().fit(study.link)
    monkeypatch.setattr(cli, "compose", lambda overrides: fake_cfg(tmp_path))
    monkeypatch.setattr("sphri.pipeline.make_pipeline", lambda cfg, cache: FakePipeline(study, surface))
    out = tmp_path / "runs" / "cov"
    (out / "arm").mkdir(parents=True)
    (out / "arm" / "density_participant_09.npz").write_text("an earlier run's map\n")
    settings = cli.load_settings(["render=false", "n_projections=32", "heldout=false"])
    with pytest.raises(ConfigError, match="exists and is not empty"):
        cli.run(["data.regions=[arm]"], settings, out)
    res = cli.run(["data.regions=[arm]"], settings, out, overwrite=True)
    assert res.out_dir == out and all(p.is_file() and out in p.parents for p in res.files["arm"])
    assert not (out / "arm" / "density_participant_09.npz").exists() and (out / "arm" / "density_poke.npz").is_file()
    assert sorted(p.name for p in out.parent.iterdir()) == ["cov"]
    client = MlflowClient(default_uri(tmp_path))
    logged = {a.path for a in client.list_artifacts(res.mlflow_run_id, "arm")}
    assert "arm/density_poke.npz" in logged and "arm/density_participant_09.npz" not in logged
    assert client.get_run(res.mlflow_run_id).data.tags["sphri.coverage_dir"] == str(out.resolve())


def test_real_pipeline_debug_fast(tmp_path):
    """The built-in data and contact stages, end to end."""
    overrides = [f"output_dir={tmp_path}", "+debug=fast", "data.regions=[arm]"]
    settings = cli.load_settings(["render=false", "n_projections=32"])
    res = cli.run(overrides, settings, tmp_path / "cov", log_mlflow=False)
    r = res.regions["arm"]
    assert r.curves["all"].n_frames > 0
    assert 0 < r.curves["all"].area_at_capture < 1
    assert len(r.comparison.table) == len(r.groups) * (len(r.groups) - 1) // 2


def test_console_shows_heldout_capture_and_notes(tmp_path, capsys):
    """The console says what held-out participants get and the caveats, not only the in-sample sentence."""
    rc = cli.main(
        [
            f"output_dir={tmp_path}",
            "+debug=fast",
            "data.regions=[arm]",
            "render=false",
            "n_projections=32",
            f"out={tmp_path / 'cov'}",
            "mlflow=false",
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "on held-out participants the same area captures" in out
    assert "note: with 3 participant value(s) the exact sign-flip test cannot reach p <= 0.05" in out
