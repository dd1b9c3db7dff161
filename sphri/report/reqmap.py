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
                f"  false-on {100 * rate:g} %: pitch at most {rec['pitch_mm']:.1f} mm ({ivt}), res "
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
                    f"  {100 * rate:>7g}%  {f:<{width}}  {rec['pitch_mm']:>11.1f} mm  {rec['accuracy_mean']:>8.3f}  "
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


def plot_map(report: SweepReport, path: Path, marks: bool | None = None) -> Path | None:
    """Accuracy contours over pitch x false-on rate with the required pitch per rate (and its interval), and
    accuracy against false-on taxels per frame -> ``path`` (+ PDF, SVG); None without a map."""
    from sphri import figures
    from sphri.report.figures import _finish, _nice_log_ticks

    if not report.maps:
        return None
    m = report.maps[0]
    plt = figures.pyplot()
    with figures.style():
        fig, (ax, ax2) = figures.new_figure("two", 3.2, ncols=2, width_ratios=[1.25, 1.0])
        res = sorted({int(r) for g in m.curves for r in g.points["res"]})
        z = np.full((len(m.rates), len(res)), np.nan)
        pitch = np.full(len(res), np.nan)
        for k, g in enumerate(m.curves):
            for _, p in g.points.iterrows():
                j = res.index(int(p["res"]))
                z[k, j] = p["accuracy_mean"]
                pitch[j] = p["pitch_mm"]
        y = np.arange(len(m.rates), dtype=float)
        finite = np.isfinite(z)
        levels = np.linspace(np.nanmin(z), np.nanmax(z), 9) if np.nanmax(z) > np.nanmin(z) else 3
        cs = ax.contourf(pitch, y, np.where(finite, z, np.nanmin(z)), levels=levels, cmap="viridis")
        fig.colorbar(cs, ax=ax, label="mean accuracy", format="%.2f")
        req = np.array([float(g.recommended["pitch_mm"]) for g in m.curves])
        lo = np.array([g.pitch_interval_mm[0] if g.pitch_interval_mm else np.nan for g in m.curves])
        hi = np.array([g.pitch_interval_mm[1] if g.pitch_interval_mm else np.nan for g in m.curves])
        xerr = np.vstack([np.where(np.isfinite(lo), req - lo, 0.0), np.where(np.isfinite(hi), hi - req, 0.0)])
        ax.plot(req, y, "-", color="white", lw=1.5, clip_on=False, zorder=4)
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
            label=f"required pitch ({report.rule.ci:.0%} interval)",
        )
        ax.set_xscale("log")
        _nice_log_ticks(ax.xaxis, pitch[np.isfinite(pitch)])
        ax.invert_xaxis()
        ax.set_yticks(y, [f"{100 * r:g} %" for r in m.rates])
        ax.set_xlabel("taxel pitch (mm; finer to the right)")
        ax.set_ylabel("false-on rate per taxel and frame\n(rows evenly spaced)")
        ax.legend(loc="lower left", framealpha=0.8)
        ax.set_title("accuracy and the required pitch", loc="left")

        colors = plt.get_cmap("plasma")
        drawn = False
        for k, (rate, g) in enumerate(zip(m.rates, m.curves)):
            if rate <= 0:
                continue
            x = rate * g.points["n_taxels"].to_numpy(float)
            acc = g.points["accuracy_mean"].to_numpy(float)
            color = colors(k / max(len(m.rates), 1))
            ax2.plot(x, acc, "o-", ms=3, color=color, label=f"{100 * rate:g} %")
            dip = m.dip_index(g)
            if dip is not None:
                ax2.plot([x[dip]], [acc[dip]], "v", ms=8, color=color, mec="black")
            drawn = True
        ax2.set_xscale("log")
        ax2.set_xlabel("false-on taxels per frame (rate x taxels)")
        ax2.set_ylabel("mean accuracy")
        ax2.grid(True, which="both", alpha=0.3)
        if drawn:
            ax2.legend(title="false-on rate", loc="lower right", ncol=2)
        ax2.set_title("accuracy and false-on count (v: dip)", loc="left")
        return _finish(fig, report, path, marks)
