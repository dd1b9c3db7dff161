"""Figures of the skin design (:mod:`sphri.sessions.skin`): the budget curve and the chosen skin on the robot."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sphri import figures
from sphri.sessions.render import _finish


def plot_budget_curve(
    curves: pd.DataFrame,
    pitch_mm: float,
    budget_cm2: float,
    path: str | Path,
    title: str,
    provenance: figures.Provenance | None = None,
) -> Path:
    """Captured share of contact frames against skin area (cm^2; top axis: taxels at ``pitch_mm``).

    Left: pooled, in-sample and held-out (mean +/- SD over the splits). Right: in-sample per scenario.
    The dotted line marks the study's budget."""
    with figures.style():
        fig, (a, b) = figures.new_figure("two", 2.9, ncols=2, sharey=True)
        pooled = curves[curves["scenario"] == "all"]
        for kind, colour, label in (
            ("in_sample", "#4c72b0", "in sample"),
            ("heldout", "#55a868", "held-out participants"),
        ):
            c = pooled[pooled["curve"] == kind]
            if not len(c):
                continue
            a.step(c["area_cm2"], 100 * c["captured"], where="post", color=colour, label=label)
            sd = c["captured_sd"].to_numpy(float)
            if np.isfinite(sd).any():
                a.fill_between(
                    c["area_cm2"],
                    100 * (c["captured"] - sd),
                    100 * np.minimum(c["captured"] + sd, 1),
                    step="post",
                    color=colour,
                    alpha=0.2,
                    linewidth=0,
                )
        a.set_title("pooled over scenarios", loc="left")
        a.set_ylabel("contact frames captured (%)")
        a.legend(loc="lower right")
        for s, c in curves[(curves["scenario"] != "all") & (curves["curve"] == "in_sample")].groupby("scenario"):
            b.step(c["area_cm2"], 100 * c["captured"], where="post", label=figures.human(s))
        per = curves[(curves["scenario"] != "all") & (curves["curve"] == "in_sample")]
        if len(per):  # each scenario's curve is flat once it captures all: show up to where the last one gets there
            full = per[per["captured"] >= per.groupby("scenario")["captured"].transform("max") - 1e-9]
            right = max(float(full.groupby("scenario")["area_cm2"].min().max()), budget_cm2) * 1.15
            b.set_xlim(-0.02 * right, right)
        b.set_title("per scenario (in sample)", loc="left")
        b.legend(loc="lower right")
        k = pitch_mm**2 / 100.0  # cm^2 per taxel
        for ax in (a, b):
            ax.axvline(budget_cm2, color="#555555", linestyle=":", linewidth=1)
            ax.set_xlabel("skin area (cm$^2$)")
            ax.set_ylim(0, 101)
            top = ax.secondary_xaxis("top", functions=(lambda x: x / k, lambda t: t * k))
            top.set_xlabel(f"taxels at {pitch_mm:g} mm pitch")
        return _finish(fig, title, path, provenance)


def plot_skin(
    view,
    pooled: np.ndarray,
    chosen: np.ndarray,
    path: str | Path,
    title: str,
    provenance: figures.Provenance | None = None,
) -> Path:
    """The pooled contact density on the whole robot, and on the chosen patches only (the recommended skin)."""
    from sphri.sessions.render import plot_views

    return plot_views(view, {"pooled": pooled, "skin": np.where(chosen, pooled, 0.0)}, path, title, provenance)
