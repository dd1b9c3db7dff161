"""Figures a journal takes (issue 28, item 6): the style file, human labels, typeset units, symmetric matrices
drawn once, figures that fit a page, one banner, and the layout checks that find label-over-data and empty axes."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from sphri import figures


@pytest.fixture
def kept(monkeypatch):
    """The figures that sphri's plot functions save, left open for inspection (``save`` runs as usual)."""
    out = []
    real = figures.save

    def save(fig, path, *a, **kw):
        out.append(fig)
        kw["close"] = False
        return real(fig, path, *a, **kw)

    monkeypatch.setattr(figures, "save", save)
    yield out
    figures.pyplot().close("all")


def _banner(fig):
    found = [t for t in fig.texts if t.get_gid() == "sphri-banner"]
    assert len(found) == 1, "exactly one banner per figure"
    t = found[0]
    return t.get_text(), t.get_color(), t.get_fontsize(), t.get_position(), t.get_ha(), t.get_va()


# ---- the style file ------------------------------------------------------------------------------------------


def test_style_comes_from_the_shipped_mplstyle_and_can_be_overridden(tmp_path, monkeypatch):
    plt = figures.pyplot()
    assert figures.STYLE_PATH.name == "sphri.mplstyle" and figures.STYLE_PATH.is_file()
    assert not hasattr(figures, "RC"), "no hand-kept rcParams dict beside the style file"
    with figures.style():
        assert plt.rcParams["font.size"] == 8.0 and plt.rcParams["svg.fonttype"] == "none"
    mine = tmp_path / "journal.mplstyle"
    mine.write_text("font.size: 9.5\n")
    monkeypatch.setenv(figures.STYLE_ENV, str(mine))
    with figures.style():
        assert plt.rcParams["font.size"] == 9.5 and plt.rcParams["pdf.fonttype"] == 42  # the rest stays sphri's
    monkeypatch.setenv(figures.STYLE_ENV, str(tmp_path / "nope.mplstyle"))
    with pytest.raises(ValueError, match="SPHRI_MPLSTYLE.*nope.mplstyle"):
        with figures.style():
            pass


def test_the_style_file_ships_in_the_wheel():
    from pathlib import Path

    setup = (Path(__file__).resolve().parents[1] / "setup.py").read_text()
    assert '"*.mplstyle"' in setup


# ---- the layout checker --------------------------------------------------------------------------------------


def test_text_over_a_data_line_is_found_but_not_text_beside_a_reference_line():
    fig, ax = figures.new_figure("one", 2.4)
    ax.plot([1, 2, 3, 4], [0.2, 0.5, 0.8, 0.9], label="rf")
    ax.axvline(2.5, ls=":")
    ax.text(2.5, 0.5, "study: 18 taxels / 24 cm", rotation=90, ha="right", va="center")
    assert any("lies over the data line 'rf'" in p for p in figures.layout_problems(fig))
    fig, ax = figures.new_figure("one", 2.4)
    ax.plot([1, 2, 3, 4], [0.6, 0.7, 0.8, 0.9], label="rf")
    ax.axvline(2.5, ls=":")
    ax.set_ylim(0, 1)
    ax.text(2.5, 0.05, "study", ha="right", va="bottom")  # under the curve, along its own reference line
    assert figures.layout_problems(fig) == []


def test_a_sweep_in_a_third_of_the_axis_is_found():
    fig, ax = figures.new_figure("one", 2.4)
    ax.plot([60.0, 120.0], [0.5, 0.7], "o-")
    ax.set_xscale("log")
    ax.axvline(13.3)  # the study's line widens the view: the two points sit in the right third
    assert any("of the axis width" in p for p in figures.layout_problems(fig))
    ax.set_xlim(55, 130)
    assert not any("of the axis width" in p for p in figures.layout_problems(fig))


def test_a_line_over_a_map_need_not_span_it():
    """The requirement map draws the required pitch per row over its contours: the contours fill the axes
    (the quick map's line spans 38 % of them and was flagged)."""
    fig, (ax, bare) = figures.new_figure("two", 2.6, ncols=2)
    ax.contourf(np.linspace(1.0, 100.0, 10), np.arange(3.0), np.random.default_rng(0).random((3, 10)))
    ax.plot([20.0, 40.0, 30.0], [0.0, 1.0, 2.0], "o-")
    bare.plot([20.0, 40.0, 30.0], [0.0, 1.0, 2.0], "o-")
    bare.set_xlim(1.0, 100.0)
    problems = [p for p in figures.layout_problems(fig) if "of the axis width" in p]
    assert len(problems) == 1, problems  # the bare panel only


