"""The requirement map: the required taxel pitch as a function of the skin's false-on rate.

A sweep over resolution and false-on rate (``+experiment=requirement_map``)
gives one curve (a :class:`sphri.report.analysis.GroupReport`) per false-on
rate. The false-on rate of a job is the probability, per taxel and frame,
that an untouched taxel reads on (:func:`sphri.report.sweep.false_on_rate`:
``noise.p * noise.salt_vs_pepper`` for salt-and-pepper noise in replace
mode). :func:`sphri.report.analysis.requirement_maps` lines the curves up by
rate (a :class:`sphri.report.analysis.RequirementMap`: part of the analysis),
for each set of the other group keys, whenever two or more rates are swept;
here :func:`map_rows` is ``requirement_map.csv`` (one row per rate and
resolution) and :func:`plot_map` its figure.

``false_on_per_frame`` is the expected number of false-on taxels in one
frame of an untouched skin, ``rate * n_taxels`` (touched taxels are on
already, so a frame with contact shows slightly fewer). A *dip* is a
resolution outside the tolerance of the best that is finer than a resolution
inside it (the first-crossing rule would have stopped before it); the
deepest one per rate is flagged, so the table shows the false-on count per
frame at which each rate's trough sits.

When the sweep also varies the skin-side ``filter`` (the maps differ only in
it), :func:`filter_rows` is ``filter_pairs.csv`` (one row per false-on rate,
filter and resolution: the accuracy of each (pitch, filter) pair) and
:func:`filter_text` the summary: per rate, the pair with the highest mean
accuracy and each filter's required pitch; and what each filter costs on
clean data (false-on rate 0): the mean accuracy without it minus with it, at
each resolution, paired over participants.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sphri.report.analysis import GroupReport, RequirementMap, SweepReport, noise_text

#: The group key of the skin-side filter.
FILTER_KEY = "filter"


def map_rows(report: SweepReport) -> list[dict[str, object]]:
    """``requirement_map.csv``: one row per (map, false-on rate, resolution)."""
    rows = []
    for m in report.maps:
        for rate, g in zip(m.rates, m.curves):
            rec, iv = g.recommended, g.pitch_interval_mm
            dip = m.dip_index(g)
            deficit, deficit_se = g.sat.deficit, g.sat.deficit_se
            for i, p in g.points.iterrows():
                rows.append(
                    {
                        "map": m.label,
                        "false_on_rate": rate,
                        "res": int(p["res"]),
                        "n_taxels": p["n_taxels"],
                        "pitch_mm": p["pitch_mm"],
                        "area_per_taxel_cm2": p["area_per_taxel_cm2"],
                        "accuracy_mean": p["accuracy_mean"],
                        "accuracy_se": p["accuracy_se"],
                        "accuracy_std": p["accuracy_std"],
                        "participants": int(p["n"]),
                        "seeds": int(p["n_seeds"]),
                        "false_on_per_frame": rate * float(p["n_taxels"]),
                        "deficit": float(deficit[i]),
                        "deficit_se": float(deficit_se[i]),
                        "bound": float(g.sat.bound[i]),
                        "outside_tolerance": bool(g.certificate.outside[i]),
                        "dip": dip == i,
                        "required": i == g.sat.index,
                        "required_res": int(rec["res"]),
                        "required_pitch_mm": rec["pitch_mm"],
                        "required_pitch_lo_mm": iv[0] if iv else float("nan"),
                        "required_pitch_hi_mm": iv[1] if iv else float("nan"),
                        "required_at_finest": bool(g.sat.at_finest),
                        "best_res": int(g.best["res"]),
                        "best_accuracy": g.best["accuracy_mean"],
                        "tolerance": g.sat.tolerance,
                        "tolerance_certifiable": g.certificate.certifiable,
                        "rerun_noise_per_participant": g.certificate.noise.per_participant,
                        "rerun_noise_curve": g.certificate.noise.curve,
                        "rerun_noise_source": g.certificate.noise.source,
                        "synthetic": bool(g.context["synthetic"]),
                    }
                )
    return rows


def map_text(report: SweepReport) -> list[str]:
    """The map in plain text: the required pitch per false-on rate, and where each curve dips."""
    lines = []
    for m in report.maps:
        lines.append("")
        lines.append("[requirement map" + (f": {m.label}" if m.label else "") + "]")
        for rate, g in zip(m.rates, m.curves):
            rec, iv = g.recommended, g.pitch_interval_mm
            ivt = f"{iv[0]:.1f}-{iv[1]:.1f} mm" if iv else "no interval"
            dip = m.dip_index(g)
            dtxt = ""
            if dip is not None:
                p = g.points.iloc[dip]
                dtxt = (
                    f"; dip at res {int(p['res'])} ({p['pitch_mm']:.1f} mm, {rate * float(p['n_taxels']):.1f} "
                    f"false-on taxels per frame, accuracy {p['accuracy_mean']:.3f})"
                )
            lines.append(
                f"  false-on {100 * rate:.3g} %: pitch at most {rec['pitch_mm']:.1f} mm ({ivt}), res "
                f"{int(rec['res'])}, certified within {g.sat.tolerance:.3f} (smallest certifiable "
                f"{g.certificate.certifiable:.3f}), best {g.best['accuracy_mean']:.3f} at "
                f"res {int(g.best['res'])}" + (" [finest point]" if g.sat.at_finest else "") + dtxt
            )
        lines.append("  " + noise_text(m.curves[0]) + f" (false-on {100 * m.rates[0]:g} %; each rate in the CSV)")
    return lines + filter_text(report)


def filter_sets(report: SweepReport) -> list[tuple[str, dict[str, RequirementMap]]]:
    """Maps that differ only in the ``filter`` key: (label of the other keys, filter -> map), two filters or more."""
    parts: dict[tuple[tuple[str, str], ...], dict[str, RequirementMap]] = {}
    for m in report.maps:
        if FILTER_KEY not in m.keys:
            continue
        other = tuple((k, v) for k, v in m.keys.items() if k != FILTER_KEY)
        parts.setdefault(other, {})[m.keys[FILTER_KEY]] = m
    return [(", ".join(f"{k}={v}" for k, v in o), maps) for o, maps in parts.items() if len(maps) >= 2]


def _rates(maps: dict[str, RequirementMap]) -> list[float]:
    """False-on rates every filter's map has."""
    common = set.intersection(*(set(m.rates) for m in maps.values()))
    return sorted(common)


