"""The report's figures, in sphri's figure style (:mod:`sphri.figures`: print sizes, fonts of at
least 7 pt, PNG + PDF + SVG, no clipped or overlapping text).

- :func:`plot_curves`: accuracy and macro F1 against resolution for each
  group, mean with a +/- std band over participants, x axis the taxel pitch
  along the link (mm, log scale, fine to the right) with taxels per 24 cm on
  top and the taxel count below when every group shares it; the saturation
  point (star) with its bootstrap interval as a horizontal error bar through it.
- :func:`plot_recall`: per-gesture recall against resolution, one panel per
  group, each gesture's own saturation point marked.
- :func:`plot_bootstrap`: how often each resolution was chosen by the rule
  over the bootstrap resamples.
- :func:`plot_tornado`: a sensitivity sweep's saturation pitch per
  assumption variant with its bootstrap interval, the reference as a line.

Every figure carries "SYNTHETIC DATA" and the sweep id in its top margin when
the runs did (:class:`sphri.figures.Provenance`; ``marks=false`` turns it off).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sphri import figures
from sphri.report.analysis import CHANCE, GroupReport, SweepReport
from sphri.types import GESTURES

if TYPE_CHECKING:
    from matplotlib.axis import Axis
    from matplotlib.figure import Figure

#: The reference study's saturation: 18 taxels along the 24 cm arm.
STUDY_TAXELS_PER_24CM = 18.0


def _provenance(report: SweepReport, marks: bool | None) -> figures.Provenance:
    """The SYNTHETIC banner and sweep id: shown for (partly) synthetic runs unless ``marks`` says otherwise."""
    return figures.Provenance(synthetic=report.synthetic != "none", ids=f"sweep {report.sweep.sweep_id}", show=marks)


def _finish(fig: Figure, report: SweepReport, path: Path, marks: bool | None) -> Path:
    figures.mark(fig, _provenance(report, marks))
    figures.save(fig, path)
    return path


def _x(report: SweepReport) -> tuple[str, str]:
    """(column, label) of the x axis shared by all groups."""
    if report.groups and all(g.has_pitch for g in report.groups):
        return "pitch_u_mm", "taxel pitch along the link (mm; finer to the right)"
    return "n_taxels", "taxels (log scale)"


def _shared_count_map(report: SweepReport) -> tuple[np.ndarray, np.ndarray] | None:
    """(pitch_u, n_taxels) sorted by pitch when every group has the same mapping, else None."""
    pairs = None
    for g in report.groups:
        p = g.points[["pitch_u_mm", "n_taxels"]].to_numpy(float)
        p = p[np.argsort(p[:, 0])]
        if not np.all(np.isfinite(p)) or np.any(np.diff(p[:, 0]) <= 0):
            return None
        key = {(round(a, 6), int(b)) for a, b in p}
        if pairs is None:
            pairs = key
        elif key != pairs and not (key <= pairs or pairs <= key):
            return None
        else:
            pairs |= key
    if not pairs or len(pairs) < 2:
        return None
    arr = np.array(sorted(pairs), dtype=float)
    if np.any(np.diff(arr[:, 0]) <= 0) or np.any(np.diff(arr[:, 1]) > 0):  # count must fall as pitch grows
        return None
    return arr[:, 0], arr[:, 1]


#: y limits of a 0-1 metric: a small margin below 0 and above 1, so that a curve at 0 or 1 is drawn clear of
#: the axis line instead of vanishing into it.
Y_UNIT = (-0.04, 1.04)


def _log_limits(values: np.ndarray, margin: float = 0.04) -> tuple[float, float]:
    """(lo, hi) of a log axis spanning ``values`` with ``margin`` of the log span (or x1.1) on each side."""
    lo, hi = float(values.min()), float(values.max())
    pad = max(np.log(hi / lo) * margin, np.log(1.1)) if hi > lo else np.log(1.5)
    return lo * np.exp(-pad), hi * np.exp(pad)


def _all(report: SweepReport, col: str) -> np.ndarray:
    v = np.concatenate([g.points[col].to_numpy(float) for g in report.groups])
    return v[np.isfinite(v) & (v > 0)]


def _nice_log_ticks(axis: Axis, values: np.ndarray) -> None:
    """Plain-number ticks (1, 2, 5 x 10^k) spanning ``values`` on a log axis."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

    if values.size == 0:
        return
    lo, hi = values.min(), values.max()
    ticks = [
        m * 10.0**k for k in range(int(np.floor(np.log10(lo))) - 1, int(np.ceil(np.log10(hi))) + 1) for m in (1, 2, 5)
    ]
    ticks = [x for x in ticks if lo / 1.5 <= x <= hi * 1.5]
    if sum(lo <= x <= hi for x in ticks) < 2:  # a short sweep: label its ends as well
        ticks = sorted({*ticks, float(f"{lo:.3g}"), float(f"{hi:.3g}")})
    axis.set_major_locator(FixedLocator(ticks))
    axis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:.3g}"))
    axis.set_minor_formatter(NullFormatter())


