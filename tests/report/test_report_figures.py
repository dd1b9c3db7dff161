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
    truth = make_sweep(store, tmp_path / "sens", [1, 3, 6, 13, 27, 50], variants=variants, n_participants=6, seed=3)
    _, sens, _ = make_report(truth.sweep_dir, rule=RULE, out_dir=tmp_path / "sens_report", log_to_mlflow=False)
    assert "tornado" in sens.figures
    _check_formats(sens.figures.values())
    assert _layout_warnings(caplog) == []


def test_marks_switch_the_synthetic_banner_off(two_model_sweep, tmp_path):
    svg = ("png", "svg")  # the banner is text in the SVG
    _, on, _ = make_report(
        two_model_sweep.sweep_dir, rule=RULE, out_dir=tmp_path / "on", log_to_mlflow=False, formats=svg
    )
    _, off, _ = make_report(
        two_model_sweep.sweep_dir, rule=RULE, out_dir=tmp_path / "off", log_to_mlflow=False, marks=False, formats=svg
    )
    assert not list((tmp_path / "on").glob("*.pdf")), "only the formats asked for"
    for a, b in ((on.figures["curves"], off.figures["curves"]), (on.confusions["rf"], off.confusions["rf"])):
        assert "SYNTHETIC DATA" in a.with_suffix(".svg").read_text()
        assert "SYNTHETIC DATA" not in b.with_suffix(".svg").read_text()


def test_short_sweep_fills_the_axis_and_recall_at_zero_stays_visible(store, tmp_path, monkeypatch):
    """A 2-point sweep (res 2, 4: pitch far coarser than the study's 13.3 mm) spans the x axis instead of its
    right third; the study's line and label do not widen the view or cross a curve; the 0-1 axes keep a
    margin so that a recall of 0 is drawn above the axis line, not on it."""
    import numpy as np

    from sphri import figures

    kept = {}
    real = figures.save

    def save(fig, path, *a, **kw):
        kept[path.stem] = fig
        kw["close"] = False
        return real(fig, path, *a, **kw)

    monkeypatch.setattr(figures, "save", save)
    short = make_sweep(store, tmp_path / "short", [2, 4], n_participants=4, seed=5)
    _, files, _ = make_report(
        short.sweep_dir, rule=RULE, out_dir=tmp_path / "short_report", log_to_mlflow=False, formats=("png",)
    )
    curves = kept[files.figures["curves"].stem]
    assert figures.layout_problems(curves) == []
    for ax in curves.axes[:2]:
        x = np.concatenate(
            [
                ax.transData.transform(line.get_xydata())[:, 0]
                for line in ax.get_lines()
                if line.get_transform() is ax.transData
            ]
        )
        assert (x.max() - x.min()) / ax.bbox.width >= 0.6
        assert not ax.texts, "reference lines are named in the legend, not by text over the data"
    legend = [t.get_text() for t in curves.legends[0].get_texts()]
    assert any("study: 18 taxels / 24 cm" in t and "outside the sweep" in t for t in legend)
    recall = kept[files.figures["recall"].stem]
    ax = recall.axes[0]
    y0 = ax.transData.transform([(1.0, 0.0)])[0, 1]
    assert y0 - ax.bbox.y0 >= 2.0, "a recall of 0 lies on the axis line"
    assert figures.layout_problems(recall) == []
    figures.pyplot().close("all")
