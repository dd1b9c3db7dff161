"""From a loaded sweep to the report's numbers: curves, saturation points, requirements.

For each group of jobs (see :mod:`sphri.report.sweep`) the per-participant
scores form (P, R) matrices (participants x resolutions, coarse to fine by
``layout.res``); :func:`sphri.report.saturation.certified_saturation` finds the
coarsest resolution certified to keep accuracy within a tolerance of the
best (with a bootstrap interval), and the same for each gesture's recall
curve (which gestures need fine skin). The requirement sentence states the saturation point in physical
units: the larger of the two pitches (along and around the link, mm) and
the area per taxel (cm^2).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from sphri.report.saturation import (
    CERTIFY_ALPHA,
    Certificate,
    Saturation,
    Tolerance,
    certified_saturation,
    curve_stats,
    physical_interval,
    points_text,
)
from sphri.report.sweep import GEOMETRY_PARAMS, Sweep, natural_key
from sphri.types import GESTURES

#: Chance accuracy of the 8-gesture task.
CHANCE = 1.0 / len(GESTURES)


@dataclass(frozen=True)
class RuleSettings:
    """How the requirement is chosen (:func:`sphri.report.saturation.certified_saturation`) under several
    tolerances, one of which (``primary``) the requirement sentence uses."""

    tolerances: tuple[str, ...] = ("0.01", "0.02", "0.03")
    """Tolerances shown side by side, in accuracy units (0.01 = 1 point)."""
    primary: str = "0.01"
    """The tolerance the requirement sentence asks for (one of ``tolerances``; raised to the smallest
    certifiable tolerance when that is larger)."""
    n_boot: int = 2000
    """Bootstrap resamples (participants and seeds)."""
    ci: float = 0.95
    seed: int = 0
    alpha: float = CERTIFY_ALPHA
    """The probability allowed that the requirement's promise is broken."""

    def __post_init__(self) -> None:
        names = [t.name for t in self.parsed()]
        if len(set(names)) != len(names):
            raise ValueError(f"tolerances {list(self.tolerances)} repeat a tolerance")
        if Tolerance.parse(self.primary).name not in names:
            raise ValueError(f"primary tolerance {self.primary!r} is not among the tolerances {names}")
        if self.n_boot < 0 or not 0 < self.ci < 1:
            raise ValueError(f"n_boot={self.n_boot} must be >= 0 and ci={self.ci} in (0, 1)")

    def parsed(self) -> list[Tolerance]:
        """The tolerances, parsed, in the order given."""
        if not self.tolerances:
            raise ValueError("tolerances is empty: give at least one (e.g. 0.01,0.02,0.03)")
        return [Tolerance.parse(t) for t in self.tolerances]

    @property
    def primary_tolerance(self) -> Tolerance:
        return Tolerance.parse(self.primary)

    def describe(self) -> str:
        """The rule in a few sentences."""
        others = [t.describe() for t in self.parsed() if t.name != self.primary_tolerance.name]
        text = (
            "The requirement is the coarsest resolution from which every finer swept resolution is within the "
            f"tolerance of the best, with {1 - self.alpha:.0%} confidence. Each participant's accuracy is "
            "averaged over the seeds; for every pair of resolutions the paired difference over participants "
            "(which carries each person's own response to resolution) gets a one-sided upper confidence bound "
            "(Student's t, Bonferroni over the resolutions). A resolution's bound is its largest against any "
            "resolution, so the best need not be picked from the same noisy data. The smallest tolerance the "
            "study can certify is the finest resolution's bound; a tolerance asked for below it is raised to "
            f"it. The requirement sentence asks for {self.primary_tolerance.describe()}"
            + ("; the tolerance table also shows " + ", ".join(others) if others else "")
            + "."
        )
        if self.n_boot == 0:
            return text + " No bootstrap interval was requested."
        return (
            f"{text} Each {self.ci:.0%} interval is the {100 * (1 - self.ci) / 2:g}/{100 * (1 + self.ci) / 2:g} "
            f"percentiles of the resolution chosen on {self.n_boot} bootstrap resamples of the participants and, "
            "with several seeds, of the seeds (each resample redoes the bounds and the rule at the tolerance used)."
        )


