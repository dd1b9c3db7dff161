"""Every report figure exists as PNG, PDF and SVG, with no text past the canvas, under 7 pt at print size
or overlapping other text (``sphri.figures.layout_problems``, which ``figures.save`` runs on each figure)."""

from __future__ import annotations

import logging

from fake_sweep import make_sweep

from sphri.report.analysis import RuleSettings
from sphri.report.build import make_report

RULE = RuleSettings(n_boot=200)


def _layout_warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "sphri.figures"]


def _check_formats(paths) -> None:
    for png in paths:
        for fmt in ("png", "pdf", "svg"):
            f = png.with_suffix("." + fmt)
            assert f.is_file() and f.stat().st_size > 0, f"{f.name} missing"


def test_every_report_figure_is_clean_in_three_formats(two_model_sweep, store, tmp_path, caplog):
    caplog.set_level(logging.WARNING, logger="sphri.figures")
    _, files, _ = make_report(two_model_sweep.sweep_dir, rule=RULE, out_dir=tmp_path / "two", log_to_mlflow=False)
    assert {"curves", "recall", "bootstrap"} <= set(files.figures)
    assert set(files.confusions) == {"rf", "cnn_gru"}  # redrawn here from the jobs' counts: checked too
    _check_formats([*files.figures.values(), *files.confusions.values()])
    variants = {"reference": (3.0, 0.02), "noise0": (1.5, 0.0), "noise5": (8.0, 0.05)}
    truth = make_sweep(store, tmp_path / "sens", [1, 3, 6, 13, 27, 50], variants=variants,
                       n_participants=6, seed=3)
    _, sens, _ = make_report(truth.sweep_dir, rule=RULE, out_dir=tmp_path / "sens_report", log_to_mlflow=False)
    assert "tornado" in sens.figures
    _check_formats(sens.figures.values())
    assert _layout_warnings(caplog) == []


def test_marks_switch_the_synthetic_banner_off(two_model_sweep, tmp_path):
    svg = ("png", "svg")  # the banner is text in the SVG
    _, on, _ = make_report(two_model_sweep.sweep_dir, rule=RULE, out_dir=tmp_path / "on", log_to_mlflow=False,
                           formats=svg)
    _, off, _ = make_report(two_model_sweep.sweep_dir, rule=RULE, out_dir=tmp_path / "off", log_to_mlflow=False,
                            marks=False, formats=svg)
    assert not list((tmp_path / "on").glob("*.pdf")), "only the formats asked for"
    for a, b in ((on.figures["curves"], off.figures["curves"]), (on.confusions["rf"], off.confusions["rf"])):
        assert "SYNTHETIC DATA" in a.with_suffix(".svg").read_text()
        assert "SYNTHETIC DATA" not in b.with_suffix(".svg").read_text()
