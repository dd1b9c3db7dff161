"""sphri.figures: print sizes, vector output, and the layout checks the figure tests rely on."""

from __future__ import annotations

import pytest

from sphri import figures


def test_clean_figure_has_no_problems_and_saves_three_formats(tmp_path):
    fig, ax = figures.new_figure("one", 2.4)
    ax.plot([1, 2, 3], [1, 4, 9])
    ax.set_xlabel("taxel pitch (mm)")
    ax.set_ylabel("accuracy")
    figures.mark(fig, figures.Provenance(synthetic=True, ids="sweep abc"))
    assert figures.layout_problems(fig) == []
    written = figures.save(fig, tmp_path / "curve.png")
    assert sorted(p.suffix for p in written) == [".pdf", ".png", ".svg"]
    assert all(p.stat().st_size > 0 for p in written)
    assert "SYNTHETIC DATA" in (tmp_path / "curve.svg").read_text()  # text stays text in SVG


def test_the_checked_png_is_the_picture_matplotlib_saves(tmp_path):
    """save() draws a figure once for its layout check and its PNG; the check asks every axis for its
    ticks, which marks the figure stale. The PNG must be the picture savefig writes (constrained
    layout, a colour bar, tick labels, the banner), not a second draw's."""
    import numpy as np
    from PIL import Image

    def build():
        fig, axes = figures.new_figure("two", 2.6, ncols=2)
        with figures.style():
            image = axes[0].imshow(np.arange(48.0).reshape(6, 8), aspect="auto")
            fig.colorbar(image, ax=axes[0], label="frames per cm$^2$")
            axes[1].plot(np.linspace(0, 30, 20), np.linspace(0.2, 0.9, 20))
            axes[1].set_xlabel("taxel pitch (mm)")
            figures.mark(fig, figures.Provenance(synthetic=True, ids="sweep abc"))
        return fig

    figures.save(build(), tmp_path / "checked.png", formats=["png"])
    with figures.style():
        dpi = figures.pyplot().rcParams["savefig.dpi"]
        build().savefig(tmp_path / "matplotlib.png", dpi=dpi)
    checked, reference = (
        np.asarray(Image.open(tmp_path / f"{n}.png").convert("RGBA")) for n in ("checked", "matplotlib")
    )
    assert checked.shape == reference.shape and np.array_equal(checked, reference)


def test_only_formats_restricts_what_save_writes(tmp_path):
    with figures.only_formats(["png"]):
        fig, ax = figures.new_figure("one", 2.0)
        ax.plot([0, 1], [0, 1])
        assert [p.suffix for p in figures.save(fig, tmp_path / "a.png")] == [".png"]
        fig, ax = figures.new_figure("one", 2.0)
        assert sorted(p.suffix for p in figures.save(fig, tmp_path / "b.png", formats=("png", "pdf"))) == [
            ".pdf",
            ".png",
        ]
    fig, ax = figures.new_figure("one", 2.0)
    assert len(figures.save(fig, tmp_path / "c.png")) == 3  # back to PNG + PDF + SVG after the block
    with pytest.raises(ValueError, match="figure formats"):
        with figures.only_formats(["jpeg"]):
            pass


@pytest.mark.filterwarnings("ignore:constrained_layout not applied")
def test_text_past_the_canvas_is_found():
    fig, ax = figures.new_figure("one", 2.0)
    ax.text(0.9, 0.5, "a label far too long to fit inside a one-column figure", transform=ax.transAxes)
    assert any("extends past the canvas" in p for p in figures.layout_problems(fig))


def test_small_print_size_fonts_are_found():
    fig, ax = figures.new_figure(12.0, 6.0)  # drawn wide: printed at two columns, fonts shrink
    ax.set_title("title at 8.5 pt")
    assert any("pt at print size" in p for p in figures.layout_problems(fig))


def test_overlapping_labels_are_found():
    fig, ax = figures.new_figure("one", 2.0)
    ax.text(0.2, 0.5, "saturation", transform=ax.transAxes)
    ax.text(0.22, 0.5, "study: 18 taxels", transform=ax.transAxes)
    assert any("overlaps" in p for p in figures.layout_problems(fig))


def test_provenance_switch():
    assert figures.Provenance(synthetic=True).visible
    assert not figures.Provenance(synthetic=False).visible
    assert not figures.Provenance(synthetic=True, show=False).visible
    assert figures.Provenance(synthetic=False, ids="run 1", show=True).visible


def test_confusion_matrix_fits_one_column_without_layout_problems(tmp_path, monkeypatch):
    import numpy as np

    from sphri.tracking import artifacts
    from sphri.types import CVResult, FoldResult

    rng = np.random.default_rng(0)
    folds = [FoldResult(str(i), 40, 0.5, 0.5, rng.integers(0, 9, (8, 8)), np.full(8, 0.5)) for i in range(3)]
    cv = CVResult("loso", "rf", folds)
    seen = []
    monkeypatch.setattr(figures, "layout_problems", lambda fig, *a, **k: seen.append(_real_problems(fig)) or seen[-1])
    out = artifacts.write_confusion_png(
        cv,
        tmp_path / "confusion.png",
        title="rf, LOSO over 3 folds",
        provenance=figures.Provenance(synthetic=True, ids="res 18"),
        formats=("png", "pdf", "svg"),
    )
    assert seen == [[]]
    assert {p.suffix for p in tmp_path.iterdir()} == {".png", ".pdf", ".svg"} and out.exists()


_real_problems = figures.layout_problems