def _interp_extrap(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolation with linear extrapolation past both ends (``xp`` increasing).

    A secondary axis needs exact inverse functions over the whole view, also
    beyond the first and last sweep points, so clamping (``np.interp``) will not do.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.interp(x, xp, fp)
    lo_slope = (fp[1] - fp[0]) / (xp[1] - xp[0])
    hi_slope = (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
    y = np.where(x < xp[0], fp[0] + (x - xp[0]) * lo_slope, y)
    return np.where(x > xp[-1], fp[-1] + (x - xp[-1]) * hi_slope, y)


def _count_ticks(axis: Axis, pitch: np.ndarray, count: np.ndarray, max_ticks: int = 9) -> None:
    """Ticks at the sweep's taxel counts, thinned so that labels do not overlap on the log pitch axis."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    order = np.argsort(-pitch)  # left (coarse) to right (fine)
    keep, last = [], None
    span = np.log(pitch.max() / pitch.min()) if pitch.size > 1 else 1.0
    for i in order:
        if last is None or np.log(last / pitch[i]) >= span / max_ticks:
            keep.append(count[i])
            last = pitch[i]
    axis.set_major_locator(FixedLocator(keep))
    axis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:.0f}"))
    axis.set_minor_locator(NullLocator())
    axis.set_minor_formatter(NullFormatter())


#: Groups above which the curves' legend names each saturation star once for all and the figure grows with it.
MANY_GROUPS = 4


def _group_colors(report: SweepReport, plt: Any) -> Any:
    """The colour map of the report's groups (``colors(i % colors.N)`` is group i's colour in every figure):
    ten colours up to ten groups, twenty beyond."""
    return plt.get_cmap("tab10" if len(report.groups) <= 10 else "tab20")


def plot_curves(report: SweepReport, path: Path, marks: bool | None = None) -> Path:
    """Accuracy and macro F1 against resolution (two panels) -> ``path`` (+ PDF, SVG)."""
    plt = figures.pyplot()
    xcol, xlabel = _x(report)
    n = len(report.groups)
    # many groups (a map's rates x filters): one legend row per two curves below the panels, so the figure grows
    legend_rows = int(np.ceil((n + 3) / 2)) if n > MANY_GROUPS else 0
    with figures.style():
        fig, axes = figures.new_figure("two", 5.6 + 0.16 * max(legend_rows - 4, 0), nrows=2, sharex=True)
        colors = _group_colors(report, plt)
        for i, g in enumerate(report.groups):
            _draw_curve(axes, g, xcol, colors(i % colors.N))
        xs = _all(report, xcol)
        _metric_axes(axes, xs)
        if all(not np.isfinite(g.points["macro_f1_mean"].to_numpy(float)).any() for g in report.groups):
            axes[1].text(
                0.5,
                0.5,
                "no macro F1 per participant in these runs (swept with tracking.artifacts=false: no per-participant table)",
                transform=axes[1].transAxes,
                ha="center",
                va="center",
                wrap=True,
            )
        extra = _pitch_axes(report, axes, xs) if xcol == "pitch_u_mm" else []
        axes[1].set_xlabel(xlabel)
        _curves_legend(report, fig, axes, extra)
        axes[0].set_title("accuracy against skin resolution", loc="left")
        return _finish(fig, report, path, marks)


def _draw_curve(axes: Any, g: GroupReport, xcol: str, color: Any) -> None:
    """One group's accuracy and macro F1 (mean +/- std band) on ``axes`` and its saturation point (a star on
    the accuracy panel, its bootstrap interval a horizontal error bar through it)."""
    x = g.points[xcol].to_numpy(float)
    for ax, metric in zip(axes, ("accuracy", "macro_f1")):
        m = g.points[f"{metric}_mean"].to_numpy(float)
        s = g.points[f"{metric}_std"].to_numpy(float)
        ax.plot(x, m, "o-", color=color, label=f"{g.label} (n={g.sat.n_participants})")
        ax.fill_between(x, m - s, m + s, color=color, alpha=0.15, lw=0)
    rec = g.recommended
    x0, y0 = float(rec[xcol]), float(rec["accuracy_mean"])
    xerr = None
    if g.sat.interval is not None:  # the bootstrap interval: an error bar through the saturation point
        ends = g.points[xcol].iloc[list(g.sat.interval)].to_numpy(float)
        xerr = [[max(x0 - ends.min(), 0.0)], [max(ends.max() - x0, 0.0)]]
    axes[0].errorbar(
        [x0],
        [y0],
        xerr=xerr,
        fmt="*",
        ms=11,
        color=color,
        mec="black",
        ecolor=color,
        elinewidth=2.0,
        capsize=3,
        zorder=5,
        label=f"saturation: {g.label}",
    )


def _metric_axes(axes: Any, xs: np.ndarray) -> None:
    """Chance line, labels, 0-1 limits, grid and the log x axis spanning ``xs`` on both panels."""
    for ax, name in zip(axes, ("accuracy", "macro F1")):
        ax.axhline(CHANCE, color="0.4", ls="--", lw=0.8, label=f"chance ({CHANCE:.3g})")
        ax.set_ylabel(f"{name}\n(mean +/- std over participants)")
        ax.set_ylim(*Y_UNIT)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xscale("log")
        _nice_log_ticks(ax.xaxis, xs)
        if xs.size:
            ax.set_xlim(*_log_limits(xs))


def _pitch_axes(report: SweepReport, axes: Any, xs: np.ndarray) -> list[tuple[Any, str]]:
    """On a pitch x axis (``xs``, mm): the study's pitch as a line, finer to the right, taxels per 24 cm on
    top and the taxel count below when every group shares it; returns the reference lines for the legend
    (named there, never as text over the data)."""
    from matplotlib.lines import Line2D

    extra = []
    study = 240.0 / STUDY_TAXELS_PER_24CM
    inside = xs.size > 0 and xs.min() / 1.15 <= study <= xs.max() * 1.15
    for ax in axes:
        if inside:
            ax.axvline(study, color="0.2", ls=":", lw=1.0)
    extra.append(
        (
            Line2D([], [], color="0.2", ls=":", lw=1.0),
            f"study: 18 taxels / 24 cm ({study:.1f} mm)" + ("" if inside else ", outside the sweep"),
        )
    )
    lo, hi = _log_limits(xs) if xs.size else (None, None)
    axes[0].set_xlim(hi, lo)  # finer to the right
    top = axes[0].secondary_xaxis(
        "top", functions=(lambda p: 240.0 / np.maximum(p, 1e-9), lambda t: 240.0 / np.maximum(t, 1e-9))
    )
    top.set_xlabel("taxels per 24 cm along the link (the study's axis)")
    _nice_log_ticks(top.xaxis, 240.0 / xs)
    cmap = _shared_count_map(report)
    if cmap is not None:
        _count_axis(axes[1], cmap)
    return extra


def _count_axis(ax: Any, cmap: tuple[np.ndarray, np.ndarray]) -> None:
    """The taxel count below ``ax``'s pitch axis, from the shared (pitch, count) map ``cmap``."""
    lp, n = np.log(cmap[0]), np.log(cmap[1])

    def to_count(p: np.ndarray) -> np.ndarray:
        return np.exp(_interp_extrap(np.log(np.maximum(p, 1e-9)), lp, n))

    def to_pitch(c: np.ndarray) -> np.ndarray:
        return np.exp(_interp_extrap(-np.log(np.maximum(c, 1e-9)), -n, lp))

    bottom = ax.secondary_xaxis(-0.32, functions=(to_count, to_pitch))
    bottom.set_xlabel("taxel count (at the sweep's points)")
    _count_ticks(bottom.xaxis, cmap[0], cmap[1])