@dataclass
class ToleranceRow:
    """The saturation point of one curve under one tolerance."""

    tolerance: Tolerance
    sat: Saturation
    pitch_interval_mm: tuple[float, float] | None
    area_interval_cm2: tuple[float, float] | None
    primary: bool
    """True for the tolerance the requirement sentence uses."""


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
    """(P, R) float64 per-participant accuracy, the mean over the replicate seeds (NaN = missing)."""
    macro_f1: np.ndarray
    """(P, R) float64 per-participant macro F1."""
    recall: dict[str, np.ndarray]
    """gesture -> (P, R) per-participant recall."""
    sat: Saturation
    pitch_interval_mm: tuple[float, float] | None
    area_interval_cm2: tuple[float, float] | None
    gesture_sat: dict[str, Saturation]
    certificate: Certificate
    """What the rule certified under the primary tolerance: the smallest certifiable tolerance, the one used, the
    rerun noise."""
    seeds: list[str]
    """The replicate seeds of this curve (one entry when the sweep has no replicates)."""
    context: dict[str, Any]
    """robot, region, link, dataset, synthetic, cv_scheme, model."""
    requirement: str = ""
    """The requirement sentence (physical units)."""
    facts: str = ""
    """Saturation vs best accuracy, and the paired gap."""
    interval_text: str = ""
    """The bootstrap interval in words (or why there is none)."""
    warnings: list[str] = field(default_factory=list)
    by_tolerance: list[ToleranceRow] = field(default_factory=list)
    """The saturation point under each of the rule's tolerances (the primary one is ``sat``)."""

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


#: Group key naming a job's assumption variant (the root config key ``variant``, set by ``conf/sensitivity/*.yaml``).
VARIANT_KEY = "variant"
#: The variant holding the reference assumptions.
REFERENCE_VARIANT = "reference"


@dataclass
class Sensitivity:
    """The requirement under each assumption variant of a sensitivity sweep (one set of other keys, e.g. one model)."""

    label: str
    """The other group keys these variants share ("" when only the variant varies)."""
    reference: GroupReport | None
    """The ``reference`` variant's curve (None when the sweep has none)."""
    variants: list[GroupReport]
    """Every variant's curve (reference included), ordered by how far its pitch moves from the reference."""
    sentence: str
    """The requirement with its interval under the reference, and the range across the assumptions tested."""


#: Group keys that set the noise (and so the false-on rate): not what separates one map from another.
_NOISE_PREFIX = "noise"


@dataclass
class RequirementMap:
    """The curves of one set of other group keys, one per false-on rate (ascending)."""

    label: str
    """The other group keys these curves share ("" when only the noise varies)."""
    rates: list[float]
    curves: list[GroupReport]
    keys: dict[str, str] = field(default_factory=dict)
    """The other group keys themselves (``{"filter": "persistence"}``)."""

    def dip_index(self, g: GroupReport) -> int | None:
        """The deepest resolution outside the tolerance that is finer than one inside it, or None."""
        env = g.certificate
        inside = ~env.outside & np.isfinite(g.sat.stats.mean)
        if not inside.any():
            return None
        first_in = int(np.argmax(inside))
        cand = [i for i in range(first_in + 1, len(env.outside)) if env.outside[i]]
        if not cand:
            return None
        return min(cand, key=lambda i: g.sat.stats.mean[i])


def requirement_maps(groups: list[GroupReport]) -> list[RequirementMap]:
    """One map per set of non-noise group keys that sweeps two or more false-on rates; [] otherwise."""
    parts: dict[tuple[tuple[str, str], ...], list[tuple[float, GroupReport]]] = {}
    for g in groups:
        rates = g.points["false_on_rate"].to_numpy(float) if "false_on_rate" in g.points else np.array([np.nan])
        if not (np.isfinite(rates).all() and np.ptp(rates) == 0 and g.has_pitch):
            continue
        other = tuple((k, v) for k, v in g.keys.items() if not k.startswith(_NOISE_PREFIX))
        parts.setdefault(other, []).append((float(rates[0]), g))
    out = []
    for other, members in parts.items():
        rates = sorted({r for r, _ in members})
        if len(rates) < 2 or len(rates) != len(members):
            continue  # one rate, or two curves share a rate (another noise setting varies): not a map
        members.sort(key=lambda t: t[0])
        out.append(
            RequirementMap(
                ", ".join(f"{k}={v}" for k, v in other), [r for r, _ in members], [g for _, g in members], dict(other)
            )
        )
    return out


