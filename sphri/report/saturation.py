"""The saturation rule and its bootstrap over participants (pure functions).

Input everywhere is a score matrix ``scores`` of shape (P, R): one row per
participant (a LOSO fold), one column per sweep point, the columns ordered
**coarse to fine** (fewest taxels first). Entries are accuracies (or any
score in which higher is better); NaN marks a missing value (a failed job,
a fold without that gesture, ...).

The rule (a one-standard-error rule, as in Breiman et al.'s CART pruning):

1. For each sweep point r, the curve is the mean of the finite scores over
   participants, ``mean[r]``, with standard error
   ``se[r] = std(ddof=1) / sqrt(n[r])`` (n[r] finite scores; undefined, and
   taken as 0, when n[r] < 2). Points with no finite score are ineligible.
2. The best point b is the one with the highest mean (the coarsest among
   ties). The tolerance is ``n_se * se[b]`` (one standard error of the best
   by default), or a fixed ``tolerance`` in score units when given.
3. The saturation point is the **coarsest** point whose mean is within the
   tolerance of the best: the first r with ``mean[r] >= mean[b] - tolerance``.

Consequences: a flat curve saturates at the coarsest point; a curve that
still rises by more than the tolerance at its finest point saturates at the
finest point (the sweep did not reach saturation; :attr:`Saturation.at_finest`
says so).

Participants without any finite score are dropped first.

The interval is a participant bootstrap: draw P participants with
replacement (whole rows, so each participant's scores stay paired across
resolutions), recompute the curve, its standard errors and the rule, and
record the selected point; the interval is the (1 - ci)/2 and (1 + ci)/2
percentiles (``inverted_cdf``, so both ends are sweep points) of the
selected point over ``n_boot`` resamples. :func:`physical_interval` turns it
into a pitch (or any per-point quantity). With fewer than two participants
there is no standard error and no bootstrap: the interval is ``None`` and
:attr:`Saturation.note` says why.

The **paired rule** (:func:`paired_saturation`, what the report uses)
compares each resolution with the best one participant by participant:

1. The best point b is the one with the highest mean (coarsest among ties).
2. For each point r, each participant's deficit is ``s[p, b] - s[p, r]``
   (their accuracy at the best point minus theirs at r; participants
   missing either score are left out of that pair); the paired deficit is
   its mean over participants, with the paired standard error
   ``std(ddof=1) / sqrt(n)`` (0 at b itself).
3. The saturation point is the coarsest r whose paired deficit is within a
   :class:`Tolerance`: a fixed number of accuracy points (``0.01``: one
   point), or ``k`` paired standard errors of that point's own deficit
   (``se``: one).

Between-participant differences (one person is better at every resolution)
cancel in the pairs, so the rule sees only how each person's accuracy changes
with resolution. A fixed tolerance in points ignores a gain smaller than it,
however consistent; the SE tolerance ignores gains that are not consistent
across participants. The bootstrap redraws participants and redoes both the
best point and the rule.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

#: Slack for float comparisons of means (scores are in [0, 1]).
_EPS = 1e-12


@dataclass(frozen=True)
class CurveStats:
    """Per-point summary of a (P, R) score matrix over participants."""

    mean: np.ndarray
    """(R,) float64 mean of the finite scores (NaN where none)."""
    std: np.ndarray
    """(R,) float64 sample standard deviation, ddof=1 (0 where n < 2, NaN where n = 0)."""
    se: np.ndarray
    """(R,) float64 standard error ``std / sqrt(n)`` (0 where n < 2, NaN where n = 0)."""
    n: np.ndarray
    """(R,) int64 number of finite scores (participants) per point."""


@dataclass(frozen=True)
class Saturation:
    """Outcome of the saturation rule on one curve (indices into the R points)."""

    index: int
    """Selected (saturation) point, index into the coarse-to-fine order."""
    best_index: int
    """Point with the highest mean."""
    tolerance: float
    """Allowed shortfall from the best mean (score units, e.g. accuracy)."""
    stats: CurveStats
    n_participants: int
    """Participants (rows) with at least one finite score."""
    interval: tuple[int, int] | None
    """(low, high) percentile indices of the bootstrap, or None (see ``note``)."""
    ci: float
    n_boot: int
    """Bootstrap resamples drawn (0 when no interval)."""
    boot_index: np.ndarray | None
    """(n_boot,) int64 selected index per resample, or None."""
    gap: float
    """Mean paired shortfall of the selected point from the best (score units; >= 0 up to noise)."""
    gap_interval: tuple[float, float] | None
    """Bootstrap percentile interval of ``gap`` (paired over participants), or None."""
    note: str
    """Why something is missing or degenerate ("" when all is well)."""
    rule: str = "unpaired"
    """"unpaired" (:func:`saturation`) or "paired" (:func:`paired_saturation`)."""
    deficit: np.ndarray | None = None
    """Paired rule: (R,) mean paired deficit from the best point (score units; 0 at the best)."""
    deficit_se: np.ndarray | None = None
    """Paired rule: (R,) paired standard error of ``deficit`` (0 at the best, and where n < 2)."""
    tolerance_name: str = ""
    """Paired rule: the :class:`Tolerance` used, as written (``se``, ``2se``, ``0.01``)."""

    @property
    def at_finest(self) -> bool:
        """True when the rule picked the finest point: the sweep may not have saturated."""
        return self.index == self.stats.mean.shape[0] - 1 and self.stats.mean.shape[0] > 1


def curve_stats(scores: np.ndarray) -> CurveStats:
    """Mean, std (ddof=1), standard error and count per column of ``scores`` (P, R), NaNs skipped."""
    mean, std, se, n = _batch_stats(_as_matrix(scores)[None])
    return CurveStats(mean[0], std[0], se[0], n[0])


def _as_matrix(scores: np.ndarray) -> np.ndarray:
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim != 2:
        raise ValueError(f"scores must be a (participants, points) matrix, got shape {s.shape}")
    if s.shape[0] == 0 or s.shape[1] == 0:
        raise ValueError(f"scores is empty (shape {s.shape}): no participants or no sweep points")
    s = np.where(np.isfinite(s), s, np.nan)
    return s


def _batch_stats(s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(B, P, R) scores with NaNs -> mean, std, se (B, R) float64 and n (B, R) int64."""
    finite = np.isfinite(s)
    n = finite.sum(axis=1)
    filled = np.where(finite, s, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = filled.sum(axis=1) / n
        dev = np.where(finite, s - mean[:, None, :], 0.0)
        var = (dev**2).sum(axis=1) / (n - 1)
    std = np.where(n >= 2, np.sqrt(np.maximum(var, 0.0)), 0.0)
    std = np.where(n == 0, np.nan, std)
    with np.errstate(invalid="ignore", divide="ignore"):
        se = np.where(n >= 2, std / np.sqrt(np.maximum(n, 1)), 0.0)
    se = np.where(n == 0, np.nan, se)
    mean = np.where(n == 0, np.nan, mean)
    return mean, std, se, n.astype(np.int64)


def _rule(
    mean: np.ndarray, se: np.ndarray, n_se: float, tolerance: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorized rule on (B, R) curves -> (selected, best, tolerance) each (B,); -1 where no finite point."""
    valid = np.isfinite(mean)
    any_valid = valid.any(axis=1)
    masked = np.where(valid, mean, -np.inf)
    best = np.argmax(masked, axis=1)  # first maximum = coarsest among ties
    rows = np.arange(mean.shape[0])
    best_mean = masked[rows, best]
    if tolerance is None:
        best_se = se[rows, best]
        tol = n_se * np.where(np.isfinite(best_se), best_se, 0.0)
    else:
        tol = np.full(mean.shape[0], float(tolerance))
    eligible = valid & (masked >= (best_mean - tol - _EPS)[:, None])
    selected = np.argmax(eligible, axis=1)  # first True = coarsest
    selected = np.where(any_valid, selected, -1)
    best = np.where(any_valid, best, -1)
    return selected, best, tol


def saturation_index(scores: np.ndarray, n_se: float = 1.0, tolerance: float | None = None) -> int:
    """Index of the saturation point of ``scores`` (P, R), columns coarse to fine (see module doc)."""
    return saturation(scores, n_se=n_se, tolerance=tolerance, n_boot=0).index


def saturation(
    scores: np.ndarray,
    n_se: float = 1.0,
    tolerance: float | None = None,
    n_boot: int = 2000,
    ci: float = 0.95,
    seed: int = 0,
) -> Saturation:
    """Apply the saturation rule to ``scores`` (P, R) and bootstrap it over participants.

    ``n_se``: the tolerance in standard errors of the best point's mean
    (used when ``tolerance`` is None). ``tolerance``: a fixed allowed
    shortfall in score units instead. ``n_boot``: bootstrap resamples (0 =
    no interval). ``ci``: interval coverage. ``seed``: the resampling seed
    (same seed, same interval). Raises ValueError for a malformed matrix or
    when no point has a finite score.
    """
    if not np.isfinite(n_se) or n_se < 0:
        raise ValueError(f"n_se={n_se!r} is invalid: must be a finite number >= 0")
    if tolerance is not None and (not np.isfinite(tolerance) or tolerance < 0):
        raise ValueError(f"tolerance={tolerance!r} is invalid: must be a finite number >= 0 (score units)")
    s, stats, mean, se = _scored(scores, ci, n_boot)
    sel, best, tol = _rule(mean, se, n_se, tolerance)
    index, best_index = int(sel[0]), int(best[0])
    gap_vals = s[:, best_index] - s[:, index]
    gap = (
        float(np.nanmean(gap_vals))
        if np.isfinite(gap_vals).any()
        else float(stats.mean[best_index] - stats.mean[index])
    )

    notes = []
    n_missing = int((~np.isfinite(s)).sum())
    if n_missing:
        notes.append(f"{n_missing} of {s.size} participant x point scores are missing (NaN) and were skipped")
    single = "only one participant: no standard error and no bootstrap interval; the rule's tolerance is " + (
        "the fixed tolerance" if tolerance is not None else "0, so the saturation point is the best point"
    )

    def select(sb: np.ndarray) -> np.ndarray:
        return _rule(*_batch_stats(sb)[0:3:2], n_se, tolerance)[0]

    sat = Saturation(index, best_index, float(tol[0]), stats, s.shape[0], None, ci, 0, None, gap, None, "")
    return _outcome(
        sat, notes, single, n_boot, lambda: _bootstrap(s, index, best_index, n_boot, ci, seed, notes, select)
    )


def _check_bootstrap(ci: float, n_boot: int) -> None:
    if not 0.0 < ci < 1.0:
        raise ValueError(f"ci={ci!r} is invalid: must be in (0, 1)")
    if n_boot < 0:
        raise ValueError(f"n_boot={n_boot!r} is invalid: must be >= 0")


def _scored(scores: np.ndarray, ci: float, n_boot: int) -> tuple[np.ndarray, CurveStats, np.ndarray, np.ndarray]:
    """Check ``ci`` and ``n_boot``; (the (P, R) matrix without participants who have no finite score, its
    curve, and the curve's mean and standard error as (1, R) batches). Raises ValueError when no score is finite."""
    _check_bootstrap(ci, n_boot)
    s = _as_matrix(scores)
    s = s[np.isfinite(s).any(axis=1)]  # participants with no score at all carry no information
    if s.shape[0] == 0:
        raise ValueError("no finite score at any sweep point: nothing to find a saturation point on")
    mean, std, se, n = _batch_stats(s[None])
    return s, CurveStats(mean[0], std[0], se[0], n[0]), mean, se


def _outcome(sat: Saturation, notes: list[str], single: str, n_boot: int, resample, note_first: bool = False):
    """``sat`` (a rule's outcome without an interval) with its notes, and with the interval of its bootstrap
    ``resample()`` -> (interval, selections kept, gap interval) when there are two participants or more and
    ``n_boot`` > 0; otherwise a note why there is none (``single``: the note for one participant), last or with
    ``note_first`` first."""
    if sat.n_participants < 2 or n_boot == 0:
        why = single if sat.n_participants < 2 else "no bootstrap requested (n_boot=0): no interval"
        notes.insert(0 if note_first else len(notes), why)
        return replace(sat, note="; ".join(notes))
    interval, picked, gap_interval = resample()
    return replace(
        sat,
        interval=interval,
        n_boot=int(picked.size),
        boot_index=picked,
        gap_interval=gap_interval,
        note="; ".join(notes),
    )


def _bootstrap(
    s: np.ndarray,
    index: int,
    best_index: int,
    n_boot: int,
    ci: float,
    seed: int,
    notes: list[str],
    select: Callable[[np.ndarray], np.ndarray],
) -> tuple[tuple[int, int], np.ndarray, tuple[float, float] | None]:
    """Participant bootstrap of a rule: ``select`` maps (B, P, R) resamples to (B,) selected indices.

    Returns the percentile interval of the selected index, the selected
    indices of the usable resamples, and the interval of the paired gap
    between ``best_index`` and ``index``; appends notes about the resamples
    and the participant count to ``notes``.
    """
    n_part = s.shape[0]
    rng = np.random.default_rng(seed)
    boot_sel = np.empty(n_boot, dtype=np.int64)
    boot_gap = np.empty(n_boot, dtype=np.float64)
    chunk = max(1, int(2e6 // max(s.size, 1)))  # (chunk, P, R) a few times in memory: ~16 MB each
    for start in range(0, n_boot, chunk):
        b = min(chunk, n_boot - start)
        sb = s[rng.integers(0, n_part, size=(b, n_part))]  # (b, P, R): whole participants, paired across points
        boot_sel[start : start + b] = select(sb)
        with np.errstate(invalid="ignore"), _quiet():
            boot_gap[start : start + b] = np.nanmean(sb[:, :, best_index] - sb[:, :, index], axis=1)
    interval, picked, gap_interval = _bootstrap_intervals(boot_sel, boot_gap, n_part, ci, notes)
    return interval, picked, gap_interval


def _bootstrap_intervals(
    boot_sel: np.ndarray, boot_gap: np.ndarray, n_part: int, ci: float, notes: list[str]
) -> tuple[tuple[int, int], np.ndarray, tuple[float, float] | None]:
    """(interval of the selected point, the selections kept, interval of the paired gap) from the
    bootstrap's draws (``-1``: no finite point in that resample, dropped); notes what it dropped."""
    ok = boot_sel >= 0
    if not ok.all():
        notes.append(f"{int((~ok).sum())} of {boot_sel.size} resamples had no finite point and were dropped")
    lo_q, hi_q = (1.0 - ci) / 2.0, (1.0 + ci) / 2.0
    picked = boot_sel[ok]
    interval = (
        int(np.quantile(picked, lo_q, method="inverted_cdf")),
        int(np.quantile(picked, hi_q, method="inverted_cdf")),
    )
    g = boot_gap[np.isfinite(boot_gap)]
    gap_interval = (float(np.quantile(g, lo_q)), float(np.quantile(g, hi_q))) if g.size else None
    if n_part < 5:
        notes.append(f"only {n_part} participants: the bootstrap interval is coarse")
    return interval, picked, gap_interval


class _quiet:
    """Silence numpy's 'Mean of empty slice' warnings inside a block."""

    def __enter__(self) -> _quiet:
        import warnings

        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)
        return self

    def __exit__(self, *exc: Any) -> None:
        return self._w.__exit__(*exc)


def physical_interval(values: np.ndarray, sat: Saturation) -> tuple[float, float] | None:
    """The bootstrap interval of ``sat`` in a per-point quantity ``values`` (R,), e.g. pitch in mm.

    Returns (min, max) of ``values`` over the two interval end points (a
    pitch falls as the index rises, so its low end comes from the fine end),
    or None when ``sat`` has no interval.
    """
    if sat.interval is None:
        return None
    v = np.asarray(values, dtype=np.float64)
    if v.shape != sat.stats.mean.shape:
        raise ValueError(f"values has shape {v.shape}, expected one per sweep point {sat.stats.mean.shape}")
    a, b = v[sat.interval[0]], v[sat.interval[1]]
    return (float(min(a, b)), float(max(a, b)))


@dataclass(frozen=True)
class Tolerance:
    """How far below the best a resolution may be, paired over participants.

    Written ``se`` (one paired standard error of the point's deficit), ``2se``
    (k of them), or a number in score units (``0.01`` = one point of accuracy).
    """

    name: str
    n_se: float | None
    """k in "k paired standard errors", or None for a fixed tolerance."""
    points: float | None
    """Fixed tolerance in score units, or None for an SE tolerance."""

    @property
    def fixed(self) -> float:
        """``points`` of a fixed tolerance; ValueError for an SE tolerance (which has none)."""
        if self.points is None:
            raise ValueError(f"tolerance {self.name!r} is in paired standard errors, not a fixed number")
        return float(self.points)

    @classmethod
    def parse(cls, text: str | float) -> Tolerance:
        t = str(text).strip().lower()
        try:
            if t.endswith("se"):
                k = float(t[:-2]) if t[:-2] else 1.0
                if not np.isfinite(k) or k < 0:
                    raise ValueError
                return cls(t, k, None)
            v = float(t)
        except ValueError:
            raise ValueError(
                f"tolerance {text!r} is invalid: write se, 2se (paired standard errors) or a number "
                "in accuracy units such as 0.01"
            ) from None
        if not np.isfinite(v) or not 0 <= v < 1:
            raise ValueError(f"tolerance {text!r} is invalid: a fixed tolerance must be in [0, 1) accuracy units")
        return cls(f"{v:g}", None, v)

    def describe(self) -> str:
        """E.g. "one paired standard error", "1 point of accuracy (0.01)"."""
        if self.n_se is not None:
            k = "one" if self.n_se == 1 else f"{self.n_se:g}"
            return f"{k} paired standard error{'' if self.n_se == 1 else 's'}"
        pts = 100 * self.fixed
        return f"{pts:g} point{'' if pts == 1 else 's'} of accuracy ({self.fixed:g})"


def _paired_rule(sb: np.ndarray, tol: Tolerance) -> tuple[np.ndarray, ...]:
    """Paired rule on (B, P, R) resamples -> selected, best (B,), deficit, deficit_se (B, R), tolerance at selected (B,)."""
    mean, _, _, _ = _batch_stats(sb)
    valid = np.isfinite(mean)
    any_valid = valid.any(axis=1)
    best = np.argmax(np.where(valid, mean, -np.inf), axis=1)
    rows = np.arange(sb.shape[0])
    d = sb[rows, :, best][:, :, None] - sb  # (B, P, R): each participant's deficit from their best-point score
    deficit, _, dse, _ = _batch_stats(d)
    dse = np.where(np.isfinite(dse), dse, 0.0)
    deficit[rows, best] = 0.0
    dse[rows, best] = 0.0
    allowed = (tol.n_se * dse) if tol.n_se is not None else np.full(deficit.shape, tol.fixed)
    eligible = valid & np.isfinite(deficit) & (deficit <= allowed + _EPS)
    eligible[rows, best] |= valid[rows, best]
    selected = np.argmax(eligible, axis=1)
    selected = np.where(any_valid, selected, -1)
    best = np.where(any_valid, best, -1)
    return selected, best, deficit, dse, allowed[rows, np.maximum(selected, 0)]


def paired_saturation(
    scores: np.ndarray,
    tolerance: Tolerance | str | float = "0.01",
    n_boot: int = 2000,
    ci: float = 0.95,
    seed: int = 0,
) -> Saturation:
    """The paired rule (see module doc) on ``scores`` (P, R), columns coarse to fine, with a
    participant bootstrap (resample participants, redo the best point and the rule).

    ``Saturation.tolerance`` is the allowed deficit at the selected point
    (score units); ``deficit``/``deficit_se`` hold the paired curve.
    """
    tol = tolerance if isinstance(tolerance, Tolerance) else Tolerance.parse(tolerance)
    s, stats, _, _ = _scored(scores, ci, n_boot)
    sel, best, deficit, dse, allowed = _paired_rule(s[None], tol)
    index, best_index = int(sel[0]), int(best[0])
    base = dict(rule="paired", deficit=deficit[0], deficit_se=dse[0], tolerance_name=tol.name)
    gap = float(deficit[0, index])
    notes = []
    n_missing = int((~np.isfinite(s)).sum())
    if n_missing:
        notes.append(
            f"{n_missing} of {s.size} participant x point scores are missing (NaN) and were left out of their pairs"
        )
    single = "only one participant: no paired standard error and no bootstrap interval" + (
        "; the SE tolerance is 0, so the saturation point is the best point" if tol.n_se is not None else ""
    )
    sat = Saturation(index, best_index, float(allowed[0]), stats, s.shape[0], None, ci, 0, None, gap, None, "", **base)

    def select(sb: np.ndarray) -> np.ndarray:
        return _paired_rule(sb, tol)[0]

    return _outcome(
        sat, notes, single, n_boot, lambda: _bootstrap(s, index, best_index, n_boot, ci, seed, notes, select)
    )


# ---------------------------------------------------------------------------------------------------------------
# The envelope rule with cross-fitting over seeds (what the report uses)
# ---------------------------------------------------------------------------------------------------------------

#: Family-wise error rate of the envelope rule's "a finer point is outside the tolerance" decisions.
ENVELOPE_ALPHA = 0.05


@dataclass(frozen=True)
class RerunNoise:
    """How much one participant's score moves between reruns of the same sweep point."""

    per_participant: float
    """Standard deviation of one participant's score between reruns (score units; NaN when unknown)."""
    curve: float
    """The same for the participant mean of one run: ``per_participant / sqrt(P)``."""
    source: str
    """"seeds" (measured between the sweep's seeds) or "neighbours" (estimated from the jitter between
    neighbouring resolutions, the fallback for a sweep without replicates)."""

    def describe(self) -> str:
        how = (
            "measured between the sweep's seeds at the same point"
            if self.source == "seeds"
            else "no seeds to measure it: estimated from each participant's jitter between neighbouring resolutions "
            "(an upper estimate when the curve still changes between neighbours)"
        )
        return (
            f"rerun noise {self.per_participant:.3f} per participant, {self.curve:.3f} on the participant mean "
            f"of one run ({how})"
        )


def rerun_noise(scores: np.ndarray) -> RerunNoise:
    """The rerun noise of ``scores`` (S, P, R) seeds x participants x points (or (P, R): one seed).

    With two or more seeds: the pooled standard deviation between seeds of each participant's score at each
    point (``sqrt(mean over (p, r) of var_s(ddof=1))``). With one seed (the fallback): the robust spread of
    each participant's differences between neighbouring resolutions, ``1.4826 * median(|d|) / sqrt(2)``
    (differences that also carry the curve's real change, so it errs large).
    """
    s = _as_seeds(scores)
    n_seeds, n_part = s.shape[0], int(np.isfinite(s).any(axis=(0, 2)).sum())
    root_p = np.sqrt(max(n_part, 1))
    if n_seeds >= 2:
        finite = np.isfinite(s)
        k = finite.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"), _quiet():
            var = np.nanvar(s, axis=0, ddof=1)
        ok = (k >= 2) & np.isfinite(var)
        if ok.any():
            sd = float(np.sqrt(np.mean(var[ok])))
            return RerunNoise(sd, sd / root_p, "seeds")
    d = np.diff(s[0], axis=1)
    d = np.abs(d[np.isfinite(d)])
    sd = float(1.4826 * np.median(d) / np.sqrt(2.0)) if d.size else float("nan")
    return RerunNoise(sd, sd / root_p, "neighbours")


def _as_seeds(scores: np.ndarray) -> np.ndarray:
    """(P, R) or (S, P, R) -> (S, P, R) float64 with NaN for missing values."""
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim == 2:
        s = s[None]
    if s.ndim != 3:
        raise ValueError(
            f"scores must be a (participants, points) or (seeds, participants, points) array, got shape {s.shape}"
        )
    if 0 in s.shape:
        raise ValueError(f"scores is empty (shape {s.shape}): no seeds, participants or sweep points")
    return np.where(np.isfinite(s), s, np.nan)


def _wmean(x: np.ndarray, w: np.ndarray, axis: int) -> np.ndarray:
    """Weighted mean of ``x`` over ``axis`` skipping NaNs (NaN where no weight remains); ``w`` broadcasts."""
    w = np.broadcast_to(w, x.shape)
    ok = np.isfinite(x) & (w > 0)
    num = np.where(ok, x * w, 0.0).sum(axis=axis)
    den = np.where(ok, w, 0.0).sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)


def _envelope_rule(s: np.ndarray, w: np.ndarray, tol: Tolerance, floor: float, z: float) -> tuple[np.ndarray, ...]:
    """The envelope rule on B resamples.

    ``s`` (B, S, P, R) scores, ``w`` (B, S) seed weights (how often each seed was drawn; 0 = left out).
    Returns selected (B,), best (B,), deficit (B, R), deficit_se (B, R), allowed (B, R), crossfit (B,) bool.
    """
    n_b, n_s, n_p, n_r = s.shape
    rows = np.arange(n_b)
    part_mean = _wmean(s, np.ones(1), axis=2)  # (B, S, R): each seed's curve, mean over participants
    all_curve = _wmean(part_mean, w[:, :, None], axis=1)  # (B, R)
    valid = np.isfinite(all_curve)
    best_all = np.argmax(np.where(valid, all_curve, -np.inf), axis=1)  # first maximum = coarsest among ties
    d_sum = np.zeros((n_b, n_p, n_r))
    d_w = np.zeros((n_b, n_p, n_r))
    crossfit = np.zeros(n_b, dtype=bool)
    for k in range(n_s):  # fold k: choose the best point on the other seeds, measure it on seed k
        w_train = w.copy()
        w_train[:, k] = 0.0
        train = _wmean(part_mean, w_train[:, :, None], axis=1)  # (B, R)
        ok_fold = (w[:, k] > 0) & np.isfinite(train).any(axis=1)
        crossfit |= ok_fold
        b_k = np.argmax(np.where(np.isfinite(train), train, -np.inf), axis=1)
        sk = s[:, k]  # (B, P, R)
        d = sk[rows, :, b_k][:, :, None] - sk  # (B, P, R)
        wk = np.where(ok_fold, w[:, k], 0.0)[:, None, None] * np.isfinite(d)
        d_sum += np.where(wk > 0, d, 0.0) * wk
        d_w += wk
    # Resamples without two distinct seeds: the best point is chosen and measured on the same data.
    if not crossfit.all():
        nb = ~crossfit
        sb = s[nb]
        d = sb[np.arange(sb.shape[0]), :, :, best_all[nb]][:, :, :, None] - sb  # (b, S, P, R)
        d_mean = _wmean(d, w[nb][:, :, None, None], axis=1)  # (b, P, R)
        d_sum[nb] = np.where(np.isfinite(d_mean), d_mean, 0.0)
        d_w[nb] = np.isfinite(d_mean).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_part = np.where(d_w > 0, d_sum / np.where(d_w > 0, d_w, 1.0), np.nan)  # (B, P, R)
    deficit, _, dse, _ = _batch_stats(per_part)
    dse = np.where(np.isfinite(dse), dse, 0.0)
    if tol.n_se is not None:
        allowed = tol.n_se * dse
    else:
        allowed = np.full(deficit.shape, max(tol.fixed, floor))
    outside = valid & np.isfinite(deficit) & (deficit > allowed + z * dse + _EPS)
    r_idx = np.arange(n_r)
    last_out = np.max(np.where(outside, r_idx, -1), axis=1)
    # The requirement: the first valid point after the last point outside the tolerance.
    after = valid & (r_idx[None, :] > last_out[:, None])
    selected = np.where(after.any(axis=1), np.argmax(after, axis=1), -2)  # -2: even the finest point is out
    finest_valid = n_r - 1 - np.argmax(valid[:, ::-1], axis=1)
    selected = np.where(selected == -2, finest_valid, selected)
    any_valid = valid.any(axis=1)
    return (
        np.where(any_valid, selected, -1),
        np.where(any_valid, best_all, -1),
        deficit,
        dse,
        allowed,
        crossfit,
        last_out,
    )


def _family_z(n_points: int, alpha: float) -> float:
    """One-sided normal quantile for ``alpha`` shared (Bonferroni) among the ``n_points - 1`` comparisons."""
    from statistics import NormalDist

    if alpha <= 0:
        return float("inf")
    if alpha >= 1:
        return 0.0
    m = max(n_points - 1, 1)
    return float(NormalDist().inv_cdf(1.0 - alpha / m))


@dataclass(frozen=True)
class Envelope:
    """The envelope rule's extra outcome (see :func:`envelope_saturation`)."""

    noise: RerunNoise
    tolerance_requested: str
    """The tolerance asked for, as written (``0.01``, ``se``)."""
    tolerance_floor: float
    """The tolerance floor (the rerun noise of one run's curve; 0 when the floor is off or for SE tolerances)."""
    z: float
    """Noise margin in standard errors of a point's deficit (one-sided, ``alpha`` shared over the points)."""
    alpha: float
    n_seeds: int
    crossfit: bool
    """True when the best point was chosen and measured on different seeds."""
    finest_outside: bool
    """True when even the finest point is outside the tolerance (the curve falls at the fine end)."""
    outside: np.ndarray
    """(R,) bool: the points outside the tolerance on the full data."""


def envelope_saturation(
    scores: np.ndarray,
    tolerance: Tolerance | str | float = "0.01",
    n_boot: int = 2000,
    ci: float = 0.95,
    seed: int = 0,
    alpha: float = ENVELOPE_ALPHA,
    noise_floor: bool = True,
) -> tuple[Saturation, Envelope]:
    """The envelope rule on ``scores`` (P, R) or (S, P, R): seeds x participants x points, coarse to fine.

    1. **Best point, cross-fitted over seeds.** For each seed k, the best point is the one with the highest
       mean over the *other* seeds; each participant's deficit at a point is their score on seed k at that
       best point minus theirs on seed k at the point. The deficits are averaged over the folds, then over
       participants (``deficit``), with their standard error over participants (``deficit_se``). Choosing
       and measuring the best point on different replicates removes the winner's curse (the best of many
       noisy points is too high on the data that chose it). With one seed there is nothing to cross-fit:
       the best is chosen and measured on the same data, and the note says so.
    2. **Tolerance.** A fixed tolerance (``0.01`` = one point of accuracy) is raised to the rerun noise of
       one run's curve (:func:`rerun_noise`) when it is smaller (``noise_floor``); an SE tolerance (``se``,
       ``2se``) is ``k`` standard errors of each point's deficit.
    3. **Envelope.** A point is *outside* the tolerance when its deficit exceeds it by more than ``z``
       standard errors (one-sided, family-wise ``alpha`` shared among the points, Bonferroni). The
       requirement is the coarsest point from which every finer point is inside: the first point after the
       last point outside. Should the finest point itself be outside, the finest point is returned and
       :attr:`Envelope.finest_outside` says so.

    The interval is a two-level bootstrap: participants with replacement (whole rows over all seeds and
    points) and, with two or more seeds, seeds with replacement; each resample redoes the cross-fitting,
    the best point and the rule (the rerun noise and the tolerance stay those of the full data).
    """
    tol = tolerance if isinstance(tolerance, Tolerance) else Tolerance.parse(tolerance)
    _check_bootstrap(ci, n_boot)
    if not 0.0 <= alpha < 1.0:
        raise ValueError(f"alpha={alpha!r} is invalid: must be in [0, 1)")
    s = _as_seeds(scores)
    s = s[:, np.isfinite(s).any(axis=(0, 2))]  # participants with no score at all carry no information
    if s.shape[1] == 0:
        raise ValueError("no finite score at any sweep point: nothing to find a saturation point on")
    n_seeds, n_part, n_pts = s.shape
    noise = rerun_noise(s)
    floor = noise.curve if (noise_floor and tol.n_se is None and np.isfinite(noise.curve)) else 0.0
    z = _family_z(n_pts, alpha) if n_part >= 2 else 0.0
    w1 = np.ones((1, n_seeds))
    sel, best, deficit, dse, allowed, crossfit, last_out = _envelope_rule(s[None], w1, tol, floor, z)
    index, best_index = int(sel[0]), int(best[0])
    seed_avg = _wmean(s, np.ones(1), axis=0)  # (P, R) each participant's mean over seeds
    mean, std, se, n = _batch_stats(seed_avg[None])
    stats = CurveStats(mean[0], std[0], se[0], n[0])
    outside = np.isfinite(deficit[0]) & (deficit[0] > allowed[0] + z * dse[0] + _EPS) & np.isfinite(mean[0])
    finest_outside = bool(last_out[0] == n_pts - 1)
    env = Envelope(
        noise, tol.name, float(floor), float(z), float(alpha), n_seeds, bool(crossfit[0]), finest_outside, outside
    )
    base = dict(rule="envelope", deficit=deficit[0], deficit_se=dse[0], tolerance_name=tol.name)
    gap = float(deficit[0, index])
    notes = []
    n_missing = int((~np.isfinite(s)).sum())
    if n_missing:
        notes.append(f"{n_missing} of {s.size} seed x participant x point scores are missing (NaN) and were skipped")
    if n_seeds < 2:
        notes.append(
            "one seed: the best point is chosen and measured on the same runs (no cross-fitting over "
            "seeds, so the best is biased high and the requirement errs fine)"
        )
    if finest_outside:
        notes.append(
            "even the finest point swept is outside the tolerance of the best: the curve falls at the fine "
            "end, so no swept resolution keeps every finer one within tolerance"
        )

    def resample() -> tuple[tuple[int, int], np.ndarray, tuple[float, float] | None]:
        rng = np.random.default_rng(seed)
        boot_sel = np.empty(n_boot, dtype=np.int64)
        boot_gap = np.empty(n_boot, dtype=np.float64)
        chunk = max(1, int(1e6 // max(s.size, 1)))
        for start in range(0, n_boot, chunk):
            b = min(chunk, n_boot - start)
            pidx = rng.integers(0, n_part, size=(b, n_part))
            sb = np.moveaxis(s[:, pidx], 0, 1)  # (b, S, P, R)
            if n_seeds >= 2:
                draws = rng.integers(0, n_seeds, size=(b, n_seeds))
                wb = np.stack([np.bincount(d, minlength=n_seeds) for d in draws]).astype(float)
            else:
                wb = np.ones((b, 1))
            sel_b, _, def_b, _, _, _, _ = _envelope_rule(sb, wb, tol, floor, z)
            boot_sel[start : start + b] = sel_b
            boot_gap[start : start + b] = def_b[np.arange(b), index]
        return _bootstrap_intervals(boot_sel, boot_gap, n_part, ci, notes)

    single = "only one participant: no standard error and no bootstrap interval"
    sat = Saturation(
        index, best_index, float(allowed[0, index]), stats, n_part, None, ci, 0, None, gap, None, "", **base
    )
    return _outcome(sat, notes, single, n_boot, resample, note_first=True), env
