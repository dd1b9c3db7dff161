"""One figure style for every figure sphri writes (reports, coverage, tracking).

Figures are drawn at the size they will be printed: one column
(:data:`ONE_COLUMN_IN`, 3.5 in) or two (:data:`TWO_COLUMN_IN`, 7.16 in, the
IEEE/ACM double-column text width), with fonts of at least
:data:`MIN_FONT_PT` (7 pt) at that size, and saved as PNG (300 dpi) beside
PDF and SVG (text kept as text). :func:`layout_problems` finds text that
leaves the canvas, text smaller than 7 pt at print size and labels that
overlap each other; :func:`save` logs them, and the figure tests assert that
there are none.

Provenance (the SYNTHETIC banner and run ids) is one switch,
:class:`Provenance`, drawn by :func:`mark` in the figure's top margin: on by
default for synthetic data, where leaving it off would let a synthetic
figure pass for a measured one.
"""

from __future__ import annotations

import logging
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

log = logging.getLogger(__name__)

#: Text width of one column of a two-column paper, inches.
ONE_COLUMN_IN = 3.5
#: Text width of a two-column paper, inches.
TWO_COLUMN_IN = 7.16
#: Smallest font allowed at print size, points.
MIN_FONT_PT = 7.0
#: Formats written by :func:`save` (the first is the path's own suffix).
FORMATS: tuple[str, ...] = ("png", "pdf", "svg")

RC = {
    "font.size": 8.0,
    "axes.titlesize": 8.5,
    "axes.labelsize": 8.0,
    "xtick.labelsize": 7.0,
    "ytick.labelsize": 7.0,
    "legend.fontsize": 7.0,
    "legend.title_fontsize": 7.0,
    "figure.titlesize": 9.0,
    "axes.linewidth": 0.6,
    "lines.linewidth": 1.2,
    "lines.markersize": 3.5,
    "grid.linewidth": 0.4,
    "figure.dpi": 100,
    "savefig.dpi": 300,
    "pdf.fonttype": 42,  # TrueType in PDFs: editable text, accepted by publishers
    "svg.fonttype": "none",  # SVG text stays text
    "figure.constrained_layout.use": True,
}


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def width_in(width: str | float) -> float:
    """Inches of ``"one"`` column, ``"two"`` columns, or a number of inches."""
    if width == "one":
        return ONE_COLUMN_IN
    if width == "two":
        return TWO_COLUMN_IN
    w = float(width)
    if not 1.0 <= w <= 2 * TWO_COLUMN_IN:
        raise ValueError(f"figure width {w} in is outside [1, {2 * TWO_COLUMN_IN}] in")
    return w


@contextmanager
def style() -> Iterator[None]:
    """Matplotlib rc settings of sphri's figures, for the figures created inside."""
    plt = pyplot()
    with plt.rc_context(RC):
        yield


def new_figure(width: str | float = "two", height: float = 2.6, nrows: int = 1, ncols: int = 1, **kwargs):
    """``(fig, axes)`` at print size in sphri's style (constrained layout).

    Draw inside ``with style():`` as well: matplotlib fixes an artist's font
    when it is created (titles, labels, colour bars added later)."""
    plt = pyplot()
    with style():
        fig, axes = plt.subplots(nrows, ncols, figsize=(width_in(width), float(height)), **kwargs)
    return fig, axes


@dataclass(frozen=True)
class Provenance:
    """What a figure says about where its data came from."""

    synthetic: bool = False
    """The data are synthetic: the banner says SYNTHETIC DATA."""
    ids: str = ""
    """Run or sweep ids to print small under the banner ("" for none)."""
    show: bool | None = None
    """Draw the marks: None = only when synthetic (the default), True always, False never."""

    @property
    def visible(self) -> bool:
        return self.synthetic if self.show is None else bool(self.show)


def mark(fig, provenance: Provenance) -> None:
    """Draw the provenance marks in the figure's top-right corner (inside the canvas)."""
    if not provenance.visible:
        return
    parts = []
    if provenance.synthetic:
        parts.append("SYNTHETIC DATA")
    if provenance.ids:
        parts.append(provenance.ids)
    if parts:
        fig.text(0.995, 0.995, " | ".join(parts), ha="right", va="top", fontsize=MIN_FONT_PT,
                 color="firebrick" if provenance.synthetic else "0.35")
        engine = fig.get_layout_engine()
        if engine is not None and hasattr(engine, "set") and "rect" in engine.get():
            # keep a strip for the marks: constrained layout lays titles and legends out below it
            strip = 1.7 * MIN_FONT_PT / 72.0 / fig.get_figheight()
            engine.set(rect=(0.0, 0.0, 1.0, 1.0 - strip))


def _texts(fig):
    """Every visible, non-empty text artist of the figure."""
    from matplotlib.text import Text

    for t in fig.findobj(Text):
        if t.get_visible() and t.get_text().strip() and t.get_figure() is fig:
            yield t


def layout_problems(fig, print_width_in: float | None = None) -> list[str]:
    """Text past the canvas, below :data:`MIN_FONT_PT` at print size, or overlapping other labels.

    ``print_width_in``: the width the figure will be printed at (default: its
    own width, capped at two columns: a wider figure is scaled down, and its
    fonts with it).
    """
    with style():  # ticks are created lazily (at draw time, or when asked for): keep the same rc settings
        return _layout_problems(fig, print_width_in)