def test_a_figure_taller_than_a_page_and_an_untypeset_unit_are_found():
    fig, ax = figures.new_figure("two", 10.0)
    ax.set_title("placement under 2000 cm^2")
    problems = figures.layout_problems(fig)
    assert any("taller than a page" in p for p in problems)
    assert any("types a unit" in p for p in problems)
    assert figures.typeset("2000 cm^2, 3 m^2 and 5 mm^3") == "2000 cm$^2$, 3 m$^2$ and 5 mm$^3$"
    assert figures.fit_page(12.0) == figures.PAGE_HEIGHT_IN and figures.fit_page(3.0) == 3.0


# ---- labels ---------------------------------------------------------------------------------------------------


def test_human_labels():
    assert figures.human("S2_path_redirection") == "S2: path redirection"
    assert figures.human("torso_front_upper") == "torso front upper"
    assert figures.human("poke") == "poke"


SCEN = ["S1_greeting", "S2_path_redirection", "S3_handover", "S4_behaviour_correction"]


def _pairs(conds) -> list[tuple[int, int, str, str]]:
    """(i, j, a, b) for every pair of conditions, i < j."""
    return [(i, j, a, b) for (i, a), (j, b) in itertools.combinations(enumerate(conds), 2)]


def _effects(scen):
    rows = [
        dict(cond_a=a, cond_b=b, diff_swd_mm=10.0 * (i + j), effect_dz=0.4 * (j - i), p_holm=0.01 * (1 + i + j))
        for i, j, a, b in _pairs(scen)
    ]
    return pd.DataFrame(rows)


def _all_text(fig) -> list[str]:
    from matplotlib.text import Text

    return [t.get_text() for t in fig.findobj(Text) if t.get_visible() and t.get_text()]


def test_effect_matrix_is_drawn_once_with_human_labels_and_the_banner(tmp_path, kept):
    from sphri.sessions.render import plot_effects

    plot_effects(
        _effects(SCEN),
        SCEN,
        0.05,
        tmp_path / "effects.png",
        "Paired effect per pair (SYNTHETIC)",
        provenance=figures.Provenance(synthetic=True, ids="study"),
    )
    fig = kept[-1]
    ax = fig.axes[0]
    img = ax.images[0].get_array()
    assert img.shape == (3, 3), "the strict lower triangle: rows S2..S4 against columns S1..S3"
    assert (
        np.ma.getmaskarray(img)[np.triu_indices(3, k=1)].all() and not np.ma.getmaskarray(img)[np.tril_indices(3)].any()
    )
    assert ax.images[0].get_clip_path() is not None
    cells = [t for t in ax.texts if "mm" in t.get_text()]
    assert len(cells) == 6 and all(t.get_position()[0] <= t.get_position()[1] for t in cells)  # one per pair
    labels = [t.get_text() for t in ax.get_xticklabels() + ax.get_yticklabels()]
    assert "S2: path redirection" in labels and not any("_" in lab for lab in labels)
    assert _banner(fig)[0] == "SYNTHETIC DATA | study"
    assert figures.layout_problems(fig) == []


def _comparison(conds):
    from sphri.analysis.compare import PairwiseComparison

    rows, pp = [], []
    for i, j, a, b in _pairs(conds):
        rows.append(dict(cond_a=a, cond_b=b, mean_between_swd_mm=20.0 + 5 * i + 3 * j, p_holm=0.002 * (1 + i + j)))
        pp.append(
            dict(
                participant="p1",
                cond_a=a,
                cond_b=b,
                between_mm=1.0,
                within_a_mm=10.0 + i,
                within_b_mm=10.0 + j,
                diff_mm=1.0,
            )
        )
    return PairwiseComparison(
        conditions=list(conds),
        table=pd.DataFrame(rows),
        per_participant=pd.DataFrame(pp),
        alpha=0.05,
        alternative="greater",
        swd_p=2.0,
        n_projections=64,
    )