def _curves_legend(report: SweepReport, fig: Figure, axes: Any, extra: list[tuple[Any, str]]) -> None:
    """One legend below the panels (it never hides data): the curves, saturation points and ``extra``
    reference lines, in as many columns as the longest label leaves room for."""
    from matplotlib.lines import Line2D

    handles, labels = axes[0].get_legend_handles_labels()
    if len(report.groups) > MANY_GROUPS:  # one entry for every group's saturation star (its colour is its curve's)
        keep = [i for i, lab in enumerate(labels) if not lab.startswith("saturation")]
        handles = [handles[i] for i in keep] + [Line2D([], [], marker="*", ls="", ms=11, color="0.6", mec="black")]
        ci = f", {report.rule.ci:.0%} interval" if any(g.sat.interval is not None for g in report.groups) else ""
        labels = [labels[i] for i in keep] + [f"saturation (curve's colour{ci})"]
    handles += [h for h, _ in extra]
    labels += [lab for _, lab in extra]
    if len(report.groups) <= MANY_GROUPS and any(g.sat.interval is not None for g in report.groups):
        labels = [
            f"{lab} ({report.rule.ci:.0%} bootstrap interval)" if lab.startswith("saturation") else lab
            for lab in labels
        ]
    # outside the panels: the legend never hides data
    # as many columns as the longest label leaves room for (7 pt text: about 0.052 in per character)
    fits = int(0.95 * fig.get_figwidth() / (0.052 * max(map(len, labels)) + 0.45))
    fig.legend(handles, labels, loc="outside lower center", ncol=int(np.clip(fits, 1, 4)))


