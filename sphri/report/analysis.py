"""From a loaded sweep to the report's numbers: curves, saturation points, requirements.

For each group of jobs (see :mod:`sphri.report.sweep`) the per-participant
scores form (P, R) matrices (participants x resolutions, coarse to fine by
``encoder.res``); :func:`sphri.report.saturation.saturation` finds the
saturation point of the accuracy curve with a participant-bootstrap
interval, and of each gesture's recall curve (which gestures need fine
skin). The requirement sentence states the saturation point in physical
units: the larger of the two pitches (along and around the link, mm) and
the area per taxel (cm^2).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from sphri.report.saturation import Saturation, curve_stats, physical_interval, saturation
from sphri.report.sweep import Sweep
from sphri.types import GESTURES

#: Chance accuracy of the 8-gesture task.
CHANCE = 1.0 / len(GESTURES)


@dataclass(frozen=True)
class RuleSettings:
    """How the saturation point is chosen (see :mod:`sphri.report.saturation`)."""

    n_se: float = 1.0
    """Tolerance in standard errors of the best mean (used when ``tolerance`` is None)."""
    tolerance: float | None = None
    """Fixed tolerance in accuracy units instead (e.g. 0.02)."""
    n_boot: int = 2000
    """Participant bootstrap resamples."""
    ci: float = 0.95
    seed: int = 0

    def describe(self) -> str:
        """The rule in one sentence."""
        if self.tolerance is None:
            tol = "one standard error" if self.n_se == 1 else f"{self.n_se:g} standard errors"
            tol += " (over participants) of the best resolution's mean accuracy"
        else:
            tol = f"{self.tolerance:g} (accuracy units) of the best resolution's mean accuracy"
        text = f"The saturation point is the coarsest resolution whose mean accuracy over participants is within {tol}."
        if self.n_boot == 0:
            return text + " No bootstrap interval was requested."
        return (
            f"{text} Its {self.ci:.0%} interval is the {100 * (1 - self.ci) / 2:g}/{100 * (1 + self.ci) / 2:g} "
            f"percentiles of the point chosen by the same rule on {self.n_boot} bootstrap resamples of the participants."
        )


@dataclass
class GroupReport:
    """One curve (a group of jobs differing only in resolution) and its saturation point."""

    label: str
    keys: dict[str, str]
    points: pd.DataFrame
    """One row per resolution, coarse to fine: res, run_id, n_taxels, grid_h, grid_w,
    pitch_u_mm, pitch_v_mm, pitch_mm (the larger), area_per_taxel_cm2, taxels_per_24cm,
    accuracy_mean/std/se, macro_f1_mean/std, n (participants), recall_<g> (mean)."""
    participants: list[str]
    accuracy: np.ndarray
    """(P, R) float64 per-participant accuracy (NaN = missing)."""
    macro_f1: np.ndarray
    """(P, R) float64 per-participant macro F1."""
    recall: dict[str, np.ndarray]
    """gesture -> (P, R) per-participant recall."""
    sat: Saturation
    pitch_interval_mm: tuple[float, float] | None
    area_interval_cm2: tuple[float, float] | None
    gesture_sat: dict[str, Saturation]
    context: dict[str, Any]
    """robot, region, link, dataset, synthetic, cv_scheme, model."""
    requirement: str
    """The requirement sentence (physical units)."""
    facts: str
    """Saturation vs best accuracy, and the paired gap."""
    interval_text: str
    """The bootstrap interval in words (or why there is none)."""
    warnings: list[str] = field(default_factory=list)

    @property
    def recommended(self) -> pd.Series:
        return self.points.iloc[self.sat.index]

    @property
    def best(self) -> pd.Series:
        return self.points.iloc[self.sat.best_index]

    @property
    def has_pitch(self) -> bool:
        p = self.points["pitch_u_mm"].to_numpy(float)
        return bool(np.all(np.isfinite(p) & (p > 0)))


@dataclass
class SweepReport:
    sweep: Sweep
    rule: RuleSettings
    groups: list[GroupReport]
    notes: list[str]

    @property
    def synthetic(self) -> str:
        return self.sweep.synthetic


def _matrix(folds: pd.DataFrame, run_ids: list[str], column: str, participants: list[str]) -> np.ndarray:
    sub = folds[folds["run_id"].isin(run_ids)]
    table = sub.pivot_table(index="participant", columns="run_id", values=column, aggfunc="mean", dropna=False)
    table = table.reindex(index=participants, columns=run_ids)
    return table.to_numpy(dtype=np.float64)


def _fmt_pitch(x: float) -> str:
    return f"{x:.0f}" if x >= 100 else f"{x:.1f}"


def analyze(sweep: Sweep, rule: RuleSettings = RuleSettings()) -> SweepReport:
    """Curves, saturation points and requirement sentences for every group of ``sweep``."""
    groups = []
    notes = list(sweep.notes)
    for label, rows in sweep.groups():
        groups.append(_group(sweep, label, rows, rule))
    if sweep.failed:
        notes.append(f"{len(sweep.failed)} job(s) FAILED and are missing from the curves (listed below)")
    schemes = sorted(set(sweep.runs["cv_scheme"]))
    if "kfold" in schemes:
        notes.append("k-fold (within-subject) results are not comparable with LOSO (between-subject) results")
    return SweepReport(sweep, rule, groups, notes)


def _group(sweep: Sweep, label: str, rows: pd.DataFrame, rule: RuleSettings) -> GroupReport:
    run_ids = list(rows["run_id"])
    folds = sweep.folds[sweep.folds["run_id"].isin(run_ids)]
    participants = sorted(folds["participant"].unique(), key=str)
    acc = _matrix(folds, run_ids, "accuracy", participants)
    f1 = _matrix(folds, run_ids, "macro_f1", participants)
    recall = {g: _matrix(folds, run_ids, f"recall_{g}", participants) for g in GESTURES}

    sat = saturation(acc, n_se=rule.n_se, tolerance=rule.tolerance, n_boot=rule.n_boot, ci=rule.ci, seed=rule.seed)
    st = sat.stats
    pts = rows[["res", "run_id", "n_taxels", "grid_h", "grid_w", "pitch_u_mm", "pitch_v_mm",
                "area_per_taxel_cm2", "taxels_per_24cm"]].copy()
    pu, pv = pts["pitch_u_mm"].to_numpy(float), pts["pitch_v_mm"].to_numpy(float)
    pts["pitch_mm"] = np.where(np.isfinite(pv) & (pv > 0), np.fmax(pu, pv), pu)
    pts["accuracy_mean"], pts["accuracy_std"], pts["accuracy_se"], pts["n"] = st.mean, st.std, st.se, st.n
    f1_stats = curve_stats(f1)
    pts["macro_f1_mean"], pts["macro_f1_std"] = f1_stats.mean, f1_stats.std
    for gest, m in recall.items():
        pts[f"recall_{gest}"] = curve_stats(m).mean
    pts = pts.reset_index(drop=True)

    gesture_sat = {}
    for g, m in recall.items():
        if np.isfinite(m).any():
            gesture_sat[g] = saturation(m, n_se=rule.n_se, tolerance=rule.tolerance, n_boot=0)

    first = rows.iloc[0]
    context = {k: first[k] for k in ("robot", "region", "link", "dataset", "synthetic", "cv_scheme", "model")}
    keys = {k: str(first[f"key.{k}"]) for k in sweep.group_keys}
    pitch_iv = physical_interval(pts["pitch_mm"].to_numpy(float), sat)
    area_iv = physical_interval(pts["area_per_taxel_cm2"].to_numpy(float), sat)
    g = GroupReport(label, keys, pts, participants, acc, f1, recall, sat, pitch_iv, area_iv, gesture_sat, context, "", "", "")
    g.requirement, g.facts, g.interval_text, g.warnings = _sentences(g, rule)
    return g


def _sentences(g: GroupReport, rule: RuleSettings) -> tuple[str, str, str, list[str]]:
    rec, best, sat = g.recommended, g.best, g.sat
    c = g.context
    where = f"{c['robot']} {c['region']}, link {c['link']}; {c['model']}, {str(c['cv_scheme']).upper()}"
    if c["synthetic"]:
        where += ", SYNTHETIC data"
    tol = (f"{sat.tolerance:.3f} (one standard error)" if rule.tolerance is None and rule.n_se == 1
           else f"{sat.tolerance:.3f}")
    if len(g.points) == 1:
        where_pt = (f"{_fmt_pitch(rec['pitch_mm'])} mm pitch, {rec['area_per_taxel_cm2']:.2f} cm^2 per taxel"
                    if g.has_pitch else _taxels(rec["n_taxels"]))
        req = (f"One resolution only (encoder.res={rec['res']}, {where_pt}) on this link ({where}): accuracy "
               f"{rec['accuracy_mean']:.3f} +/- {rec['accuracy_std']:.3f}; no saturation point without a sweep "
               "over encoder.res.")
    elif g.has_pitch and np.isfinite(rec["pitch_mm"]):
        area = rec["area_per_taxel_cm2"]
        area_txt = f"{area:.2f} cm^2 per taxel" if np.isfinite(area) and area > 0 else "area per taxel unknown"
        req = (f"A taxel pitch of at most {_fmt_pitch(rec['pitch_mm'])} mm ({area_txt}) keeps accuracy within "
               f"{tol} of the best on this link ({where}).")
    else:
        req = (f"At least {int(rec['n_taxels']) if np.isfinite(rec['n_taxels']) else rec['res']} taxels "
               f"(encoder.res={rec['res']}) keep accuracy within {tol} of the best on this link ({where}).")
    facts = (f"Saturation at encoder.res={rec['res']} ({_taxels(rec['n_taxels'])}): accuracy "
             f"{rec['accuracy_mean']:.3f} +/- {rec['accuracy_std']:.3f} vs best {best['accuracy_mean']:.3f} "
             f"+/- {best['accuracy_std']:.3f} at encoder.res={best['res']}")
    if g.has_pitch:
        facts += f" ({_fmt_pitch(best['pitch_mm'])} mm)"
    facts += "."
    if sat.gap_interval is not None and sat.index != sat.best_index:
        facts += (f" Paired over participants, the saturation point is {sat.gap:.3f} below the best "
                  f"({rule.ci:.0%} CI {sat.gap_interval[0]:.3f} to {sat.gap_interval[1]:.3f}).")
    if len(g.points) == 1:
        facts = ""
        iv = "No interval: one resolution only."
    elif g.pitch_interval_mm is not None and g.has_pitch:
        lo, hi = g.pitch_interval_mm
        iv = (f"{rule.ci:.0%} bootstrap interval over {sat.n_participants} participants: "
              f"{_fmt_pitch(lo)} to {_fmt_pitch(hi)} mm pitch")
        if g.area_interval_cm2 is not None:
            iv += f" ({g.area_interval_cm2[0]:.2f} to {g.area_interval_cm2[1]:.2f} cm^2 per taxel)"
        iv += f"; encoder.res {g.points['res'].iloc[sat.interval[0]]} to {g.points['res'].iloc[sat.interval[1]]}."
    elif sat.interval is not None and len(g.points) > 1:
        iv = (f"{rule.ci:.0%} bootstrap interval over {sat.n_participants} participants: encoder.res "
              f"{g.points['res'].iloc[sat.interval[0]]} to {g.points['res'].iloc[sat.interval[1]]}.")
    else:
        iv = "No bootstrap interval: " + (sat.note or "not computed") + "."
    warn = []
    if sat.at_finest:
        warn.append("the finest resolution swept was chosen: accuracy may still rise; extend the sweep to a finer pitch")
    elif sat.index == 0 and len(g.points) > 1:
        warn.append("the coarsest resolution swept is already within tolerance of the best: a coarser skin may do, "
                    "or this model does not use spatial detail")
    if sat.note and sat.interval is not None:
        warn.append(sat.note)
    if np.nanmax(sat.stats.mean) < CHANCE + 0.05:
        warn.append(f"the best accuracy ({np.nanmax(sat.stats.mean):.3f}) is near chance ({CHANCE:.3f}): the curve carries little information")
    return req, facts, iv, warn


def _taxels(x: Any) -> str:
    try:
        n = int(x)
    except (TypeError, ValueError):
        return "? taxels"
    return f"{n} taxel" + ("" if n == 1 else "s")


def recognised(g: GroupReport, gesture: str) -> bool:
    """Whether ``gesture``'s mean recall rises above chance at some resolution of ``g``."""
    s = g.gesture_sat.get(gesture)
    return s is not None and bool(np.nanmax(s.stats.mean) > CHANCE)


def gestures_by_need(g: GroupReport) -> list[tuple[str, float, int]]:
    """(gesture, saturation pitch in mm (NaN without pitch), saturation res) sorted finest first.

    Gestures never recognised above chance are left out (their flat recall
    curve "saturates" at the coarsest point, which says nothing about skin).
    """
    out = []
    for gest, s in g.gesture_sat.items():
        if not recognised(g, gest):
            continue
        row = g.points.iloc[s.index]
        pitch = float(row["pitch_mm"]) if g.has_pitch else float("nan")
        out.append((gest, pitch, int(row["res"])))
    out.sort(key=lambda t: (-t[2], t[0]))
    return out
