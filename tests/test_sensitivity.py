"""+experiment=requirement_sensitivity: the assumption variants compose, and the quick preset runs end to
end (multirun + report) with the requirement per variant."""

from __future__ import annotations

import pandas as pd
import yaml

from sphri.config import CONF_DIR, compose

VARIANTS = sorted(p.stem for p in (CONF_DIR / "sensitivity").glob("*.yaml"))


def swept(name: str) -> dict[str, list[str]]:
    params = yaml.safe_load((CONF_DIR / "experiment" / f"{name}.yaml").read_text())["hydra"]["sweeper"]["params"]
    return {k: str(v).split(",") for k, v in params.items()}


def test_every_variant_names_itself_and_changes_one_assumption():
    assert {"reference", "noise0", "noise1", "noise5", "debounce", "coverage"} <= set(VARIANTS)
    ref = compose(["sensitivity=reference"])
    assert ref.variant == "reference"
    expected = {"noise0": ("noise.p", 0.0), "noise1": ("noise.p", 0.01), "noise5": ("noise.p", 0.05)}
    for name in VARIANTS:
        cfg = compose([f"sensitivity={name}"])
        assert cfg.variant == name, f"conf/sensitivity/{name}.yaml must set variant: {name}"
        if name in expected:
            key, value = expected[name]
            assert cfg.noise.p == value
    assert compose(["sensitivity=debounce"]).filter._target_.endswith("DebounceFilter")
    assert compose(["sensitivity=coverage"]).encoder._target_.endswith("CoverageEncoder")
    assert compose([]).get("variant") is None, "outside a sensitivity study there is no variant"


def test_the_full_study_sweeps_every_variant_over_a_coarse_grid():
    params = swept("requirement_sensitivity")
    assert set(params) == {"sensitivity", "layout.res"}
    assert set(params["sensitivity"]) <= set(VARIANTS) and "reference" in params["sensitivity"]
    res = [int(r) for r in params["layout.res"]]
    assert res[0] == 1 and res[-1] == 50 and 12 <= len(res) <= 20 and res == sorted(set(res))
    cfg = compose(["+experiment=requirement_sensitivity", "sensitivity=noise5"])
    assert cfg.model._target_.endswith("RandomForest") and cfg.noise.p == 0.05
    quick = compose(["+experiment=requirement_sensitivity_quick", "sensitivity=reference"])
    assert quick.data.participants == 3 and quick.cv.workers == 1
    assert set(swept("requirement_sensitivity_quick")["sensitivity"]) <= set(VARIANTS)


def test_quick_preset_runs_end_to_end_and_reports_each_variant(sweep_then_report):
    sweep, rep = sweep_then_report(
        ["+experiment=requirement_sensitivity_quick", "tracking.confusion_png=false"],
        9,
        ["n_boot=200", "mlflow=false", "formats=png"],
    )
    assert rep.returncode == 0, rep.stderr[-3000:]
    assert "grouped by variant" in rep.stdout
    assert "under the reference assumptions; between" in rep.stdout and "across the 3 assumptions tested" in rep.stdout
    table = pd.read_csv(sweep / "report" / "sensitivity.csv")
    assert sorted(table["variant"]) == ["debounce", "noise0", "reference"]
    assert (table["saturation_pitch_mm"] > 0).all()
    assert (sweep / "report" / "sensitivity_tornado.png").stat().st_size > 1000
    tol = pd.read_csv(sweep / "report" / "tolerances.csv")
    assert len(tol) == 9 and tol["used_in_sentence"].sum() == 3