@dataclass
class SweepReport:
    sweep: Sweep
    rule: RuleSettings
    groups: list[GroupReport]
    notes: list[str]
    sensitivity: list[Sensitivity] = field(default_factory=list)
    """One entry per set of other keys when the sweep varies ``variant`` (``+experiment=requirement_sensitivity``)."""
    maps: list[RequirementMap] = field(default_factory=list)
    """One :class:`RequirementMap` per set of other keys when the sweep varies the false-on rate
    (``+experiment=requirement_map``; its table and figure: :mod:`sphri.report.reqmap`)."""

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
    return SweepReport(sweep, rule, groups, notes, sensitivity(groups, rule), requirement_maps(groups))


def variant_value(g: GroupReport) -> float:
    """What a variant's requirement is compared by: saturation pitch in mm (or, without pitch, -taxels)."""
    rec = g.recommended
    return float(rec["pitch_mm"]) if g.has_pitch else -float(rec["n_taxels"])


def sensitivity(groups: list[GroupReport], rule: RuleSettings) -> list[Sensitivity]:
    """Requirement per assumption variant, for each set of other group keys; [] unless ``variant`` varies."""
    if not any(VARIANT_KEY in g.keys for g in groups):
        return []
    out = []
    parts: dict[tuple[tuple[str, str], ...], list[GroupReport]] = {}
    for g in groups:
        other = tuple((k, v) for k, v in g.keys.items() if k != VARIANT_KEY)
        parts.setdefault(other, []).append(g)
    for other, members in parts.items():
        if len(members) < 2:
            continue
        label = ", ".join(f"{k}={v}" for k, v in other)
        ref = next((g for g in members if g.keys.get(VARIANT_KEY) == REFERENCE_VARIANT), None)
        base = variant_value(ref) if ref is not None else float(np.median([variant_value(g) for g in members]))
        ordered = sorted(members, key=lambda g: (-abs(variant_value(g) - base), g.keys.get(VARIANT_KEY, "")))
        out.append(Sensitivity(label, ref, ordered, _sensitivity_sentence(ref, members, rule)))
    return out


def _sensitivity_sentence(ref: GroupReport | None, members: list[GroupReport], rule: RuleSettings) -> str:
    if not all(g.has_pitch for g in members):
        vals = [int(g.recommended["n_taxels"]) for g in members]
        head = (
            f"at least {int(ref.recommended['n_taxels'])} taxels under the reference assumptions"
            if ref is not None
            else "no reference variant in this sweep"
        )
        return f"The skin needs {head}; between {min(vals)} and {max(vals)} taxels across the {len(members)} assumptions tested."
    pitches = {g.keys.get(VARIANT_KEY, g.label): float(g.recommended["pitch_mm"]) for g in members}
    lo_v, hi_v = min(pitches, key=pitches.__getitem__), max(pitches, key=pitches.__getitem__)
    if ref is not None:
        head = (
            f"A taxel pitch of at most {_fmt_pitch(pitches[ref.keys[VARIANT_KEY]])} mm "
            f"({_pitch_interval_words(ref.pitch_interval_mm, ref.sat, rule)}) under the reference assumptions"
        )
    else:
        head = "No reference variant in this sweep (conf/sensitivity/reference.yaml)"
    finest = [g.keys.get(VARIANT_KEY, g.label) for g in members if g.sat.at_finest]
    used = [g.sat.tolerance for g in members]
    within = (
        points_text(used[0])
        if max(used) - min(used) < 1e-12
        else f"{100 * min(used):.1f} to {100 * max(used):.1f} points of accuracy, the tolerance each one's data certify"
    )
    tail = (
        f"; between {_fmt_pitch(pitches[lo_v])} mm ({lo_v}) and {_fmt_pitch(pitches[hi_v])} mm ({hi_v}) across the "
        f"{len(members)} assumptions tested (accuracy within {within} of each one's best at every finer pitch, "
        f"{1 - rule.alpha:.0%} confidence, paired over participants)."
    )
    if finest:
        tail += (
            f" Under {', '.join(finest)} the finest resolution swept was chosen: accuracy may still rise at a "
            "finer pitch, so the requirement there may be finer than stated."
        )
    return head + tail


