"""One figure style for every figure sphri writes (reports, coverage, tracking).

Figures are drawn at the size they will be printed: one column
(:data:`ONE_COLUMN_IN`, 3.5 in) or two (:data:`TWO_COLUMN_IN`, 7.16 in, the
IEEE/ACM double-column text width), with fonts of at least
:data:`MIN_FONT_PT` (7 pt) at that size, and saved as PNG (300 dpi) beside
PDF and SVG (text kept as text). The rc settings live in the shipped style
file ``sphri/sphri.mplstyle`` (:data:`STYLE_PATH`); style files named in
``SPHRI_MPLSTYLE`` are applied on top of it. :func:`layout_problems` finds
text that leaves the canvas, text smaller than 7 pt at print size, labels
that overlap each other (the banner may touch nothing), text placed over a
data line, a sweep spanning less than :data:`MIN_DATA_SPAN` of its axis,
figures taller than a page (:data:`PAGE_HEIGHT_IN`) and units typed as
``cm^2``; :func:`save` logs them, and the figure tests assert that there are
none. Scenario, gesture and body-part identifiers become labels through
:func:`human`; symmetric matrices are drawn once (:func:`lower_triangle`).

Provenance (the SYNTHETIC banner and run ids) is one switch,
:class:`Provenance`, drawn by :func:`mark` in the figure's top margin: on by
default for synthetic data, where leaving it off would let a synthetic
figure pass for a measured one.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger(__name__)

#: Text width of one column of a two-column paper, inches.
ONE_COLUMN_IN = 3.5
#: Text width of a two-column paper, inches.
TWO_COLUMN_IN = 7.16
#: Smallest font allowed at print size, points.
MIN_FONT_PT = 7.0
#: Formats written by :func:`save` (the first is the path's own suffix).
FORMATS: tuple[str, ...] = ("png", "pdf", "svg")

#: sphri's matplotlib style file (shipped in the wheel); :func:`style` applies it.
STYLE_PATH = Path(__file__).with_name("sphri.mplstyle")
#: Environment variable naming further style files (``os.pathsep``-separated), applied after :data:`STYLE_PATH`.
STYLE_ENV = "SPHRI_MPLSTYLE"
#: Tallest figure that fits a page's text block (A4 or letter, with a caption line), inches at print size.
PAGE_HEIGHT_IN = 9.0
#: Share of an axis' width that a sweep's data must span (no empty thirds).
MIN_DATA_SPAN = 0.6
#: The banner text of synthetic data (:func:`mark`).
SYNTHETIC_TEXT = "SYNTHETIC DATA"
#: The banner colours: synthetic data, and ids alone.
BANNER_COLOURS = {True: "firebrick", False: "0.35"}


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


def style_files() -> list[str]:
    """The style files :func:`style` applies: :data:`STYLE_PATH`, then those named in :data:`STYLE_ENV`."""
    extra = [p for p in os.environ.get(STYLE_ENV, "").split(os.pathsep) if p.strip()]
    for p in extra:
        if not Path(p).is_file():
            raise ValueError(f"{STYLE_ENV}: style file {p!r} does not exist")
    return [str(STYLE_PATH), *extra]


@contextmanager
def style() -> Iterator[None]:
    """Matplotlib settings of sphri's figures (:data:`STYLE_PATH`, then :data:`STYLE_ENV`'s files), for the
    figures created inside."""
    plt = pyplot()
    with plt.style.context(style_files()):
        yield


def fit_page(height_in: float) -> float:
    """``height_in`` capped at :data:`PAGE_HEIGHT_IN`: a figure that grows with its rows still fits a page."""
    return float(min(height_in, PAGE_HEIGHT_IN))


_UNTYPESET = re.compile(r"\b(c?m|mm)\^([23])\b")


def typeset(text: str) -> str:
    """Units typed as ``cm^2`` / ``m^2`` / ``mm^3`` in ``text`` written with mathtext (``cm$^2$``), as in every
    sphri figure."""
    return _UNTYPESET.sub(lambda m: f"{m.group(1)}$^{m.group(2)}$", str(text))


def human(name: str) -> str:
    """A scenario, gesture or body-part identifier as a label: ``S2_path_redirection`` -> ``S2: path
    redirection``, ``torso_front_upper`` -> ``torso front upper``."""
    name = str(name)
    m = re.fullmatch(r"(S\d+)_(.+)", name)
    if m:
        return f"{m.group(1)}: {m.group(2).replace('_', ' ')}"
    return name.replace("_", " ")


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


def mark(fig, provenance: Provenance | None) -> None:
    """Draw the provenance marks in the figure's top-right corner (inside the canvas); None draws none."""
    if provenance is None or not provenance.visible:
        return
    parts = [p for p in (SYNTHETIC_TEXT if provenance.synthetic else "", provenance.ids) if p]
    if parts:
        fig.text(
            0.995,
            0.995,
            " | ".join(parts),
            ha="right",
            va="top",
            fontsize=MIN_FONT_PT,
            color=BANNER_COLOURS[bool(provenance.synthetic)],
            gid="sphri-banner",
        )
        engine = fig.get_layout_engine()
        if engine is not None and hasattr(engine, "set") and "rect" in engine.get():
            # keep a strip for the marks: constrained layout lays titles and legends out below it
            strip = 1.7 * MIN_FONT_PT / 72.0 / fig.get_figheight()
            top = 1.0 - strip
            title = getattr(fig, "_suptitle", None)
            if title is not None and title.get_text():
                # constrained layout puts a suptitle at the figure's top edge, over the strip: pin it under the
                # strip and lay the panels out below it (an explicit y gets no margin of its own)
                fig.suptitle(title.get_text(), y=top, va="top", fontsize=title.get_fontsize(), wrap=title.get_wrap())
                h = fig._suptitle.get_window_extent(fig.canvas.get_renderer()).height / fig.dpi / fig.get_figheight()
                top -= h + 0.5 * strip
            engine.set(rect=(0.0, 0.0, 1.0, top))


