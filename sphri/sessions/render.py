"""Figures and files of the scenario study: whole-body views, atlas, gesture histogram, placement, PLY.

Views reuse :class:`sphri.analysis.render.LinkView` on the robot's rest-pose
mesh; every panel of one figure shares one colour scale (% of contact per cm^2).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import trimesh  # noqa: E402

from sphri.analysis.render import CMAP, PERCENT_PER_CM2, LinkView, _colourbar, _vmax  # noqa: E402
from sphri.sessions.body import BodySurface  # noqa: E402
from sphri.types import GESTURES  # noqa: E402

#: (title, azimuth deg, elevation deg): the robot faces +x, its left is +y.
VIEWS = (("front", 0.0, 10.0), ("left", 90.0, 10.0), ("back", 180.0, 10.0), ("right", 270.0, 10.0), ("top", 0.0, 89.0))


def _finish(fig, title: str, path: str | Path) -> Path:
    """Title the figure, write it to ``path`` (PNG) and close it."""
    fig.suptitle(title, fontsize=11)
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path


def body_view(body: BodySurface) -> LinkView:
    return LinkView(body.mesh, body.samples, target_faces=20000)


def plot_views(view: LinkView, densities: dict[str, np.ndarray], path: str | Path, title: str) -> Path:
    """Rows: maps; columns: front, left, back, right, top; one colour scale and bar."""
    names = list(densities)
    vmax = _vmax(list(densities.values()))
    fig, axes = plt.subplots(len(names), len(VIEWS), figsize=(2.0 * len(VIEWS) + 1.4, 2.6 * len(names) + 0.6),
                             dpi=100, squeeze=False)
    for r, n in enumerate(names):
        for c, (vt, az, el) in enumerate(VIEWS):
            ax = axes[r, c]
            view.draw(ax, densities[n], az, vmax, elev_deg=el)
            if r == 0:
                ax.set_title(vt, fontsize=10)
        axes[r, 0].text(-0.08, 0.5, n.replace("_", "\n", 1), transform=axes[r, 0].transAxes, rotation=90,
                        ha="right", va="center", fontsize=9)
    fig.subplots_adjust(left=0.05, right=0.88, bottom=0.02, top=0.93, wspace=0.02, hspace=0.08)
    _colourbar(fig, vmax, cax=fig.add_axes((0.9, 0.15, 0.018, 0.7)))
    return _finish(fig, title, path)


def plot_atlas(body: BodySurface, robot, density: np.ndarray, path: str | Path, title: str) -> Path:
    """One unrolled chart per body part: angle around the link's long axis vs position along it (cm)."""
    parts = body.parts
    cols = 6
    rows = int(np.ceil(len(parts) / cols))
    vals = np.asarray(density) * PERCENT_PER_CM2
    vmax = _vmax([density])
    fig, axes = plt.subplots(rows, cols, figsize=(2.3 * cols + 1.2, 2.3 * rows + 0.6), dpi=100, squeeze=False)
    axis_of = {}
    for li, name in enumerate(body.links):
        s = body.local[li]
        d = s.points_m - s.points_m.mean(axis=0)
        _, _, vt = np.linalg.svd(d, full_matrices=False)
        axis_of[li] = (s.points_m.mean(axis=0), vt)
    for k, p in enumerate(parts):
        ax = axes[k // cols, k % cols]
        idx = np.flatnonzero(body.part == p)
        li = int(body.link_of[idx[0]])
        centre, vt = axis_of[li]
        local = body.local[li].points_m[idx - body.offset[li]] - centre
        along = local @ vt[0] * 100
        ang = np.degrees(np.arctan2(local @ vt[2], local @ vt[1]))
        ax.scatter(ang, along, c=vals[idx], cmap=CMAP, vmin=0, vmax=vmax, s=6, marker="s", linewidths=0)
        ax.set_title(f"{p} ({body.samples.area_m2[idx].sum() * 1e4:.0f} cm$^2$)", fontsize=8)
        ax.set_xlim(-180, 180)
        ax.tick_params(labelsize=6)
        if k % cols == 0:
            ax.set_ylabel("along (cm)", fontsize=7)
        ax.set_xlabel("around (deg)", fontsize=7)
    for k in range(len(parts), rows * cols):
        axes[k // cols, k % cols].set_axis_off()
    fig.subplots_adjust(left=0.05, right=0.9, bottom=0.06, top=0.92, wspace=0.35, hspace=0.6)
    _colourbar(fig, vmax, cax=fig.add_axes((0.92, 0.15, 0.015, 0.7)))
    return _finish(fig, title, path)


def write_density_ply(view: LinkView, densities: dict[str, np.ndarray], path: str | Path) -> Path:
    """PLY of the rest-pose robot with one float vertex attribute per map (``density_<name>``, % per cm^2) and colours of the first."""
    first = next(iter(densities.values()))
    vals = view.vertex_values(first) * PERCENT_PER_CM2
    vmax = _vmax([first])
    rgba = (plt.get_cmap(CMAP)(np.clip(vals / vmax, 0, 1)) * 255).astype(np.uint8)
    mesh = trimesh.Trimesh(view.vertices, view.faces, vertex_colors=rgba, process=False, validate=False)
    for name, d in densities.items():
        mesh.vertex_attributes[f"density_{name}"] = (view.vertex_values(d) * PERCENT_PER_CM2).astype(np.float32)
    path = Path(path)
    mesh.export(path, include_attributes=True)
    return path


def plot_gesture_histogram(hist: pd.DataFrame, path: str | Path, title: str) -> Path:
    scen = list(pd.unique(hist["scenario"]))
    fig, axes = plt.subplots(1, len(scen), figsize=(2.6 * len(scen) + 0.5, 3.4), dpi=100, sharey=True, squeeze=False)
    x = np.arange(len(GESTURES))
    for i, s in enumerate(scen):
        ax = axes[0, i]
        h = hist[hist["scenario"] == s].set_index("gesture").loc[list(GESTURES)]
        n = max(int(h["n_episodes"].iloc[0]), 1)
        ax.bar(x, h["expected"] / n, color="#4c72b0", alpha=0.8, label="expected (sum of probabilities)")
        ax.errorbar(x, h["expected"] / n, yerr=h["expected_sd"] / n, fmt="none", ecolor="black", capsize=2, lw=0.8)
        ax.plot(x, h["count"] / n, "o", color="#dd8452", ms=4, label="argmax count")
        ax.set_xticks(x, GESTURES, rotation=60, fontsize=7)
        ax.set_title(f"{s}\n({int(h['n_episodes'].iloc[0])} episodes)", fontsize=8)
        ax.set_ylim(0, 1)
    axes[0, 0].set_ylabel("share of coded episodes")
    axes[0, -1].legend(fontsize=6, loc="upper right")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_placement(ranking: pd.DataFrame, table: pd.DataFrame, path: str | Path, title: str) -> Path:
    """Left: parts ranked by contact frames per cm^2 (pooled), chosen ones dark. Right: capture per group."""
    chosen = set(str(table.loc[table["group"] == "all", "parts"].iat[0]).split(";"))
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2), dpi=100, gridspec_kw={"width_ratios": [1.4, 1]})
    r = ranking.iloc[::-1]
    a.barh(r["part"], r["frames_per_cm2"], color=["#c44e52" if p in chosen else "#bbbbbb" for p in r["part"]])
    a.set_xlabel("contact frames per cm$^2$ (pooled)")
    a.tick_params(labelsize=7)
    a.set_title("body parts (red: the pooled placement)", fontsize=9)
    y = np.arange(len(table))
    b.barh(y - 0.2, 100 * table["captured"], height=0.4, label="in sample", color="#4c72b0")
    b.barh(y + 0.2, 100 * table["heldout_captured"], height=0.4, label="held-out participants", color="#55a868")
    for i, row in enumerate(table.itertuples()):
        b.text(1, i, f"{100 * row.area_share:.0f} % area", va="center", fontsize=6, color="white")
    b.set_yticks(y, table["group"], fontsize=7)
    b.invert_yaxis()
    b.set_xlim(0, 100)
    b.set_xlabel("contact frames captured (%)")
    b.legend(fontsize=7, loc="lower right")
    b.set_title("placement under the budget", fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_effects(effects: pd.DataFrame, scenarios: list[str], alpha: float, path: str | Path, title: str) -> Path:
    """Scenario x scenario matrix of the paired effect: cells coloured by d_z (mean between-minus-within SWD over
    its SD across participants), text: the mean difference in mm, d_z and the Holm-corrected p (* <= alpha)."""
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
    fig, ax = plt.subplots(figsize=(1.15 * n + 2.6, 0.95 * n + 1.8), dpi=100)
    im = ax.imshow(dz, cmap="RdBu_r", vmin=-lim, vmax=lim)
    for i in range(n):
        for j in range(n):
            if text[i][j]:
                ax.text(j, i, text[i][j], ha="center", va="center", fontsize=6.5,
                        color="white" if abs(dz[i, j]) > 0.6 * lim else "black")
    ax.set_xticks(range(n), scenarios, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(n), scenarios, fontsize=8)
    cb = fig.colorbar(im, ax=ax, shrink=0.8)
    cb.set_label("effect size d$_z$ (between - within SWD)")
    ax.set_title(title + f"\nHolm-corrected p (* <= {alpha:g})", fontsize=9)
    path = Path(path)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
    return path