def _seed_matrix(
    folds: pd.DataFrame, rows: pd.DataFrame, res: list[int], seeds: list[str], column: str, participants: list[str]
) -> np.ndarray:
    """(S, P, R) per-seed matrices of ``column`` (NaN where a seed lacks a resolution)."""
    out = np.full((len(seeds), len(participants), len(res)), np.nan)
    for i, sd in enumerate(seeds):
        by_res = dict(zip(rows.loc[rows["seed"] == sd, "res"], rows.loc[rows["seed"] == sd, "run_id"]))
        have = [j for j, r in enumerate(res) if r in by_res]
        if have:
            out[i][:, have] = _matrix(folds, [by_res[res[j]] for j in have], column, participants)
    return out


def _seed_mean(m: np.ndarray) -> np.ndarray:
    """(S, P, R) -> (P, R) mean over seeds, NaNs skipped (NaN where no seed has a value)."""
    finite = np.isfinite(m)
    n = finite.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.where(finite, m, 0.0).sum(axis=0) / np.maximum(n, 1), np.nan)


def _group(sweep: Sweep, label: str, rows: pd.DataFrame, rule: RuleSettings) -> GroupReport:
    rows = rows.copy()
    if "seed" not in rows.columns:
        rows["seed"] = "0"
    rows["seed"] = rows["seed"].astype(str)
    run_ids = list(rows["run_id"])
    folds = sweep.folds[sweep.folds["run_id"].isin(run_ids)]
    participants = sorted(folds["participant"].unique(), key=str)
    seeds = sorted(rows["seed"].unique(), key=natural_key)
    res = sorted(int(r) for r in rows["res"].unique())
    acc_s = _seed_matrix(folds, rows, res, seeds, "accuracy", participants)
    acc = _seed_mean(acc_s)
    f1 = _seed_mean(_seed_matrix(folds, rows, res, seeds, "macro_f1", participants))
    recall_s = {g: _seed_matrix(folds, rows, res, seeds, f"recall_{g}", participants) for g in GESTURES}
    recall = {g: _seed_mean(m) for g, m in recall_s.items()}

    tol_env = [
        (t, *certified_saturation(acc_s, t, n_boot=rule.n_boot, ci=rule.ci, seed=rule.seed, alpha=rule.alpha))
        for t in rule.parsed()
    ]
    primary = rule.primary_tolerance.name
    sat, certificate = next((st, env) for t, st, env in tol_env if t.name == primary)
    st = sat.stats
    # One row per resolution: the lowest seed's job names the point (its confusion matrix, its geometry).
    first_seed = rows.sort_values("seed", key=lambda c: c.map(natural_key), kind="stable").drop_duplicates("res")
    first_seed = first_seed.set_index("res").loc[res].reset_index()
    pts = first_seed[["res", "run_id", *GEOMETRY_PARAMS]].copy()
    pts["false_on_rate"] = first_seed["false_on_rate"].to_numpy(float) if "false_on_rate" in first_seed else np.nan
    pu, pv = pts["pitch_u_mm"].to_numpy(float), pts["pitch_v_mm"].to_numpy(float)
    pts["pitch_mm"] = np.where(np.isfinite(pv) & (pv > 0), np.fmax(pu, pv), pu)
    pts["accuracy_mean"], pts["accuracy_std"], pts["accuracy_se"], pts["n"] = st.mean, st.std, st.se, st.n
    pts["n_seeds"] = np.isfinite(acc_s).any(axis=1).sum(axis=0)
    f1_stats = curve_stats(f1)
    pts["macro_f1_mean"], pts["macro_f1_std"] = f1_stats.mean, f1_stats.std
    for gest, m in recall.items():
        pts[f"recall_{gest}"] = curve_stats(m).mean
    pts = pts.reset_index(drop=True)

    gesture_sat = {}
    for gest, m in recall_s.items():
        if np.isfinite(m).any():
            gesture_sat[gest] = certified_saturation(m, rule.primary_tolerance, n_boot=0, alpha=rule.alpha)[0]

    first = rows.iloc[0]
    pitch, area = pts["pitch_mm"].to_numpy(float), pts["area_per_taxel_cm2"].to_numpy(float)
    g = GroupReport(
        label,
        keys={k: str(first[f"key.{k}"]) for k in sweep.group_keys},
        points=pts,
        participants=participants,
        accuracy=acc,
        macro_f1=f1,
        recall=recall,
        pitch_interval_mm=physical_interval(pitch, sat),
        sat=sat,
        gesture_sat=gesture_sat,
        certificate=certificate,
        seeds=seeds,
        area_interval_cm2=physical_interval(area, sat),
        context={k: first[k] for k in ("robot", "region", "link", "dataset", "synthetic", "cv_scheme", "model")},
        by_tolerance=[
            ToleranceRow(t, st_, physical_interval(pitch, st_), physical_interval(area, st_), t.name == primary)
            for t, st_, _ in tol_env
        ],
    )
    g.requirement, g.facts, g.interval_text = (
        _requirement_sentence(g, rule),
        _facts_sentence(g, rule),
        _interval_sentence(g, rule),
    )
    g.warnings = _warnings(g)
    return g