def plot_recall(report: SweepReport, path: Path, max_groups: int = 6, marks: bool | None = None) -> Path | None:
    """Per-gesture recall against resolution, one panel per group (first ``max_groups``) -> ``path``.

    None when no job logged per-gesture recall (``per_participant.csv`` missing).
    """
    if not any(g.gesture_sat for g in report.groups):
        return None
    plt = figures.pyplot()
    xcol, xlabel = _x(report)
    groups = report.groups[:max_groups]
    ncol = min(2, len(groups))
    nrow = int(np.ceil(len(groups) / ncol))
    with figures.style():
        fig, axes = figures.new_figure(
            "two" if ncol > 1 else "one", 2.4 * nrow + 0.9, nrows=nrow, ncols=ncol, squeeze=False, sharey=True
        )
        colors = plt.get_cmap("tab10")
        for ax, g in zip(axes.ravel(), groups):
            x = g.points[xcol].to_numpy(float)
            for k, gest in enumerate(GESTURES):
                y = g.points[f"recall_{gest}"].to_numpy(float)
                if not np.isfinite(y).any():
                    continue
                ax.plot(x, y, "-", color=colors(k), label=figures.human(gest))
                s = g.gesture_sat.get(gest)
                if s is not None:
                    ax.plot([x[s.index]], [y[s.index]], "o", color=colors(k), mec="black")
            ax.set_xscale("log")
            xf = x[np.isfinite(x) & (x > 0)]
            _nice_log_ticks(ax.xaxis, xf)
            if xf.size:
                lo, hi = _log_limits(xf)
                ax.set_xlim(*((hi, lo) if xcol == "pitch_u_mm" else (lo, hi)))
            ax.set_ylim(*Y_UNIT)
            ax.set_title(g.label, loc="left")
            ax.set_xlabel(xlabel.split(" (")[0] + (" (mm)" if xcol == "pitch_u_mm" else ""))
            ax.grid(True, which="both", alpha=0.3)
        for ax in axes[:, 0]:
            ax.set_ylabel("recall (mean over participants)")
        for ax in axes.ravel()[len(groups) :]:
            ax.set_visible(False)
        handles, labels = axes[0, 0].get_legend_handles_labels()
        if handles:
            fig.legend(
                handles,
                labels,
                loc="outside lower center",
                ncol=8 if ncol > 1 else 4,
                title="gesture (dot: its saturation point)",
            )
        return _finish(fig, report, path, marks)


