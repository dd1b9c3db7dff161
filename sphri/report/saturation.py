"""The requirement rule: the coarsest pitch certified to keep accuracy within T of the best (pure functions).

Input is a score array of shape (S, P, R) or (P, R): seeds x participants x
sweep points, the points ordered **coarse to fine** (fewest taxels first).
Entries are accuracies (or any score in which higher is better); NaN marks a
missing value (a failed job, a fold without that gesture, ...).

The claim the rule makes, and proves at confidence ``1 - alpha``: *from the
chosen pitch on, every finer swept pitch is within T of the best swept pitch*.

1. **Participants are the unit.** Each participant's scores are averaged over
   the seeds first; the seeds only make each participant's score less noisy.
2. **Paired deficits against every candidate best.** For each pair of points
   (j, r), each participant's difference ``x[p, j] - x[p, r]`` (participants
   missing either score are left out of that pair) has a mean and a standard
   error over participants: a participant x resolution effect (one person
   gains more from fine skin than another) is in that spread, and so in the
   bound. The one-sided upper confidence bound of the pair is
   ``mean + t * se`` with Student's t at ``n - 1`` degrees of freedom.
3. **The best is not chosen, so its selection costs nothing.** A point's
   bound is the largest of its bounds against *every* point j:
   ``bound[r] = max_j (mean_jr + t * se_jr)``. Whichever point truly is best,
   the bound against it is among them, so no winner's curse enters (a best
   chosen as the highest observed mean is too high on the data that chose it).
4. **Multiplicity.** The true best's comparisons with the other R - 1 points
   must hold together: ``t`` is taken at ``1 - alpha / (R - 1)``
   (Bonferroni). With probability at least ``1 - alpha`` then, for every
   point r at once, the true gap of r to the true best is at most
   ``bound[r]``; that holds for any T, including one chosen from the data.
5. **Envelope.** A point is *certified at T* when it and every finer point
   have ``bound <= T``. The requirement is the coarsest certified point.
6. **The smallest certifiable T.** ``T* = bound[finest]`` is the smallest T at
   which any pitch is certified (the bounds' suffix maximum only grows toward
   the coarse end). A T asked for below ``T*`` cannot be certified with these
   participants and seeds: the rule uses ``max(T, T*)`` and says so, never a
   smaller T.

The interval is a bootstrap: participants with replacement (whole rows over
seeds and points) and, with two or more seeds, seeds with replacement; each
resample redoes the bounds and the envelope at the T the full data used.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

#: Slack for float comparisons of means (scores are in [0, 1]).
_EPS = 1e-12

#: The rule's error rate: the probability that the true gap of a certified point to the true best exceeds T.
CERTIFY_ALPHA = 0.05


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
    """Outcome of the rule on one curve (indices into the R points)."""

    index: int
    """Selected point (the requirement), index into the coarse-to-fine order."""
    best_index: int
    """Point with the highest mean (reported; the rule does not rely on it)."""
    tolerance: float
    """The tolerance certified (score units): the one asked for, or the smallest certifiable when larger."""
    stats: CurveStats
    n_participants: int
    """Participants with at least one finite score."""
    interval: tuple[int, int] | None
    """(low, high) percentile indices of the bootstrap, or None (see ``note``)."""
    ci: float
    n_boot: int
    """Bootstrap resamples kept (0 when no interval)."""
    boot_index: np.ndarray | None
    """(n_boot,) int64 selected index per resample, or None."""
    gap: float
    """Mean paired shortfall of the selected point from the best-mean point (score units)."""
    gap_interval: tuple[float, float] | None
    """Bootstrap percentile interval of ``gap``, or None."""
    note: str
    """Why something is missing or degenerate ("" when all is well)."""
    deficit: np.ndarray
    """(R,) mean paired deficit from the best-mean point (0 there)."""
    deficit_se: np.ndarray
    """(R,) paired standard error of ``deficit``."""
    bound: np.ndarray
    """(R,) upper confidence bound of each point's gap to the best (any candidate best; inf when unknown)."""
    rule: str = "certified"

    @property
    def at_finest(self) -> bool:
        """True when the rule picked the finest point: the sweep may not have saturated."""
        return self.index == self.stats.mean.shape[0] - 1 and self.stats.mean.shape[0] > 1