def filter_rows(report: SweepReport) -> list[dict[str, object]]:
    """``filter_pairs.csv``: one row per (other keys, false-on rate, filter, resolution)."""
    rows: list[dict[str, object]] = []
    for label, maps in filter_sets(report):
        for rate in _rates(maps):
            curves = {f: m.curves[m.rates.index(rate)] for f, m in maps.items()}
            best_f, best_i = _best_pair(curves)
            for f, g in curves.items():
                for i, p in g.points.iterrows():
                    rows.append(
                        {
                            "others": label,
                            "false_on_rate": rate,
                            "filter": f,
                            "res": int(p["res"]),
                            "pitch_mm": p["pitch_mm"],
                            "accuracy_mean": p["accuracy_mean"],
                            "accuracy_se": p["accuracy_se"],
                            "required": i == g.sat.index,
                            "certified_tolerance": g.sat.tolerance,
                            "best_pair": (f, i) == (best_f, best_i),
                        }
                    )
    return rows


def _best_pair(curves: dict[str, GroupReport]) -> tuple[str, int]:
    """(filter, resolution index) of the highest mean accuracy among every filter's points at one rate."""
    return max(
        ((f, i) for f, g in curves.items() for i in range(len(g.points))),
        key=lambda t: (np.nan_to_num(curves[t[0]].points["accuracy_mean"].iloc[t[1]], nan=-np.inf), t[0] == "none"),
    )


def clean_cost(none: GroupReport, other: GroupReport) -> tuple[np.ndarray, np.ndarray]:
    """Per resolution of two clean-data curves (GroupReports over the same resolutions and participants): the
    paired mean over participants of accuracy without the filter minus with it, and its standard error."""
    from sphri.report.saturation import curve_stats

    a, b = np.asarray(none.accuracy), np.asarray(other.accuracy)
    if a.shape != b.shape:
        return np.full(a.shape[1], np.nan), np.full(a.shape[1], np.nan)
    st = curve_stats(a - b)
    return st.mean, st.se


