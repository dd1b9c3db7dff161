"""Figures and files of the scenario study: whole-body views, atlas, gesture histogram, placement, PLY.

Views reuse :class:`sphri.analysis.render.LinkView` on the robot's rest-pose
mesh; every panel of one figure shares one colour scale (% of contact per cm^2).
Figures follow :mod:`sphri.figures` (print sizes, PNG + PDF + SVG, no clipped
or overlapping text).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from sphri import figures  # noqa: E402
from sphri.analysis.render import CMAP, PERCENT_PER_CM2, LinkView, _colourbar, _save, _triangle_colourbar, _vmax  # noqa: E402
from sphri.sessions.body import BodySurface  # noqa: E402
from sphri.types import GESTURES  # noqa: E402

#: (title, azimuth deg, elevation deg): the robot faces +x, its left is +y.
VIEWS = (("front", 0.0, 10.0), ("left", 90.0, 10.0), ("back", 180.0, 10.0), ("right", 270.0, 10.0), ("top", 0.0, 89.0))


def _finish(fig, title: str, path: str | Path, provenance: figures.Provenance | None) -> Path:
    """Title the figure (units typeset), draw the provenance banner (:func:`sphri.figures.mark`), write it to
    ``path`` (PNG, PDF, SVG) and close it."""
    with figures.style():
        fig.suptitle(figures.typeset(title), wrap=True)
        return _save(fig, path, provenance)


def body_view(body: BodySurface, faces: int = 20000) -> LinkView:
    """The whole robot's mesh for the 3-D views, simplified to about ``faces`` faces."""
    return LinkView(body.mesh, body.samples, target_faces=faces)


#: Surface without contact (density under NONE_SHARE of the colour scale's top) is drawn in this grey, apart from
#: the colour scale, whose lowest colour (CMAP_FLOOR along CMAP) is a visible yellow.
NO_CONTACT = (0.80, 0.80, 0.80, 1.0)
NONE_SHARE = 1e-3
CMAP_FLOOR = 0.15


def contact_colours(view: LinkView, density: np.ndarray, vmax: float, smooth: bool = False) -> np.ndarray:
    """(F, 4) RGBA per display face: the colour scale from 0 to ``vmax`` (% per cm^2) starting at CMAP_FLOOR, and
    :data:`NO_CONTACT` grey where the density is under NONE_SHARE x ``vmax`` (no contact).

    ``smooth``: (F, 3, 4) per face corner for Gouraud shading (:meth:`LinkView.corner_values`): a face with
    contact goes from corner to corner on the scale (never grey: at least its lowest colour), a face without
    contact is grey throughout."""
    vals = view.face_values(np.asarray(density)) * PERCENT_PER_CM2
    none = vals < NONE_SHARE * vmax
    scale = view.corner_values(vals, flat=none) if smooth else vals
    out = plt.get_cmap(CMAP)(CMAP_FLOOR + (1.0 - CMAP_FLOOR) * np.clip(scale / vmax, 0.0, 1.0))
    out[none] = NO_CONTACT
    return out


def _crop(ax, view: LinkView, azim_deg: float, elev_deg: float) -> None:
    """Limit a view's axes to the robot's projected extent (3 % margin), so that it fills its panel."""
    _, right, up = view._eye(azim_deg, elev_deg)
    x, y = view.display @ right, view.display @ up
    m = 0.03 * max(float(np.ptp(x)), float(np.ptp(y)))
    ax.set_xlim(float(x.min()) - m, float(x.max()) + m)
    ax.set_ylim(float(y.min()) - m, float(y.max()) + m)


def _contact_bar(fig, vmax: float, ax) -> None:
    """The colour bar of :func:`contact_colours`, saying what grey means."""
    from matplotlib.colors import ListedColormap

    cmap = ListedColormap(plt.get_cmap(CMAP)(np.linspace(CMAP_FLOOR, 1.0, 256)))
    _colourbar(fig, vmax, ax, cmap=cmap, label="contact, % per cm$^2$\ngrey: no contact")