@dataclass(frozen=True)
class Certificate:
    """What the rule certified on one curve (see :func:`certified_saturation`)."""

    noise: RerunNoise
    tolerance_requested: float
    """T asked for (score units)."""
    certifiable: float
    """T*: the smallest tolerance at which any swept pitch is certified (the finest point's bound)."""
    tolerance_used: float
    """``max(tolerance_requested, certifiable)``: the T the requirement is stated with."""
    alpha: float
    t: float
    """Student's t quantile of the bounds (one-sided, ``alpha`` shared over R - 1 points; at the fewest pairs)."""
    n_seeds: int
    n_participants: int
    outside: np.ndarray
    """(R,) bool: points whose bound exceeds the tolerance used (not certified within it)."""

    @property
    def raised(self) -> bool:
        """True when the T asked for could not be certified and the larger T* is used."""
        return self.certifiable > self.tolerance_requested + _EPS

    def describe(self) -> str:
        """The certificate in words (for the summary and the page)."""
        head = (
            f"smallest certifiable tolerance {points_text(self.certifiable)} with {self.n_participants} "
            f"participants and {self.n_seeds} seed{'s' if self.n_seeds != 1 else ''}"
        )
        if self.raised:
            head += f"; the {points_text(self.tolerance_requested)} asked for cannot be certified, so it is used"
        return head + (
            f"; {1 - self.alpha:.0%} confidence, one-sided bounds on paired deficits against every point, "
            f"Bonferroni over the points (t = {self.t:.2f})"
        )


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


def _check_bootstrap(ci: float, n_boot: int) -> None:
    if not 0.0 < ci < 1.0:
        raise ValueError(f"ci={ci!r} is invalid: must be in (0, 1)")
    if n_boot < 0:
        raise ValueError(f"n_boot={n_boot!r} is invalid: must be >= 0")


def _t_quantile(q: float, df: np.ndarray) -> np.ndarray:
    """Student's t quantile ``q`` at ``df`` degrees of freedom (NaN where df < 1)."""
    from scipy.stats import t as student

    df = np.asarray(df, dtype=np.float64)
    out = np.full(df.shape, np.nan)
    ok = df >= 1
    out[ok] = student.ppf(q, df[ok])
    return out