def plot_bootstrap(report: SweepReport, path: Path, marks: bool | None = None) -> Path | None:
    """Share of bootstrap resamples choosing each resolution, per group -> ``path`` (None without any bootstrap)."""
    groups = [g for g in report.groups if g.sat.boot_index is not None and len(g.points) > 1]
    if not groups:
        return None
    plt = figures.pyplot()
    many = len(groups) > MANY_GROUPS
    with figures.style():
        fig, ax = figures.new_figure("two", 2.4 + (0.16 * np.ceil(len(groups) / 3) if many else 0.0))
        colors = _group_colors(report, plt)
        width = 0.8 / len(groups)
        union = sorted({int(r) for g in groups for r in g.points["res"]})
        where = {r: k for k, r in enumerate(union)}
        for i, g in enumerate(groups):
            boot = g.sat.boot_index
            assert boot is not None  # groups without one are left out above
            counts = np.bincount(boot, minlength=len(g.points)) / len(boot)
            pos = np.array([where[int(r)] for r in g.points["res"]]) + (i - (len(groups) - 1) / 2) * width
            ax.bar(pos, counts, width=width, color=colors(report.groups.index(g) % colors.N), label=g.label)
        step = max(1, int(np.ceil(len(union) / 20)))
        ax.set_xticks(np.arange(len(union))[::step], [str(r) for r in union][::step])
        ax.set_xlabel("taxels along the link (layout.res)")
        ax.set_ylabel("share of resamples")
        if many:  # below the panel, in columns: inside it, a long list would hide the bars
            fig.legend(loc="outside lower center", ncol=3)
        else:
            ax.legend(loc="upper left")
        ax.grid(True, axis="y", alpha=0.3)
        ax.set_title("saturation point over bootstrap resamples of participants", loc="left")
        return _finish(fig, report, path, marks)


def plot_tornado(report: SweepReport, path: Path, marks: bool | None = None) -> Path | None:
    """Saturation pitch (mm) per assumption variant with its bootstrap interval, one panel per set of other
    keys, variants ordered by their shift from the reference (largest on top) -> ``path``; None without variants."""
    if not report.sensitivity:
        return None
    n = len(report.sensitivity)
    height = max(len(s.variants) for s in report.sensitivity)
    with figures.style():
        fig, axes = figures.new_figure("two", 1.4 + 0.22 * height, ncols=n, squeeze=False)
        pitch_all = True
        for ax, sens in zip(axes[0], report.sensitivity):
            pitch = all(g.has_pitch for g in sens.variants)
            pitch_all &= pitch
            col = "pitch_mm" if pitch else "n_taxels"
            for y, g in enumerate(reversed(sens.variants)):
                v = float(g.recommended[col])
                iv = g.pitch_interval_mm if pitch else None
                is_ref = sens.reference is g
                color = "black" if is_ref else ("firebrick" if g.sat.at_finest else "tab:blue")
                if iv is not None:
                    ax.plot(iv, [y, y], "-", color=color, lw=5, alpha=0.35, solid_capstyle="butt")
                ax.plot([v], [y], "o", color=color)
            ax.set_yticks(
                range(len(sens.variants)),
                [figures.human(g.keys.get("variant", g.label)) for g in reversed(sens.variants)],
            )
            if sens.reference is not None:
                ax.axvline(float(sens.reference.recommended[col]), color="black", ls="--", lw=0.8)
            ax.set_xlabel("saturation pitch (mm)" if pitch else "taxels at saturation")
            ax.grid(True, axis="x", alpha=0.3)
            ax.set_title(sens.label or "assumption variants", loc="left")
        if pitch_all:
            fig.supxlabel(
                f"dot: the rule ({report.rule.primary_tolerance.describe()}, or what each variant's data certify "
                f"if larger);\nbar: {report.rule.ci:.0%} "
                "bootstrap interval; dashed: reference; red: finest point swept",
                color="0.3",
                fontsize=figures.MIN_FONT_PT,
            )
        return _finish(fig, report, path, marks)