def _texts(fig):
    """Every visible, non-empty text artist of the figure."""
    from matplotlib.text import Text

    for t in fig.findobj(Text):
        if t.get_visible() and t.get_text().strip() and t.get_figure() is fig:
            yield t


def layout_problems(fig, print_width_in: float | None = None, *, drawn: bool = False) -> list[str]:
    """Text past the canvas, below :data:`MIN_FONT_PT` at print size, or overlapping other labels.

    ``print_width_in``: the width the figure will be printed at (default: its
    own width, capped at two columns: a wider figure is scaled down, and its
    fonts with it). ``drawn``: the figure was just drawn (its renderer holds
    that draw, as when its PNG was taken from it); otherwise it is drawn here.
    """
    with style():  # ticks are created lazily (at draw time, or when asked for): keep the same rc settings
        if not drawn:
            fig.canvas.draw()
        return _layout_problems(fig, print_width_in)


def _layout_problems(fig, print_width_in: float | None) -> list[str]:
    renderer = fig.canvas.get_renderer()
    w_in = fig.get_figwidth()
    scale = (print_width_in or min(w_in, TWO_COLUMN_IN)) / w_in
    canvas = fig.bbox
    problems = []
    labels = []
    height = fig.get_figheight() * scale
    if height > PAGE_HEIGHT_IN + 1e-6:
        problems.append(f"figure is {height:.1f} in tall at print size (> {PAGE_HEIGHT_IN:g} in: taller than a page)")
    ticks, not_drawn = _tick_labels(fig)
    for t in _texts(fig):
        if id(t) in not_drawn:
            continue
        box = t.get_window_extent(renderer)
        name = repr(t.get_text()[:40])
        if box.x0 < canvas.x0 - 1 or box.y0 < canvas.y0 - 1 or box.x1 > canvas.x1 + 1 or box.y1 > canvas.y1 + 1:
            problems.append(f"text {name} extends past the canvas")
        if _UNTYPESET.search(t.get_text()):
            problems.append(f"text {name} types a unit as '^' (use cm$^2$: sphri.figures.typeset)")
        size = t.get_fontsize() * scale
        if size < MIN_FONT_PT - 1e-6:
            problems.append(f"text {name} is {size:.1f} pt at print size (< {MIN_FONT_PT})")
        if id(t) not in ticks:
            labels.append((name, box, t.get_gid() == "sphri-banner"))
    for i in range(len(labels)):
        for j in range(i + 1, len(labels)):
            a, b = labels[i][1], labels[j][1]
            # the banner may touch nothing; other labels a little (descenders, ascenders of neighbours)
            share = 0.0 if labels[i][2] or labels[j][2] else 0.2
            if a.overlaps(b) and _overlap_area(a, b) > share * min(a.width * a.height, b.width * b.height):
                problems.append(f"text {labels[i][0]} overlaps {labels[j][0]}")
    for ax in fig.axes:
        if ax.get_visible():
            problems += _text_over_data(ax, renderer) + _span_problems(ax)
    return problems