def _bounds(x: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bounds on B resamples of per-participant (seed-averaged) scores ``x`` (B, P, R).

    Returns bound (B, R) (max over j of the pair's upper bound; inf where a pair lacks two participants),
    best (B,) (highest mean, -1 when none), deficit and deficit_se (B, R) against that best.
    """
    n_b, _, n_r = x.shape
    mean, _, _, _ = _batch_stats(x)
    valid = np.isfinite(mean)
    m = np.maximum(valid.sum(axis=1) - 1, 1)  # (B,) comparisons the true best makes
    d = x[:, :, :, None] - x[:, :, None, :]  # (B, P, j, r)
    dm, _, dse, dn = _batch_stats(d.reshape(n_b, x.shape[1], n_r * n_r))
    dm, dse, dn = (a.reshape(n_b, n_r, n_r) for a in (dm, dse, dn))
    q = np.broadcast_to((1.0 - alpha / m)[:, None, None], dn.shape)
    from scipy.stats import t as student

    tq = np.full(dn.shape, np.nan)
    ok = dn >= 2
    tq[ok] = student.ppf(q[ok], dn[ok] - 1)
    ucb = np.where(ok, dm + tq * dse, np.inf)
    pair_valid = valid[:, :, None] & valid[:, None, :]
    ucb = np.where(pair_valid, ucb, -np.inf)
    eye = np.eye(n_r, dtype=bool)[None]
    ucb = np.where(eye & pair_valid, 0.0, ucb)
    bound = np.where(valid, ucb.max(axis=1), np.nan)  # (B, r): max over candidate bests j
    best = np.where(valid.any(axis=1), np.argmax(np.where(valid, mean, -np.inf), axis=1), -1)
    rows = np.arange(n_b)
    bi = np.maximum(best, 0)
    deficit = dm[rows, bi, :]
    deficit_se = np.where(np.isfinite(dse[rows, bi, :]), dse[rows, bi, :], 0.0)
    return bound, best, deficit, deficit_se


def _envelope(bound: np.ndarray, tol: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(selected (B,), certifiable T* (B,)) from bounds (B, R) (NaN = invalid point) at tolerances ``tol`` (B,).

    ``tol`` NaN: use T* itself. The selection is the coarsest valid point from which every finer valid point
    has ``bound <= max(tol, T*)``; -1 where no point is valid.
    """
    valid = np.isfinite(bound) | np.isposinf(bound)
    b = np.where(valid, bound, -np.inf)
    suffix = np.maximum.accumulate(b[:, ::-1], axis=1)[:, ::-1]  # max over this and every finer point
    any_valid = valid.any(axis=1)
    finest = bound.shape[1] - 1 - np.argmax(valid[:, ::-1], axis=1)
    t_star = np.where(any_valid, b[np.arange(b.shape[0]), finest], np.nan)
    used = np.fmax(tol, t_star)
    ok = valid & (suffix <= used[:, None] + _EPS)
    selected = np.where(ok.any(axis=1) & np.isfinite(used), np.argmax(ok, axis=1), finest)  # no bound: finest
    return np.where(any_valid, selected, -1), t_star


def certified_saturation(
    scores: np.ndarray,
    tolerance: Tolerance | str | float = "0.01",
    n_boot: int = 2000,
    ci: float = 0.95,
    seed: int = 0,
    alpha: float = CERTIFY_ALPHA,
) -> tuple[Saturation, Certificate]:
    """The rule (see the module doc) on ``scores`` (S, P, R) or (P, R), points coarse to fine.

    ``tolerance``: T asked for (``0.01`` = one point); the rule uses ``max(T, T*)``. ``n_boot``: bootstrap
    resamples for the interval (0 = none). ``alpha``: the probability allowed that a certified point's true
    gap to the true best exceeds the tolerance used. Raises ValueError for a malformed array or when no
    point has a finite score.
    """
    tol = tolerance if isinstance(tolerance, Tolerance) else Tolerance.parse(tolerance)
    _check_bootstrap(ci, n_boot)
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha={alpha!r} is invalid: must be in (0, 1)")
    s = _as_seeds(scores)
    s = s[:, np.isfinite(s).any(axis=(0, 2))]  # participants with no score at all carry no information
    if s.shape[1] == 0:
        raise ValueError("no finite score at any sweep point: nothing to find a requirement on")
    sat, cert = _certify(s, tol, ci, alpha)
    notes = _rule_notes(s, tol, cert)
    used, n_part = sat.tolerance, cert.n_participants
    if n_part < 2 or n_boot == 0 or not np.isfinite(used):
        notes.insert(0, _no_interval_reason(n_part, n_boot))
        return replace(sat, note="; ".join(notes)), cert
    boot_sel, boot_gap = _bootstrap_draws(s, alpha, used, sat.best_index, sat.index, n_boot, seed)
    interval, picked, gap_interval = _bootstrap_intervals(boot_sel, boot_gap, n_part, ci, notes)
    sat = replace(
        sat,
        interval=interval,
        n_boot=int(picked.size),
        boot_index=picked,
        gap_interval=gap_interval,
        note="; ".join(notes),
    )
    return sat, cert


def _certify(s: np.ndarray, tol: Tolerance, ci: float, alpha: float) -> tuple[Saturation, Certificate]:
    """The rule on the full data ``s`` (S, P, R): the selected point, its bounds and certificate, without
    the bootstrap interval (``interval``, ``boot_index``, ``gap_interval`` None, ``note`` "")."""
    n_seeds, n_part, _ = s.shape
    noise = rerun_noise(s)
    x = _wmean(s, np.ones(1), axis=0)  # (P, R): each participant's mean over the seeds
    bound, best, deficit, dse = _bounds(x[None], alpha)
    sel, t_star = _envelope(bound, np.array([tol.fixed]))
    index, best_index, t_star_v = int(sel[0]), int(best[0]), float(t_star[0])
    used = max(tol.fixed, t_star_v)
    mean, std, se, n = _batch_stats(x[None])
    stats = CurveStats(mean[0], std[0], se[0], n[0])
    n_valid = int(np.isfinite(stats.mean).sum())
    t_q = float(_t_quantile(1.0 - alpha / max(n_valid - 1, 1), np.array([n_part - 1]))[0])
    outside = np.isfinite(stats.mean) & ~(bound[0] <= used + _EPS)
    cert = Certificate(noise, tol.fixed, t_star_v, used, float(alpha), t_q, n_seeds, n_part, outside)
    sat = Saturation(
        index,
        best_index,
        used,
        stats,
        n_part,
        None,
        ci,
        0,
        None,
        float(deficit[0, index]),
        None,
        "",
        deficit=deficit[0],
        deficit_se=dse[0],
        bound=bound[0],
    )
    return sat, cert


def _rule_notes(s: np.ndarray, tol: Tolerance, cert: Certificate) -> list[str]:
    """What the rule on ``s`` (S, P, R) skipped or could not certify, in words."""
    n_seeds, n_part, _ = s.shape
    t_star_v = cert.certifiable
    notes = []
    n_missing = int((~np.isfinite(s)).sum())
    if n_missing:
        notes.append(f"{n_missing} of {s.size} seed x participant x point scores are missing (NaN) and were skipped")
    if not np.isfinite(t_star_v):
        notes.append(
            "fewer than two participants at the finest point: no bound, nothing certified; the finest point is returned"
        )
    elif cert.raised:
        notes.append(
            f"the {points_text(tol.fixed)} asked for cannot be certified with {n_part} participants and "
            f"{n_seeds} seed{'s' if n_seeds != 1 else ''}: the smallest certifiable is {points_text(t_star_v)}"
        )
    return notes


def _no_interval_reason(n_part: int, n_boot: int) -> str:
    """Why the rule gives no bootstrap interval: one participant, no resamples asked for, or no finite T."""
    if n_part < 2:
        return "only one participant: no bound and no bootstrap interval"
    return "no bootstrap requested (n_boot=0): no interval" if n_boot == 0 else "no finite tolerance: no interval"


def _bootstrap_draws(
    s: np.ndarray, alpha: float, used: float, best_index: int, index: int, n_boot: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """(selected point (n_boot,), paired gap of ``index`` to ``best_index`` (n_boot,)) on resamples of the
    participants of ``s`` (S, P, R) and, with two or more seeds, of the seeds; each redoes the bounds and the
    envelope at the tolerance ``used``. Resamples are drawn in chunks that keep the pair arrays small."""
    n_seeds, n_part, n_pts = s.shape
    rng = np.random.default_rng(seed)
    boot_sel = np.empty(n_boot, dtype=np.int64)
    boot_gap = np.empty(n_boot, dtype=np.float64)
    chunk = max(1, int(4e6 // max(n_part * n_pts * n_pts, 1)))
    for start in range(0, n_boot, chunk):
        b = min(chunk, n_boot - start)
        pidx = rng.integers(0, n_part, size=(b, n_part))
        sb = np.moveaxis(s[:, pidx], 0, 1)  # (b, S, P, R)
        if n_seeds >= 2:
            draws = rng.integers(0, n_seeds, size=(b, n_seeds))
            wb = np.stack([np.bincount(d, minlength=n_seeds) for d in draws]).astype(float)
        else:
            wb = np.ones((b, 1))
        xb = _wmean(sb, wb[:, :, None, None], axis=1)  # (b, P, R)
        bound_b = _bounds(xb, alpha)[0]
        sel_b, _ = _envelope(bound_b, np.full(b, used))
        boot_sel[start : start + b] = sel_b
        with np.errstate(invalid="ignore"), _quiet():
            boot_gap[start : start + b] = np.nanmean(xb[:, :, best_index] - xb[:, :, index], axis=1)
    return boot_sel, boot_gap


def certify_index(scores: np.ndarray, tolerance: float, alpha: float = CERTIFY_ALPHA) -> tuple[int, float]:
    """(selected index, tolerance used) of the rule on ``scores`` without a bootstrap: the simulations' fast path."""
    sat, cert = certified_saturation(scores, tolerance, n_boot=0, alpha=alpha)
    return sat.index, cert.tolerance_used


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
    """How far below the best a resolution may be: a number in score units (``0.01`` = one point of accuracy)."""

    name: str
    points: float
    """The tolerance in score units."""

    @property
    def fixed(self) -> float:
        return float(self.points)

    @classmethod
    def parse(cls, text: str | float) -> Tolerance:
        t = str(text).strip().lower()
        if t.endswith("se"):
            raise ValueError(
                f"tolerance {text!r} is invalid: the rule certifies a tolerance in accuracy units (0.01 = 1 point); "
                "a tolerance in standard errors is not a promise about accuracy"
            )
        try:
            v = float(t)
        except ValueError:
            raise ValueError(f"tolerance {text!r} is invalid: write a number in accuracy units such as 0.01") from None
        if not np.isfinite(v) or not 0 <= v < 1:
            raise ValueError(f"tolerance {text!r} is invalid: a tolerance must be in [0, 1) accuracy units")
        return cls(f"{v:g}", v)

    def describe(self) -> str:
        """E.g. "1 point of accuracy (0.01)"."""
        return points_text(self.fixed)


def points_text(t: float) -> str:
    """A tolerance in words: "1 point of accuracy (0.01)", "2.7 points of accuracy (0.027)"."""
    pts = round(100 * t, 1)
    return f"{pts:g} point{'' if pts == 1 else 's'} of accuracy ({t:.3g})"


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