def noise_text(g: GroupReport) -> str:
    """The rerun noise and the tolerance the rule certified, in words."""
    cert = g.certificate
    return f"{cert.noise.describe()}; {cert.describe()}"


def _where(g: GroupReport) -> str:
    """The link, model and evaluation the curve ran on ("reachy arm, link l_arm; rf, LOSO, SYNTHETIC data")."""
    c = g.context
    where = f"{c['robot']} {c['region']}, link {c['link']}; {c['model']}, {str(c['cv_scheme']).upper()}"
    if c["synthetic"]:
        where += ", SYNTHETIC data"
    return where


def _tolerance_words(g: GroupReport, rule: RuleSettings) -> str:
    """The tolerance the requirement is stated with, and why when it is larger than the one asked for."""
    cert = g.certificate
    tol = points_text(g.sat.tolerance)
    if cert.raised:
        tol += (
            f" (the smallest this study certifies with {cert.n_participants} participants and {cert.n_seeds} "
            f"seed{'s' if cert.n_seeds != 1 else ''}; the {rule.primary_tolerance.describe()} asked for cannot be)"
        )
    return tol


def _requirement_sentence(g: GroupReport, rule: RuleSettings) -> str:
    """The requirement: a pitch (with its interval and area per taxel), else a taxel count, else what one
    resolution alone measured."""
    rec, sat, cert = g.recommended, g.sat, g.certificate
    where, tol = _where(g), _tolerance_words(g, rule)
    if len(g.points) == 1:
        where_pt = (
            f"{_fmt_pitch(rec['pitch_mm'])} mm pitch, {rec['area_per_taxel_cm2']:.2f} cm^2 per taxel"
            if g.has_pitch
            else _taxels(rec["n_taxels"])
        )
        return (
            f"One resolution only (layout.res={rec['res']}, {where_pt}) on this link ({where}): accuracy "
            f"{rec['accuracy_mean']:.3f} +/- {rec['accuracy_std']:.3f}; no saturation point without a sweep "
            "over layout.res."
        )
    if g.has_pitch and np.isfinite(rec["pitch_mm"]):
        area = rec["area_per_taxel_cm2"]
        area_txt = f"{area:.2f} cm^2 per taxel" if np.isfinite(area) and area > 0 else "area per taxel unknown"
        return (
            f"A taxel pitch of at most {_fmt_pitch(rec['pitch_mm'])} mm ({_pitch_interval_words(g.pitch_interval_mm, sat, rule)}; "
            f"{area_txt}) keeps accuracy within {tol} of the best at every finer swept pitch, with "
            f"{1 - cert.alpha:.0%} confidence, paired over participants, on this link ({where})."
        )
    res_iv = sat.interval
    iv_txt = (
        f"{rule.ci:.0%} interval layout.res {g.points['res'].iloc[res_iv[0]]} to {g.points['res'].iloc[res_iv[1]]}"
        if res_iv is not None
        else "no interval: " + (sat.note or "not computed")
    )
    return (
        f"At least {int(rec['n_taxels']) if np.isfinite(rec['n_taxels']) else rec['res']} taxels "
        f"(layout.res={rec['res']}; {iv_txt}) keep accuracy within {tol} of the best at every finer "
        f"swept resolution, with {1 - cert.alpha:.0%} confidence, paired over participants, on this link ({where})."
    )


