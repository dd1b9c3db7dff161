"""+experiment=requirement_map: the false-on-rate knob composes as documented, and the quick preset runs end to
end (multirun + report) writing requirement_map.csv and its layout-checked figure."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import yaml

from sphri.config import CONF_DIR, compose
from sphri.report.sweep import false_on_rate, group_keys

MAP_COLUMNS = {
    "false_on_rate",
    "res",
    "pitch_mm",
    "accuracy_mean",
    "accuracy_se",
    "required_pitch_mm",
    "required_pitch_lo_mm",
    "required_pitch_hi_mm",
    "false_on_per_frame",
}


def swept(name: str) -> dict[str, list[str]]:
    params = yaml.safe_load((CONF_DIR / "experiment" / f"{name}.yaml").read_text())["hydra"]["sweeper"]["params"]
    return {k: str(v).split(",") for k, v in params.items()}


def test_full_map_sweeps_six_false_on_rates_sixteen_resolutions_three_seeds():
    params = swept("requirement_map")
    assert [float(p) for p in params["noise.p"]] == [0.0, 0.002, 0.005, 0.01, 0.02, 0.05]
    assert params["layout.res"] == swept("requirement_sensitivity")["layout.res"], "the sensitivity study's grid"
    assert len(params["layout.res"]) == 16 and params["seed"] == ["0", "1", "2"]
    assert params["filter"] == ["none", "despeckle", "persistence"]
    assert swept("requirement_map_quick")["filter"] == ["none", "despeckle", "persistence"]
    assert compose(["+experiment=requirement_map", "filter=persistence"]).filter.ms == 50.0
    cfg = compose(["+experiment=requirement_map", "noise.p=0.005"])
    assert cfg.model._target_.endswith("RandomForest")
    # replace mode with salt_vs_pepper=1: p is exactly the false-on rate, and nothing touched is turned off
    assert cfg.noise.mode == "replace" and cfg.noise.salt_vs_pepper == 1.0 and cfg.noise.p == 0.005
    quick = compose(["+experiment=requirement_map_quick"])
    assert quick.data.participants == 3 and quick.data.repetitions == 2 and quick.model.n_estimators == 30
    q = swept("requirement_map_quick")
    assert len(q["noise.p"]) >= 2 and len(q["layout.res"]) >= 2 and len(q["seed"]) == 2


def test_full_threshold_map_lines_its_rates_up_with_the_salt_and_pepper_map():
    from sphri.noise.components import threshold_false_on_rate

    params = swept("requirement_map_threshold")
    assert params["layout.res"] == swept("requirement_map")["layout.res"] and params["seed"] == ["0", "1"]
    cfg = compose(["+experiment=requirement_map_threshold"])
    assert cfg.encoder._target_.endswith("CoverageEncoder") and cfg.noise.threshold_mm2 == 10.0
    rates = [
        threshold_false_on_rate(float(s), cfg.noise.threshold_mm2, cfg.noise.drift_sigma_mm2)
        for s in params["noise.sigma_mm2"]
    ]
    salt = [float(p) for p in swept("requirement_map")["noise.p"]]
    assert rates == pytest.approx(salt, rel=0.002, abs=1e-12)


@pytest.mark.parametrize("effect", ["crosstalk", "drift"])
def test_the_noise_effect_rows_keep_the_1_percent_false_on_rate(effect):
    from sphri.noise.components import threshold_false_on_rate

    cfg = compose([f"+experiment=requirement_map_{effect}"])
    n = cfg.noise
    assert threshold_false_on_rate(n.sigma_mm2, n.threshold_mm2, n.drift_sigma_mm2) == pytest.approx(0.01, rel=0.002)
    assert (n.crosstalk > 0) == (effect == "crosstalk") and (n.drift_sigma_mm2 > 0) == (effect == "drift")
    assert swept(f"requirement_map_{effect}")["layout.res"] == swept("requirement_map_threshold")["layout.res"]


def test_false_on_rate_is_range_checked_and_read_back_from_the_noise_params():
    with pytest.raises(Exception, match="noise.p"):
        compose(["+experiment=requirement_map", "noise.p=1.5"])
    with pytest.raises(Exception, match="noise.salt_vs_pepper"):
        compose(["+experiment=requirement_map", "noise.salt_vs_pepper=-0.1"])
    assert (
        false_on_rate(
            {"noise": "salt_pepper", "noise.p": "0.02", "noise.mode": "replace", "noise.salt_vs_pepper": "1.0"}
        )
        == 0.02
    )
    assert false_on_rate(
        {"noise": "salt_pepper", "noise.p": "0.02", "noise.mode": "replace", "noise.salt_vs_pepper": "0.5"}
    ) == pytest.approx(0.01)  # the paper's 2 % noise
    assert false_on_rate({"noise": "salt_pepper", "noise.p": "0.02", "noise.mode": "flip"}) == 0.02
    assert false_on_rate({"noise": "none"}) == 0.0
    assert np.isnan(false_on_rate({"noise": "gaussian", "noise.sigma": "0.05"}))


def test_seeds_are_replicates_not_groups():
    jobs = [
        {"seed": str(s), "model.seed": str(s), "noise.p": p, "layout.res": str(r)}
        for s in (0, 1, 2)
        for p in ("0", "0.01")
        for r in (2, 6)
    ]
    assert group_keys(jobs) == ["noise.p"]


def test_quick_map_runs_end_to_end_and_reports_the_map(sweep_then_report):
    # the quick preset at two of its false-on rates, two resolutions and two filters (16 jobs): a map per filter
    # with a row per rate, and the filter table
    res = [2, 12]
    sweep, rep = sweep_then_report(
        [
            "+experiment=requirement_map_quick",
            "noise.p=0,0.05",
            "layout.res=2,12",
            "filter=none,persistence",
            "tracking.confusion_png=false",
        ],
        16,
        ["n_boot=200", "mlflow=false"],
    )
    assert "[requirement map: filter=none]" in rep.stdout and "[requirement map: filter=persistence]" in rep.stdout
    assert "[filters]" in rep.stdout and "<- best pair:" in rep.stdout and "best accuracy (pitch)" in rep.stdout
    assert "cost of persistence on clean data (false-on 0)" in rep.stdout
    assert "measured between the sweep's seeds" in rep.stdout and "smallest certifiable tolerance" in rep.stdout
    # the figure machinery's layout check logs any clipped or overlapping text as a warning naming the file
    assert "requirement_map.png:" not in rep.stderr, rep.stderr[-3000:]
    assert "filter_map.png:" not in rep.stderr, rep.stderr[-3000:]
    d = sweep / "report"
    table = pd.read_csv(d / "requirement_map.csv")
    assert MAP_COLUMNS <= set(table.columns)
    rates = [0.0, 0.05]
    assert sorted(table["false_on_rate"].unique()) == pytest.approx(rates) and len(table) == 2 * len(rates) * len(res)
    assert (table["seeds"] == 2).all() and (table["participants"] == 3).all()
    assert table["false_on_per_frame"].to_numpy() == pytest.approx(table["false_on_rate"] * table["n_taxels"])
    pairs = pd.read_csv(d / "filter_pairs.csv")
    assert len(pairs) == len(rates) * 2 * len(res) and set(pairs["filter"]) == {"none", "persistence"}
    assert pairs.groupby("false_on_rate")["best_pair"].sum().eq(1).all()
    assert pairs.groupby(["false_on_rate", "filter"])["required"].sum().eq(1).all()
    for _rate, rows in pairs.groupby("false_on_rate"):
        best = rows[rows["best_pair"]].iloc[0]
        assert best["accuracy_mean"] == pytest.approx(rows["accuracy_mean"].max())
    for _key, rows in table.groupby(["map", "false_on_rate"]):
        assert rows["required_pitch_mm"].nunique() == 1 and rows["required"].sum() == 1
        req = rows[rows["required"]].iloc[0]
        assert req["pitch_mm"] == pytest.approx(req["required_pitch_mm"])
        assert req["required_pitch_lo_mm"] <= req["required_pitch_mm"] <= req["required_pitch_hi_mm"]
        # every resolution from the required one on is certified within the tolerance, never one below T*
        finer = rows[rows["res"] >= req["res"]]
        assert not finer["outside_tolerance"].any() and (finer["bound"] <= req["tolerance"] + 1e-12).all()
        assert req["tolerance"] >= max(0.01, req["tolerance_certifiable"]) - 1e-12
    for fmt in ("png", "pdf", "svg"):
        assert (d / f"requirement_map.{fmt}").stat().st_size > 1000
        assert (d / f"filter_map.{fmt}").stat().st_size > 1000
    # the (pitch, filter) figure: one panel per filter, the best pair and each filter's required pitch marked
    fsvg = (d / "filter_map.svg").read_text()
    assert "filter: none" in fsvg and "filter: persistence" in fsvg and "best pair at the rate" in fsvg
    assert "required pitch" in fsvg and "(pitch, filter) pair" in fsvg
    # the figure: the certified tolerance in the title, one discrete row per rate, the clean row on a symlog axis
    svg = (d / "requirement_map.svg").read_text()
    # with a filter axis the figure draws the unfiltered map (the filters are filter_map's)
    tol = table[table["map"] == "filter=none"].groupby("false_on_rate")["tolerance"].first().round(3)
    title = f"T = {tol.min():.3f}" + ("" if tol.nunique() == 1 else f"-{tol.max():.3f} by row")
    assert f"required pitch (filter=none), certified within {title}" in svg
    assert "deficit to the row" in svg and "(symlog)" in svg and "clean row at 0" in svg and "contour" not in svg


def test_threshold_quick_map_reads_the_false_on_rate_from_the_noise_and_reports_a_map(sweep_then_report):
    # noise=threshold at debug size: sigma 0 and 5 mm^2 against a 10 mm^2 threshold (false-on 0 and
    # P(N(0, 5^2) > 10) = 2.275 %), two resolutions, two seeds (8 jobs)
    quick = compose(["+experiment=requirement_map_threshold_quick"])
    assert quick.noise._target_.endswith("ThresholdNoise") and quick.encoder._target_.endswith("CoverageEncoder")
    assert len(swept("requirement_map_threshold_quick")["noise.sigma_mm2"]) >= 2
    sweep, rep = sweep_then_report(
        ["+experiment=requirement_map_threshold_quick", "noise.sigma_mm2=0,5", "layout.res=2,12"],
        8,
        ["n_boot=200", "mlflow=false"],
    )
    assert "[requirement map]" in rep.stdout
    assert "requirement_map.png:" not in rep.stderr, rep.stderr[-3000:]
    table = pd.read_csv(sweep / "report" / "requirement_map.csv")
    assert sorted(table["false_on_rate"].unique()) == pytest.approx([0.0, 0.022750131948179195], abs=1e-6)
    assert len(table) == 4 and (table["seeds"] == 2).all()