def _data_lines(ax):
    """The axes' visible data lines (in data coordinates; reference lines drawn with axhline/axvline, whose
    transform is blended with the axes, are not data) and their points in display coordinates."""
    import numpy as np

    for line in ax.get_lines():
        if not line.get_visible() or line.get_transform() is not ax.transData:
            continue
        xy = np.asarray(line.get_xydata(), dtype=float)
        xy = xy[np.isfinite(xy).all(axis=1)] if xy.size else xy.reshape(0, 2)
        if len(xy):
            yield line, ax.transData.transform(xy)


def _text_over_data(ax, renderer) -> list[str]:
    """Texts placed in the axes (``ax.text``) that a data line crosses or a data marker sits under."""
    import numpy as np
    from matplotlib.path import Path as MplPath

    out = []
    lines = list(_data_lines(ax))
    for t in ax.texts:
        if not t.get_visible() or not t.get_text().strip():
            continue
        box = t.get_window_extent(renderer).expanded(0.98, 0.9)
        for line, pts in lines:
            hit = False
            if len(pts) >= 2 and line.get_linestyle() not in ("None", "", " ", "none"):
                hit = MplPath(pts).intersects_bbox(box, filled=False)
            if not hit and line.get_marker() not in (None, "None", "", " ", "none"):
                hit = bool(
                    np.any(
                        (pts[:, 0] >= box.x0) & (pts[:, 0] <= box.x1) & (pts[:, 1] >= box.y0) & (pts[:, 1] <= box.y1)
                    )
                )
            if hit:
                out.append(f"text {t.get_text()[:40]!r} lies over the data line {line.get_label()[:40]!r}")
                break
    return out


def _span_problems(ax) -> list[str]:
    """A sweep (data lines with two or more x values) whose points span under :data:`MIN_DATA_SPAN` of the
    axis' width: the view was widened past the data (a reference line, a fixed limit), leaving it empty.
    Axes holding a map (an image, contours, a mesh) are filled by it and not checked."""
    import numpy as np
    from matplotlib.collections import QuadMesh
    from matplotlib.contour import ContourSet

    if ax.images or any(isinstance(c, (ContourSet, QuadMesh)) for c in ax.collections):
        return []  # a map fills the axes; a line drawn over it (a required pitch per row) need not span it
    pts = [p for _, p in _data_lines(ax)]
    if not pts:
        return []
    x = np.concatenate([p[:, 0] for p in pts])
    if np.unique(np.round(x, 3)).size < 2 or ax.bbox.width <= 0:
        return []
    share = (x.max() - x.min()) / ax.bbox.width
    if share < MIN_DATA_SPAN:
        return [
            f"data span {100 * share:.0f} % of the axis width (< {100 * MIN_DATA_SPAN:.0f} %): empty space "
            f"in {ax.get_title(loc='left') or ax.get_title() or 'a panel'!r}"
        ]
    return []