def _facts_sentence(g: GroupReport, rule: RuleSettings) -> str:
    """The saturation point's accuracy against the best's, and the paired gap between them ("" for one
    resolution)."""
    if len(g.points) == 1:
        return ""
    rec, best, sat = g.recommended, g.best, g.sat
    facts = (
        f"Saturation at layout.res={rec['res']} ({_taxels(rec['n_taxels'])}): accuracy "
        f"{rec['accuracy_mean']:.3f} +/- {rec['accuracy_std']:.3f} vs best {best['accuracy_mean']:.3f} "
        f"+/- {best['accuracy_std']:.3f} at layout.res={best['res']}"
    )
    if g.has_pitch:
        facts += f" ({_fmt_pitch(best['pitch_mm'])} mm)"
    facts += "."
    if sat.gap_interval is not None and sat.index != sat.best_index:
        facts += (
            f" Paired over participants, the saturation point is {sat.gap:.3f} below the best "
            f"({rule.ci:.0%} CI {sat.gap_interval[0]:.3f} to {sat.gap_interval[1]:.3f})."
        )
    return facts


def _interval_sentence(g: GroupReport, rule: RuleSettings) -> str:
    """The bootstrap interval of the saturation point in pitch (and area) or resolution, or why there is none."""
    sat = g.sat
    if len(g.points) == 1:
        return "No interval: one resolution only."
    if g.pitch_interval_mm is not None and sat.interval is not None and g.has_pitch:  # the first implies the second
        lo, hi = g.pitch_interval_mm
        iv = (
            f"{rule.ci:.0%} bootstrap interval over {sat.n_participants} participants: "
            f"{_fmt_pitch(lo)} to {_fmt_pitch(hi)} mm pitch"
        )
        if g.area_interval_cm2 is not None:
            iv += f" ({g.area_interval_cm2[0]:.2f} to {g.area_interval_cm2[1]:.2f} cm^2 per taxel)"
        return iv + f"; layout.res {g.points['res'].iloc[sat.interval[0]]} to {g.points['res'].iloc[sat.interval[1]]}."
    if sat.interval is not None and len(g.points) > 1:
        return (
            f"{rule.ci:.0%} bootstrap interval over {sat.n_participants} participants: layout.res "
            f"{g.points['res'].iloc[sat.interval[0]]} to {g.points['res'].iloc[sat.interval[1]]}."
        )
    return "No bootstrap interval: " + (sat.note or "not computed") + "."


def _warnings(g: GroupReport) -> list[str]:
    """What the reader must know before using the requirement: a saturation point at an end of the sweep,
    what the rule noted, a curve near chance."""
    sat = g.sat
    warn = []
    if sat.at_finest:
        warn.append(
            "the finest resolution swept was chosen: accuracy may still rise; extend the sweep to a finer pitch"
        )
    elif sat.index == 0 and len(g.points) > 1:
        warn.append(
            "the coarsest resolution swept is already within tolerance of the best: a coarser skin may do, "
            "or this model does not use spatial detail"
        )
    note = "; ".join(n for n in sat.note.split("; ") if n and "cannot be certified" not in n)
    if note and sat.interval is not None:
        warn.append(note)
    if np.nanmax(sat.stats.mean) < CHANCE + 0.05:
        warn.append(
            f"the best accuracy ({np.nanmax(sat.stats.mean):.3f}) is near chance ({CHANCE:.3f}): the curve carries little information"
        )
    return warn


def _pitch_interval_words(iv: tuple[float, float] | None, sat: Saturation, rule: RuleSettings) -> str:
    """ "95 % interval 5.1 to 6.0 mm", or why there is none: a requirement never states a point alone."""
    if iv is None:
        return "no interval: " + (sat.note.split(";")[0] if sat.note else "not computed")
    return f"{rule.ci:.0%} interval {_fmt_pitch(iv[0])} to {_fmt_pitch(iv[1])} mm"


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