def filter_text(report: SweepReport) -> list[str]:
    """Per false-on rate and filter: the required pitch, the accuracy there and the tolerance certified, the best
    accuracy and its pitch, the best (pitch, filter) pair marked; then each filter's cost on clean data."""
    lines: list[str] = []
    for label, maps in filter_sets(report):
        lines.append("")
        lines.append("[filters" + (f": {label}" if label else "") + "]")
        names = sorted(maps, key=lambda f: (f != "none", f))
        width = max(len("filter"), *(len(f) for f in names))
        lines.append(
            f"  {'false-on':>8}  {'filter':<{width}}  {'required pitch':>14}  {'accuracy':>8}  {'within':>6}  "
            f"{'best accuracy (pitch)':>22}"
        )
        for rate in _rates(maps):
            curves = {f: maps[f].curves[maps[f].rates.index(rate)] for f in names}
            bf, bi = _best_pair(curves)
            for f in names:
                g = curves[f]
                rec, best = g.recommended, g.best
                mark = f"   <- best pair: {g.points['pitch_mm'].iloc[bi]:.1f} mm + {f}" if f == bf else ""
                lines.append(
                    f"  {100 * rate:>7.3g}%  {f:<{width}}  {rec['pitch_mm']:>11.1f} mm  {rec['accuracy_mean']:>8.3f}  "
                    f"{g.sat.tolerance:>6.3f}  {best['accuracy_mean']:>11.3f} ({best['pitch_mm']:>5.1f} mm){mark}"
                )
        lines.append(
            "  (required pitch: the rule's requirement per filter; within: the tolerance it certifies; best pair: "
            "the highest mean accuracy over every filter and pitch at that rate, not a certified choice; every "
            "pair's accuracy: filter_pairs.csv)"
        )
        if "none" in maps and 0.0 in _rates(maps):
            clean = {f: maps[f].curves[maps[f].rates.index(0.0)] for f in names}
            for f in names:
                if f == "none":
                    continue
                cost, se = clean_cost(clean["none"], clean[f])
                if not np.isfinite(cost).any():
                    continue
                j = int(np.nanargmax(cost))
                res = int(clean[f].points["res"].iloc[j])
                lines.append(
                    f"  cost of {f} on clean data (false-on 0): {np.nanmean(cost):+.3f} mean over resolutions, "
                    f"largest {cost[j]:+.3f} +/- {se[j]:.3f} at res {res} (accuracy without minus with, paired)"
                )
    return lines


#: Largest deficit (points of accuracy) with its own colour step in the map; deeper cells share the last colour.
DEFICIT_STEPS = 20


def deficit_grid(m: RequirementMap) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """(deficit, pitch_mm, res) of a map: ``deficit[k, j]`` is rate k's best mean accuracy minus its mean accuracy
    at resolution ``res[j]``, in points of accuracy (NaN where not swept), ``pitch_mm[j]`` that resolution's pitch;
    resolutions sorted coarse to fine."""
    res = sorted({int(r) for g in m.curves for r in g.points["res"]})
    acc = np.full((len(m.rates), len(res)), np.nan)
    pitch = np.full(len(res), np.nan)
    for k, g in enumerate(m.curves):
        _fill(acc[k], pitch, res, g)
    best = np.nanmax(np.where(np.isfinite(acc), acc, -np.inf), axis=1, keepdims=True)
    return 100.0 * (best - acc), pitch, res


def _fill(acc: np.ndarray, pitch: np.ndarray, res: list[int], g: GroupReport) -> None:
    """Write the curve ``g``'s mean accuracy into ``acc`` and its pitch into ``pitch``, at its resolutions'
    places in ``res``."""
    for _, p in g.points.iterrows():
        j = res.index(int(p["res"]))
        acc[j] = p["accuracy_mean"]
        pitch[j] = p["pitch_mm"]