def _check_and_write_png(fig, out: Path) -> list[str]:
    """The figure drawn once at ``savefig.dpi``: that Agg buffer is the PNG, and :func:`layout_problems`
    reads the same draw. The buffer is taken before the check: asking an axis for its ticks marks the
    figure stale, and drawing it again for the PNG doubled the time of every figure (both draws are the
    same picture: the draw already made every tick the check asks for)."""
    import numpy as np
    from PIL import Image

    plt = pyplot()
    dpi0 = fig.dpi
    with style():
        dpi = plt.rcParams["savefig.dpi"]
        dpi = float(dpi0 if dpi == "figure" else dpi)
        fig.set_dpi(dpi)
        try:
            fig.canvas.draw()
            image = np.array(fig.canvas.buffer_rgba())  # a copy: the check must not change the picture
            problems = layout_problems(fig, drawn=True)
            Image.fromarray(image).save(out, format="png", dpi=(dpi, dpi))
        finally:
            fig.set_dpi(dpi0)
    return problems


def _tick_labels(fig) -> tuple[set[int], set[int]]:
    """ids of the tick labels drawn (tick inside the axis' view interval) and of those not drawn."""
    drawn: set[int] = set()
    hidden: set[int] = set()
    for ax in fig.findobj(lambda a: hasattr(a, "xaxis") and hasattr(a, "yaxis")):
        for axis in (ax.xaxis, ax.yaxis):
            shown = ax.axison and ax.get_visible() and axis.get_visible()  # else the axes are drawn without ticks
            lo, hi = sorted(axis.get_view_interval())
            span = (hi - lo) * 1e-9
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                loc = tick.get_loc()
                inside = shown and loc is not None and lo - span <= loc <= hi + span
                (drawn if inside else hidden).update((id(tick.label1), id(tick.label2)))
    return drawn, hidden


def _overlap_area(a, b) -> float:
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return max(w, 0.0) * max(h, 0.0)


#: The formats :func:`save` writes when not told (see :func:`only_formats`).
_formats: list[tuple[str, ...]] = [FORMATS]


def valid_formats(formats: Sequence[str]) -> bool:
    """``formats`` names one or more of :data:`FORMATS` and nothing else (the rule of every ``formats`` setting)."""
    return len(formats) > 0 and set(formats) <= set(FORMATS)


@contextmanager
def only_formats(formats: Sequence[str]) -> Iterator[None]:
    """Within the block, :func:`save` writes ``formats`` (e.g. ``("png",)`` for a quick look) unless a
    call names its own."""
    if not valid_formats(formats):
        raise ValueError(f"figure formats {list(formats)} are invalid: choose from {list(FORMATS)}")
    _formats.append(tuple(formats))
    try:
        yield
    finally:
        _formats.pop()


def save(
    fig, path: Path | str, formats: Sequence[str] | None = None, close: bool = True, check: bool = True
) -> list[Path]:
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


def upper_mask(n: int):
    """(n, n) boolean mask, True above the diagonal: the half of a symmetric matrix that is not drawn."""
    import numpy as np

    return np.triu(np.ones((n, n), dtype=bool), k=1)


def lower_triangle(ax, image, n: int) -> None:
    """Draw a symmetric ``n`` x ``n`` matrix once: clip ``image`` (``ax.imshow`` of it, row 0 on top) to the
    cells on and below the diagonal, hide the frame (it would outline the empty half) and keep the ticks."""
    from matplotlib.patches import Polygon

    pts = [(-0.5, -0.5)]
    for i in range(n):  # a staircase along the diagonal, top-left to bottom-right
        pts += [(i + 0.5, i - 0.5), (i + 0.5, i + 0.5)]
    pts += [(-0.5, n - 0.5)]
    clip = Polygon(pts, closed=True, transform=ax.transData, facecolor="none", edgecolor="none")
    image.set_clip_path(clip)
    for spine in ax.spines.values():
        spine.set_visible(False)
    ax.tick_params(length=0)