def test_swd_matrix_masks_the_upper_triangle(tmp_path, kept, recwarn):
    from sphri.analysis.render import plot_swd_heatmap

    plot_swd_heatmap(
        _comparison(SCEN),
        tmp_path / "swd.png",
        "Scenario maps: paired SWD",
        provenance=figures.Provenance(synthetic=True, ids="study"),
    )
    assert not [w for w in recwarn if issubclass(w.category, PendingDeprecationWarning)]
    fig = kept[-1]
    ax = fig.axes[0]
    img = ax.images[0].get_array()
    n = len(SCEN)
    assert np.ma.getmaskarray(img)[np.triu_indices(n, k=1)].all()
    assert not np.ma.getmaskarray(img)[np.tril_indices(n, k=-1)].any()  # the diagonal: grey (bad), its value printed
    assert ax.images[0].get_clip_path() is not None
    cells = [t for t in ax.texts]
    assert len(cells) == n * (n + 1) // 2, "lower triangle and diagonal, each cell once"
    assert all(t.get_position()[0] <= t.get_position()[1] for t in cells)
    assert not any("_" in t.get_text() for t in ax.get_xticklabels() + ax.get_yticklabels())
    assert figures.layout_problems(fig) == []


def test_placement_figure_fits_a_page_and_typesets_the_budget(tmp_path, kept):
    from sphri.sessions.render import plot_placement

    parts = [f"part_{k:02d}_left" for k in range(80)]
    ranking = pd.DataFrame({"part": parts, "frames_per_cm2": np.linspace(2.0, 0.01, 80)})
    table = pd.DataFrame(
        {
            "group": ["all", "S2_path_redirection"],
            "parts": ["part_00_left;part_01_left"] * 2,
            "area_share": [0.1, 0.09],
            "captured": [0.7, 0.8],
            "heldout_captured": [0.65, 0.75],
        }
    )
    plot_placement(
        ranking,
        table,
        tmp_path / "placement.png",
        "Placement under 2000 cm^2 (SYNTHETIC)",
        provenance=figures.Provenance(synthetic=True),
    )
    fig = kept[-1]
    assert fig.get_figheight() <= figures.PAGE_HEIGHT_IN
    text = _all_text(fig)
    assert any("cm$^2$" in t for t in text) and not any("cm^2" in t for t in text)
    assert "part 00 left" in text and not any("part_" in t for t in text)
    assert any(t.startswith("S2: path redirection") for t in text)


def test_gesture_histogram_uses_human_scenario_names(tmp_path, kept):
    from sphri.sessions.render import plot_gesture_histogram
    from sphri.types import GESTURES

    hist = pd.DataFrame(
        [
            dict(scenario=s, gesture=g, n_episodes=10, expected=1.0, expected_sd=0.2, count=1)
            for s in SCEN[:2]
            for g in GESTURES
        ]
    )
    plot_gesture_histogram(hist, tmp_path / "g.png", "Gestures (SYNTHETIC)", provenance=figures.Provenance(True))
    titles = [ax.get_title() for ax in kept[-1].axes]
    assert titles[1].startswith("S2: path redirection\n")


def test_one_banner_style_across_figures(tmp_path, kept):
    """The banner of a study figure, a coverage figure and a plain figure: same text, colour, size and place."""
    from sphri.analysis.placement import CoverageCurve
    from sphri.analysis.render import plot_coverage_curves
    from sphri.sessions.render import plot_effects

    prov = figures.Provenance(synthetic=True, ids="data v3")
    plot_effects(_effects(SCEN), SCEN, 0.05, tmp_path / "e.png", "effects", provenance=prov)
    share = np.linspace(0, 1, 11)
    curve = CoverageCurve("all", np.arange(10), share, np.sqrt(share), 100, 0.9, 7, np.zeros(100, dtype=np.int64))
    plot_coverage_curves([curve], tmp_path / "c.png", "coverage", provenance=prov)
    fig, ax = figures.new_figure("one", 2.0)
    ax.plot([0, 1], [0, 1])
    figures.mark(fig, prov)
    kept.append(fig)
    banners = {_banner(f) for f in kept}
    assert len(banners) == 1, banners