def plot_views(
    view: LinkView,
    densities: dict[str, np.ndarray],
    path: str | Path,
    title: str,
    provenance: figures.Provenance | None = None,
    vmax: float | None = None,
) -> Path:
    """Rows: maps; columns: front, left, back, right, top, each cropped to the robot; one colour scale and bar
    (``vmax``, % per cm^2: the top of the scale, e.g. shared by every scenario's figure; default from these
    maps); colour smooth within faces, surface without contact grey (:func:`contact_colours`). Rows shrink so
    that the figure fits a page (:data:`sphri.figures.PAGE_HEIGHT_IN`)."""
    names = list(densities)
    vmax = vmax if vmax is not None and vmax > 0 else _vmax(list(densities.values()))
    with figures.style():
        fig, axes = figures.new_figure(
            "two", figures.fit_page(1.6 * len(names) + 0.7), nrows=len(names), ncols=len(VIEWS), squeeze=False
        )
        for r, n in enumerate(names):
            colours = contact_colours(view, densities[n], vmax, smooth=True)
            for c, (vt, az, el) in enumerate(VIEWS):
                ax = axes[r, c]
                view.draw(ax, None, az, vmax, elev_deg=el, colours=colours.copy())
                _crop(ax, view, az, el)
                if r == 0:
                    ax.set_title(vt)
            axes[r, 0].text(
                -0.06,
                0.5,
                figures.human(n).replace(": ", "\n", 1),
                transform=axes[r, 0].transAxes,
                rotation=90,
                ha="right",
                va="center",
            )
        _contact_bar(fig, vmax, axes)
        return _finish(fig, title, path, provenance)


#: A link whose surface's largest second moment is under ELONGATED times the next is round (a ball, a box): its
#: principal axis is set by sampling noise, and its chart runs along the vertical instead.
ELONGATED = 1.5


def chart_frame(points: np.ndarray, area: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(centre, axes)`` of the atlas chart of a link's rest-pose surface samples (world frame: the robot faces
    +x, its left is +y, up is +z; ``area`` weighs them): ``axes`` rows are the long axis and the directions at 0
    and +90 degrees around it.

    The long axis is the surface's first principal axis (the vertical for a round link, :data:`ELONGATED`), signed
    so that its largest component points up, forward or away from the robot's midplane (y = 0); 0 degrees is the
    front (+x, or up for a link lying front to back) and +90 degrees the side away from the midplane (the robot's
    left for a link on it). A link and its mirror image across the midplane (left and right arm) get the same
    chart, axes in the same orientation."""
    pts = np.asarray(points, dtype=np.float64)
    w = np.ones(len(pts)) if area is None else np.asarray(area, dtype=np.float64)
    centre = (pts * w[:, None]).sum(axis=0) / w.sum()
    _, sv, vt = np.linalg.svd((pts - centre) * np.sqrt(w)[:, None], full_matrices=False)
    along = vt[0] if len(sv) > 1 and sv[0] ** 2 >= ELONGATED * sv[1] ** 2 else np.array([0.0, 0.0, 1.0])
    side = -1.0 if centre[1] < -1e-2 else 1.0  # +y: left of the midplane (or on it)
    outward = along * np.array([1.0, side, 1.0])
    along = along * (1.0 if outward[np.argmax(np.abs(outward))] >= 0 else -1.0)
    ref = np.array([1.0, 0.0, 0.0]) if abs(along[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    zero = ref - (ref @ along) * along
    zero /= np.linalg.norm(zero)
    ninety = side * np.cross(along, zero)
    return centre, np.stack([along, zero, ninety])


def unroll(points: np.ndarray, frame: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``(angle_deg, along_cm)`` of points in a :func:`chart_frame`: angle around the long axis, position along it
    from the link's centre."""
    centre, axes = frame
    local = np.asarray(points, dtype=np.float64) - centre
    return np.degrees(np.arctan2(local @ axes[2], local @ axes[1])), local @ axes[0] * 100