def _layout_problems(fig, print_width_in: float | None) -> list[str]:
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    w_in = fig.get_figwidth()
    scale = (print_width_in or min(w_in, TWO_COLUMN_IN)) / w_in
    canvas = fig.bbox
    problems = []
    labels = []
    ticks, not_drawn = _tick_labels(fig)
    for t in _texts(fig):
        if id(t) in not_drawn:
            continue
        box = t.get_window_extent(renderer)
        name = repr(t.get_text()[:40])
        if box.x0 < canvas.x0 - 1 or box.y0 < canvas.y0 - 1 or box.x1 > canvas.x1 + 1 or box.y1 > canvas.y1 + 1:
            problems.append(f"text {name} extends past the canvas")
        size = t.get_fontsize() * scale
        if size < MIN_FONT_PT - 1e-6:
            problems.append(f"text {name} is {size:.1f} pt at print size (< {MIN_FONT_PT})")
        if id(t) not in ticks:
            labels.append((name, box))
    for i in range(len(labels)):
        for j in range(i + 1, len(labels)):
            a, b = labels[i][1], labels[j][1]
            if a.overlaps(b) and _overlap_area(a, b) > 0.2 * min(a.width * a.height, b.width * b.height):
                problems.append(f"text {labels[i][0]} overlaps {labels[j][0]}")
    return problems


def _check_and_write_png(fig, out: Path) -> list[str]:
    """:func:`layout_problems` drawn at ``savefig.dpi``, then that same Agg buffer written as the PNG."""
    import numpy as np
    from PIL import Image

    plt = pyplot()
    dpi0 = fig.dpi
    with style():
        dpi = plt.rcParams["savefig.dpi"]
        dpi = float(dpi0 if dpi == "figure" else dpi)
        fig.set_dpi(dpi)
        try:
            problems = layout_problems(fig)  # draws the canvas at this dpi
            if fig.stale:
                fig.canvas.draw()
            Image.fromarray(np.asarray(fig.canvas.buffer_rgba())).save(out, format="png", dpi=(dpi, dpi))
        finally:
            fig.set_dpi(dpi0)
    return problems


def _tick_labels(fig) -> tuple[set[int], set[int]]:
    """ids of the tick labels drawn (tick inside the axis' view interval) and of those not drawn."""
    drawn, hidden = set(), set()
    for ax in fig.findobj(lambda a: hasattr(a, "xaxis") and hasattr(a, "yaxis")):
        for axis in (ax.xaxis, ax.yaxis):
            if not ax.axison or not ax.get_visible() or not axis.get_visible():  # axes drawn without ticks
                for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                    hidden.update((id(tick.label1), id(tick.label2)))
                continue
            lo, hi = sorted(axis.get_view_interval())
            span = (hi - lo) * 1e-9
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                loc = tick.get_loc()
                inside = loc is not None and lo - span <= loc <= hi + span
                (drawn if inside else hidden).update((id(tick.label1), id(tick.label2)))
    return drawn, hidden


def _overlap_area(a, b) -> float:
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return max(w, 0.0) * max(h, 0.0)


#: The formats :func:`save` writes when not told (see :func:`only_formats`).
_formats: list[tuple[str, ...]] = [FORMATS]


@contextmanager
def only_formats(formats: Sequence[str]) -> Iterator[None]:
    """Within the block, :func:`save` writes ``formats`` (e.g. ``("png",)`` for a quick look) unless a
    call names its own."""
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise ValueError(f"figure formats {list(formats)} are invalid: choose from {list(FORMATS)}")
    _formats.append(tuple(formats))
    try:
        yield
    finally:
        _formats.pop()


def save(fig, path: Path | str, formats: Sequence[str] | None = None, close: bool = True,
         check: bool = True) -> list[Path]:
    """Write ``fig`` as ``path`` and its siblings in the other ``formats`` (same stem; default
    :data:`FORMATS`, or those of the enclosing :func:`only_formats`).

    Layout problems (:func:`layout_problems`) are logged as warnings naming
    the file; the figure tests assert that sphri's own figures have none.
    ``check=False`` skips that check (it draws the figure once more): for
    figures written per job whose code the tests check elsewhere.
    """
    path = Path(path)
    formats = _formats[-1] if formats is None else tuple(formats)
    fmts = list(dict.fromkeys([path.suffix.lstrip(".") or "png", *formats]))
    written = []
    if check and "png" in fmts and hasattr(fig.canvas, "buffer_rgba"):
        # one draw at the PNG's resolution serves the layout check and the PNG (a check drawing the figure
        # once more took as long as writing it)
        out = path.with_suffix(".png")
        problems = _check_and_write_png(fig, out)
        written.append(out)
        fmts.remove("png")
    else:
        problems = layout_problems(fig) if check else []
    for problem in problems:
        log.warning("%s: %s", path.name, problem)
    with style():
        for fmt in fmts:
            out = path.with_suffix("." + fmt)
            fig.savefig(out, format=fmt)
            written.append(out)
    if close:
        pyplot().close(fig)
    return written