def _cells(pitch: np.ndarray, n_rates: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(the order sorting ``pitch``, the pitch cells' edges, the row centres, the row edges) of a map with
    ``n_rates`` rows."""
    order = np.argsort(pitch)
    return order, _edges(pitch[order]), np.arange(n_rates, dtype=float), np.arange(n_rates + 1, dtype=float) - 0.5


def _deficit_scale(deficit: np.ndarray, plt: Any) -> tuple[Any, Any, np.ndarray]:
    """(colour map, norm, colour-bar ticks) of deficits in points: one colour step per point up to
    :data:`DEFICIT_STEPS`, one more colour shared by every deeper cell."""
    from matplotlib.colors import BoundaryNorm

    deepest = float(np.nanmax(deficit)) if np.isfinite(deficit).any() else 1.0
    top = int(min(DEFICIT_STEPS, max(1, np.ceil(deepest))))
    bounds = np.arange(0, top + 1, dtype=float)
    cmap = plt.get_cmap("viridis_r", top + (1 if deepest > top else 0))
    norm = BoundaryNorm(bounds, cmap.N, extend="max" if deepest > top else "neither")
    return cmap, norm, bounds if top <= 10 else bounds[:: int(np.ceil(top / 10))]


def _pitch_axis(ax: Any, xe: np.ndarray, pitch: np.ndarray) -> None:
    """A log pitch x axis over the cell edges ``xe``, coarse on the left, finer to the right."""
    from sphri.report.figures import _nice_log_ticks

    ax.set_xscale("log")
    ax.set_xlim(xe[-1], xe[0])
    _nice_log_ticks(ax.xaxis, pitch[np.isfinite(pitch)])


def _edges(x: np.ndarray) -> np.ndarray:
    """Cell edges around increasing positive ``x`` on a log axis (geometric midpoints, half a step past the ends)."""
    lx = np.log(x)
    if len(x) == 1:
        return np.exp(lx[0] + np.array([-0.25, 0.25]))
    mid = (lx[1:] + lx[:-1]) / 2
    return np.exp(np.concatenate([[2 * lx[0] - mid[0]], mid, [2 * lx[-1] - mid[-1]]]))


def _symlog_from_zero(axis, positive: np.ndarray) -> None:
    """A symlog axis whose linear part runs from 0 to the decade below the smallest positive value (one decade
    wide), ticked at 0 and 1, 2, 5 x 10^k: the zero values are drawn, and the positive ones on a log scale."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    lo = float(positive.min()) if positive.size else 1.0
    hi = float(positive.max()) if positive.size else 1.0
    lin = 10.0 ** np.floor(np.log10(lo))
    ax = axis.axes
    ax.set_xscale("symlog", linthresh=lin, linscale=1.0)
    ax.set_xlim(-0.15 * lin, hi * 1.5)
    ticks = [0.0] + [
        m * 10.0**k
        for k in range(int(np.log10(lin)), int(np.ceil(np.log10(hi))) + 1)
        for m in (1, 2, 5)
        if lin <= m * 10.0**k <= hi * 1.5
    ]
    if len(ticks) > 7:
        ticks = [0.0] + [t for t in ticks[1:] if round(t / 10.0 ** np.floor(np.log10(t))) == 1]
    axis.set_major_locator(FixedLocator(ticks))
    axis.set_major_formatter(FuncFormatter(lambda x, _: f"{x:.3g}"))
    axis.set_minor_locator(NullLocator())
    axis.set_minor_formatter(NullFormatter())


def _tolerance_text(m: RequirementMap) -> str:
    tol = sorted({round(float(g.sat.tolerance), 3) for g in m.curves})
    return f"T = {tol[0]:.3f}" if len(tol) == 1 else f"T = {tol[0]:.3f}-{tol[-1]:.3f} by row"


def drawn_map(report: SweepReport) -> RequirementMap:
    """The map :func:`plot_map` draws: the unfiltered one when the sweep has a filter axis (the filters are
    :func:`plot_filter_map`'s), else the first."""
    return next((m for m in report.maps if m.keys.get(FILTER_KEY) == "none"), report.maps[0])


def plot_map(report: SweepReport, path: Path, marks: bool | None = None) -> Path | None:
    """The map's figure -> ``path`` (+ PDF, SVG); None without a map.

    Left: one discrete row per false-on rate (no interpolation between rates), each cell the deficit to that
    rate's best accuracy in points, one colour step per point up to :data:`DEFICIT_STEPS`; the required pitch
    per rate with its interval, every dip marked (v), the certified tolerance T in the title. Right: accuracy
    against false-on taxels per frame on a symlog axis, so the clean row (rate 0, no false-on taxel) is drawn at
    0; every dip marked.
    """
    from sphri import figures
    from sphri.report.figures import _finish

    if not report.maps:
        return None
    m = drawn_map(report)
    plt = figures.pyplot()
    with figures.style():
        fig, (ax, ax2) = figures.new_figure("two", 3.8, ncols=2, width_ratios=[1.25, 1.0])
        pitch, xe, y, ye = _deficit_cells(fig, ax, m, plt)
        _required_pitch_marks(ax, m, y, report.rule.ci)
        _deficit_axes(ax, m, pitch, xe, y, ye)
        _false_on_panel(ax2, m, plt)
        return _finish(fig, report, path, marks)


def _deficit_cells(
    fig: Any, ax: Any, m: RequirementMap, plt: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The map's cells on ``ax`` (one row per false-on rate, one colour step per point of deficit up to
    :data:`DEFICIT_STEPS`) and their colour bar; returns (pitch per resolution, pitch cell edges sorted, row
    centres, row edges)."""
    deficit, pitch, _ = deficit_grid(m)
    order, xe, y, ye = _cells(pitch, len(m.rates))
    cmap, norm, ticks = _deficit_scale(deficit, plt)
    mesh = ax.pcolormesh(xe, ye, np.ma.masked_invalid(deficit[:, order]), cmap=cmap, norm=norm, shading="flat")
    fig.colorbar(mesh, ax=ax, label="deficit to the row's best\n(points of accuracy)", ticks=ticks, format="%.0f")
    return pitch, xe, y, ye


def _required_pitch_marks(ax: Any, m: RequirementMap, y: np.ndarray, ci: float) -> None:
    """Each rate's required pitch with its ``ci`` interval at row ``y``, and its dip (v) when it has one."""
    req = np.array([float(g.recommended["pitch_mm"]) for g in m.curves])
    lo = np.array([g.pitch_interval_mm[0] if g.pitch_interval_mm else np.nan for g in m.curves])
    hi = np.array([g.pitch_interval_mm[1] if g.pitch_interval_mm else np.nan for g in m.curves])
    xerr = np.vstack([np.where(np.isfinite(lo), req - lo, 0.0), np.where(np.isfinite(hi), hi - req, 0.0)])
    ax.errorbar(
        req,
        y,
        xerr=np.maximum(xerr, 0.0),
        fmt="o",
        color="white",
        mec="black",
        ecolor="black",
        elinewidth=1.2,
        capsize=3,
        clip_on=False,
        zorder=5,
        label=f"required pitch ({ci:.0%} interval)",
    )
    dips = [(k, m.dip_index(g)) for k, g in enumerate(m.curves)]
    dips = [(k, d) for k, d in dips if d is not None]
    if dips:
        _red_marks(
            ax, [float(m.curves[k].points["pitch_mm"].iloc[d]) for k, d in dips], [y[k] for k, _ in dips], "v", 7, "dip"
        )


def _red_marks(ax: Any, x: list[float], y: list[float], marker: str, size: float, label: str) -> None:
    """Red ``marker`` points outlined in black above the map's cells and required-pitch marks."""
    ax.plot(x, y, marker, ms=size, color="red", mec="black", zorder=6, label=label)


def _deficit_axes(ax: Any, m: RequirementMap, pitch: np.ndarray, xe: np.ndarray, y: np.ndarray, ye: np.ndarray) -> None:
    """The map panel's axes: log pitch (coarse on the left), one labelled row per rate, legend and title."""
    _pitch_axis(ax, xe, pitch)
    ax.set_yticks(y, [f"{100 * r:.3g} %" for r in m.rates])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel("taxel pitch (mm; finer to the right)")
    ax.set_ylabel("false-on rate per taxel and frame\n(one row per rate)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2, framealpha=0.8)
    which = f" ({m.label})" if m.label else ""
    ax.set_title(f"required pitch{which}, certified within {_tolerance_text(m)}", loc="left")


def _false_on_panel(ax2: Any, m: RequirementMap, plt: Any) -> None:
    """Accuracy against false-on taxels per frame, one curve per rate (the clean one at 0 on a symlog axis),
    every dip marked (v)."""
    colors = plt.get_cmap("plasma")
    positive = []
    for k, (rate, g) in enumerate(zip(m.rates, m.curves)):
        x = rate * g.points["n_taxels"].to_numpy(float)
        acc = g.points["accuracy_mean"].to_numpy(float)
        color = "black" if rate <= 0 else colors(k / max(len(m.rates), 1))
        ax2.plot(x, acc, "s" if rate <= 0 else "o-", ms=4 if rate <= 0 else 3, color=color, label=f"{100 * rate:.3g} %")
        positive.extend(x[x > 0])
        dip = m.dip_index(g)
        if dip is not None:
            ax2.plot([x[dip]], [acc[dip]], "v", ms=8, color=color, mec="black")
    _symlog_from_zero(ax2.xaxis, np.asarray(positive, dtype=float))
    ax2.set_xlabel("false-on taxels per frame (symlog)")
    ax2.set_ylabel("mean accuracy")
    ax2.grid(True, which="major", alpha=0.3)
    ax2.legend(title="false-on rate", loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, framealpha=0.8)
    ax2.set_title("accuracy by false-on count\n(clean row at 0; v: dip)", loc="left")


def filter_grid(maps: dict[str, RequirementMap]) -> tuple[list[float], list[str], np.ndarray, np.ndarray, np.ndarray]:
    """(rates, filters, deficit, pitch_mm, required) of one filter set (:func:`filter_sets`): ``deficit[f, k, j]``
    is the best mean accuracy over every (pitch, filter) pair at rate k minus filter f's mean accuracy at
    resolution j, in points of accuracy (NaN where not swept); ``pitch_mm[j]`` sorted coarse to fine;
    ``required[f, k]`` the index j of filter f's required pitch at rate k."""
    rates = _rates(maps)
    names = sorted(maps, key=lambda f: (f != "none", f))
    res = sorted({int(r) for m in maps.values() for g in m.curves for r in g.points["res"]})
    acc = np.full((len(names), len(rates), len(res)), np.nan)
    pitch = np.full(len(res), np.nan)
    required = np.zeros((len(names), len(rates)), dtype=int)
    for a, f in enumerate(names):
        for k, rate in enumerate(rates):
            g = maps[f].curves[maps[f].rates.index(rate)]
            _fill(acc[a, k], pitch, res, g)
            required[a, k] = res.index(int(g.recommended["res"]))
    best = np.nanmax(np.where(np.isfinite(acc), acc, -np.inf), axis=(0, 2), keepdims=True)
    return rates, names, 100.0 * (best - acc), pitch, required


def plot_filter_map(report: SweepReport, path: Path, marks: bool | None = None) -> Path | None:
    """The (pitch, filter) figure -> ``path`` (+ PDF, SVG); None without a filter axis.

    One panel per filter (the first filter set of :func:`filter_sets`), one discrete row per false-on rate, each
    cell the deficit of that (pitch, filter) pair to the rate's best pair over every filter, in points of
    accuracy, one colour step per point up to :data:`DEFICIT_STEPS` (the same scale in every panel): a designer
    reads off which filter reaches the best at which pitch. Marked: each filter's required pitch by the
    certified rule (o) and the best pair per rate (*); the tolerance each filter's rule certifies in its
    panel's title."""
    from sphri import figures
    from sphri.report.figures import _finish

    sets = filter_sets(report)
    if not sets:
        return None
    label, maps = sets[0]
    rates, names, deficit, pitch, required = filter_grid(maps)
    if not rates:
        return None
    order, xe, y, ye = _cells(pitch, len(rates))
    cmap, norm, ticks = _deficit_scale(deficit, figures.pyplot())
    flat = np.where(np.isfinite(deficit), deficit, np.inf)
    best = [np.unravel_index(int(np.argmin(flat[:, k, :])), (len(names), len(pitch))) for k in range(len(rates))]
    with figures.style():
        fig, axes = figures.new_figure("two", 1.2 + 0.42 * len(rates), ncols=len(names), sharey=True, squeeze=False)
        axes = axes[0]
        mesh = None
        for a, (ax, f) in enumerate(zip(axes, names)):
            mesh = ax.pcolormesh(xe, ye, np.ma.masked_invalid(deficit[a][:, order]), cmap=cmap, norm=norm)
            ax.plot(pitch[required[a]], y, "o", ms=6, color="white", mec="black", zorder=5, label="required pitch")
            mine = [(k, j) for k, (b, j) in enumerate(best) if b == a]
            if mine:
                _red_marks(ax, [pitch[j] for _, j in mine], [y[k] for k, _ in mine], "*", 11, "best pair at the rate")
            _pitch_axis(ax, xe, pitch)
            tol = sorted({round(float(maps[f].curves[maps[f].rates.index(r)].sat.tolerance) * 100, 1) for r in rates})
            ttxt = f"T = {tol[0]:g}" if len(tol) == 1 else f"T = {tol[0]:g}-{tol[-1]:g}"
            ax.set_title(f"filter: {f}\ncertified {ttxt} pts", loc="left")
            ax.set_xlabel("taxel pitch (mm)")
        axes[0].set_yticks(y, [f"{100 * r:.3g} %" for r in rates])
        axes[0].set_ylim(ye[0], ye[-1])
        axes[0].set_ylabel("false-on rate per taxel and frame")
        bar_label = "deficit to the rate's best\n(pitch, filter) pair (points)"
        fig.colorbar(mesh, ax=list(axes), label=bar_label, ticks=ticks, format="%.0f")
        handles: dict[str, Any] = {}
        for ax in axes:
            for h, lab in zip(*ax.get_legend_handles_labels()):
                handles.setdefault(lab, h)
        fig.legend(list(handles.values()), list(handles.keys()), loc="outside lower center", ncol=2, framealpha=0.8)
        return _finish(fig, report, path, marks)