def plot_atlas(
    body: BodySurface,
    density: np.ndarray,
    path: str | Path,
    title: str,
    provenance: figures.Provenance | None = None,
) -> Path:
    """One unrolled chart per body part: angle around its link's long axis vs position along it (cm), at the rest
    pose, in one orientation for every part (:func:`chart_frame`: 0 deg front, +90 deg away from the midplane,
    along up, forward or outward), so that a left part and its right counterpart read alike; each title gives the
    part's reachable area in cm^2 (the area the ranking and the placement count), as the figure's title says."""
    parts = body.parts
    cols = 5
    rows = int(np.ceil(len(parts) / cols))
    vals = np.asarray(density) * PERCENT_PER_CM2
    vmax = _vmax([density])
    world = body.samples.points_m
    area = body.samples.area_m2
    frame_of = {
        li: chart_frame(world[body.offset[li] : body.offset[li + 1]], area[body.offset[li] : body.offset[li + 1]])
        for li in range(len(body.links))
    }
    with figures.style():
        fig, axes = figures.new_figure(
            "two", figures.fit_page(1.45 * rows + 0.8), nrows=rows, ncols=cols, squeeze=False
        )
        for k, p in enumerate(parts):
            ax = axes[k // cols, k % cols]
            idx = np.flatnonzero(body.part == p)
            ang, along = unroll(world[idx], frame_of[int(body.link_of[idx[0]])])
            ax.scatter(
                ang, along, c=vals[idx], cmap=CMAP, vmin=0, vmax=vmax, s=2, marker="s", linewidths=0, rasterized=True
            )
            reach = float((body.samples.area_m2[idx] * body.reachable[idx]).sum()) * 1e4
            ax.set_title(f"{figures.human(p)}\n({reach:.0f} cm$^2$)")
            ax.set_xlim(-180, 180)
            ax.set_xticks([-180, 0, 180])
            if k % cols == 0:
                ax.set_ylabel("along (cm)")
            if k // cols == rows - 1 or k + cols >= len(parts):
                ax.set_xlabel("around (deg)")
        for k in range(len(parts), rows * cols):
            axes[k // cols, k % cols].set_axis_off()
        _colourbar(fig, vmax, ax=axes)
        return _finish(
            fig,
            f"{title} (around: 0 deg front, +90 deg outer side; along: up or outward; cm$^2$: reachable area)",
            path,
            provenance,
        )


def write_density_ply(view: LinkView, densities: dict[str, np.ndarray], path: str | Path) -> Path:
    """PLY of the rest-pose robot with one float vertex attribute per map (``density_<name>``, % per cm^2) and colours of the first."""
    first = next(iter(densities.values()))
    mesh = view.coloured_mesh(first, _vmax([first]))
    for name, d in densities.items():
        mesh.vertex_attributes[f"density_{name}"] = (view.vertex_values(d) * PERCENT_PER_CM2).astype(np.float32)
    path = Path(path)
    mesh.export(path, include_attributes=True)
    return path


def drawn_shares(coded: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per scenario and gesture: the share of the coded episodes whose session the generator drew with that
    gesture (``scenario``, ``gesture``, ``share``), for the histogram's drawn bars."""
    g = truth.reset_index(drop=True)["gesture"].to_numpy()[coded["session"].to_numpy()]
    rows = [
        (s, gest, float((g[idx] == gest).mean()))
        for s, idx in coded.groupby("scenario").indices.items()
        for gest in GESTURES
    ]
    return pd.DataFrame(rows, columns=["scenario", "gesture", "share"])


def plot_gesture_histogram(
    hist: pd.DataFrame,
    path: str | Path,
    title: str,
    provenance: figures.Provenance | None = None,
    drawn: pd.DataFrame | None = None,
) -> Path:
    """Per scenario, the share of coded episodes per gesture: expected (sum of probabilities, with its SD) and the
    argmax share; beside them, given ``drawn`` (:func:`drawn_shares`), the share the generator drew. The y-axis
    ends a little above the highest bar."""
    scen = list(pd.unique(hist["scenario"]))
    x = np.arange(len(GESTURES))
    w, off = (0.4, -0.2) if drawn is not None else (0.8, 0.0)  # bar width, offset of the coded bars
    top = 0.0
    with figures.style():
        fig, axes = figures.new_figure("two", 2.6, ncols=len(scen), sharey=True, squeeze=False)
        for i, s in enumerate(scen):
            ax = axes[0, i]
            h = hist[hist["scenario"] == s].set_index("gesture").loc[list(GESTURES)]
            n = max(int(h["n_episodes"].iloc[0]), 1)
            e, sd, c = h["expected"] / n, h["expected_sd"] / n, h["count"] / n
            ax.bar(x + off, e, width=w, color="#4c72b0", alpha=0.8, label="coded: expected (sum of probabilities)")
            ax.errorbar(x + off, e, yerr=sd, fmt="none", ecolor="black", capsize=1.5, lw=0.6)
            ax.plot(x + off, c, "o", color="#dd8452", ms=2.5, label="coded: argmax share")
            top = max(top, float((e + sd).max()), float(c.max()))
            if drawn is not None:
                d = drawn[drawn["scenario"] == s].set_index("gesture").reindex(list(GESTURES))["share"].fillna(0.0)
                ax.bar(x + 0.2, d, width=w, color="#8c8c8c", alpha=0.8, label="drawn by the generator")
                top = max(top, float(d.max()))
            ax.set_xticks(x, [figures.human(g) for g in GESTURES], rotation=90)
            ax.set_title(f"{figures.human(s)}\n({int(h['n_episodes'].iloc[0])} episodes)")
        axes[0, 0].set_ylim(0, min(1.0, 1.1 * top) if top > 0 else 1.0)
        axes[0, 0].set_ylabel("share of coded episodes")
        handles, labels = axes[0, 0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncol=3 if drawn is not None else 2)
        return _finish(fig, title, path, provenance)


def plot_placement(
    ranking: pd.DataFrame,
    table: pd.DataFrame,
    path: str | Path,
    title: str,
    provenance: figures.Provenance | None = None,
) -> Path:
    """Left: parts ranked by contact frames per cm^2 of mountable surface (pooled; the greedy's criterion), chosen
    ones red, parts not mountable hatched at the bottom with the reason. Right: capture per group."""
    chosen = set(str(table.loc[table["group"] == "all", "parts"].iat[0]).split(";"))
    out = ranking["excluded"].fillna("").astype(str) if "excluded" in ranking else pd.Series("", index=ranking.index)
    short = {"rotating": "joint", "narrower": "rod", "smaller": "small"}
    labels = [
        figures.human(p) + (f" ({short.get(e.split()[0], 'not mountable')})" if e else "")
        for p, e in zip(ranking["part"], out)
    ]
    with figures.style():
        fig, (a, b) = figures.new_figure(
            "two",
            figures.fit_page(0.12 * max(len(ranking), len(table)) + 1.4),
            ncols=2,
            gridspec_kw={"width_ratios": [1.3, 1]},
        )
        r = ranking.iloc[::-1]
        ex = out.iloc[::-1].to_numpy() != ""
        bars = a.barh(
            labels[::-1],
            r["frames_per_cm2"],
            color=["#c44e52" if p in chosen else "#bbbbbb" for p in r["part"]],
        )
        for bar, e in zip(bars, ex):
            if e:
                bar.set_hatch("//")
                bar.set_edgecolor("white")
        a.set_xlabel("contact frames per cm$^2$ (pooled; ranks and places)")
        a.set_title("red: placed; hatched: not mountable", loc="left")
        y = np.arange(len(table))
        b.barh(y - 0.2, 100 * table["captured"], height=0.4, label="in sample", color="#4c72b0")
        b.barh(y + 0.2, 100 * table["heldout_captured"], height=0.4, label="held-out participants", color="#55a868")
        b.set_yticks(
            y, [f"{figures.human(g)} ({100 * a_:.0f} % area)" for g, a_ in zip(table["group"], table["area_share"])]
        )
        b.invert_yaxis()
        b.set_xlim(0, 100)
        b.set_xlabel("contact frames captured (%)")
        b.set_title("placement under the budget", loc="left")
        fig.legend(*b.get_legend_handles_labels(), loc="outside lower right", ncol=2)
        return _finish(fig, title, path, provenance)


def plot_effects(
    effects: pd.DataFrame,
    scenarios: list[str],
    alpha: float,
    path: str | Path,
    title: str,
    provenance: figures.Provenance | None = None,
) -> Path:
    """Scenario x scenario matrix of the paired effect, drawn once (the cells below the diagonal: the matrix
    is symmetric and its diagonal empty): cells coloured by d_z (mean between-minus-within SWD over its SD
    across participants), text: the mean difference in mm, d_z and the Holm-corrected p (* <= alpha)."""
    n = len(scenarios)
    idx = {s: i for i, s in enumerate(scenarios)}
    dz = np.full((n, n), np.nan)
    text = [["" for _ in range(n)] for _ in range(n)]
    for r in effects.itertuples(index=False):
        i, j = idx[r.cond_a], idx[r.cond_b]
        p = "p<.001" if r.p_holm < 0.001 else f"p={r.p_holm:.3f}"
        t = f"{r.diff_swd_mm:+.0f} mm\nd$_z$={r.effect_dz:.2f}\n{p}{' *' if r.p_holm <= alpha else ''}"
        dz[i, j] = dz[j, i] = r.effect_dz
        text[i][j] = text[j][i] = t
    lim = max(float(np.nanmax(np.abs(dz))) if np.isfinite(dz).any() else 1.0, 0.5)
    k = n - 1  # rows 1..n-1 against columns 0..n-2 (n >= 2: a study tests two groups or more): a k x k triangle
    sub = dz[1:, :-1]
    names = [figures.human(s) for s in scenarios]
    with figures.style():
        side = float(np.clip(0.75 * k + 2.6, figures.ONE_COLUMN_IN, figures.TWO_COLUMN_IN))
        fig, ax = figures.new_figure(side, figures.fit_page(0.7 * k + 2.0))
        im = ax.imshow(np.ma.masked_array(sub, mask=figures.upper_mask(k)), cmap="RdBu_r", vmin=-lim, vmax=lim)
        figures.lower_triangle(ax, im, k)
        for i in range(k):
            for j in range(i + 1):
                t = text[i + 1][j]
                if t:
                    ax.text(
                        j,
                        i,
                        t,
                        ha="center",
                        va="center",
                        fontsize=figures.MIN_FONT_PT,
                        color="white" if abs(sub[i, j]) > 0.6 * lim else "black",
                    )
        ax.set_xticks(range(k), names[:-1], rotation=45, ha="right")
        ax.set_yticks(range(k), names[1:])
        _triangle_colourbar(fig, ax, im, k, "effect size d$_z$\n(between - within SWD)")
        ax.set_xlabel(f"Holm-corrected p (* <= {alpha:g})")
        return _finish(fig, title, path, provenance)


def part_colours(n: int) -> np.ndarray:
    """(n, 4) RGBA: distinct colours for ``n`` body parts (tab20, then tab20b, then around again)."""
    table = np.vstack([plt.get_cmap("tab20")(np.arange(20)), plt.get_cmap("tab20b")(np.arange(20))])
    return table[np.arange(n) % len(table)]


def plot_parts(
    view: LinkView,
    face_part: np.ndarray,
    areas_cm2: dict[str, float],
    path: str | Path,
    title: str,
) -> Path:
    """The robot from the front, left, back, right and top, each face in its body part's colour; the legend
    names each part with its area (cm^2)."""
    from matplotlib.patches import Patch

    names = list(areas_cm2)
    colour = dict(zip(names, part_colours(len(names))))
    grey = np.array([0.75, 0.75, 0.75, 1.0])
    faces = np.array([colour.get(p, grey) for p in face_part])
    with figures.style():
        ncol = 4 if len(names) > 12 else 3
        rows = int(np.ceil(len(names) / ncol))
        fig, axes = figures.new_figure("two", figures.fit_page(2.2 + 0.17 * rows), ncols=len(VIEWS), squeeze=False)
        for c, (vt, az, el) in enumerate(VIEWS):
            view.draw(axes[0, c], None, az, 1.0, elev_deg=el, colours=faces)
            axes[0, c].set_title(vt)
        handles = [Patch(color=colour[p], label=f"{p} ({areas_cm2[p]:,.0f} cm$^2$)") for p in names]
        fig.legend(handles=handles, loc="outside lower center", ncol=ncol)
        return _finish(fig, title, path, None)
