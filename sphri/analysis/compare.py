"""Do two conditions produce different touch distributions? Paired SWD tests.

Design (per pair of conditions a, b and per participant i). Each
condition's trials of participant i are split into two halves of equal trial
count ``k = min(n_a, n_b) // 2`` (alternating by trial order: 1st, 3rd, ...
vs 2nd, 4th, ...; extra trials are left out so that all four halves hold
``k`` trials). With surface densities a1, a2, b1, b2 of the halves:

    between_i = (SW(a1, b2) + SW(a2, b1)) / 2      cross-condition
    within_i  = (SW(a1, a2) + SW(b1, b2)) / 2      split-half baseline
    d_i       = between_i - within_i

If a and b produce the same distribution for participant i, the four
halves are exchangeable; swapping a2 with b2 maps d_i to -d_i, so d_i is
symmetric about 0 whatever the participant's own distribution, and the
sign-flip test over participants (:func:`sphri.analysis.stats.sign_flip_test`,
one-sided: differences make ``between`` exceed ``within``) is exact under
the null. All pairs of one analysis are Holm-corrected together.

A participant enters a pair's test only with >= 2 trials with contact in
both conditions (so that each half has one); the count used is reported.

Every trial enters. When ``2 k`` is less than a condition's trial count
(three repetitions give k = 1: one split-half would leave the third out),
``halves`` may return several splits (:func:`rotated_halves`: the trial
order rotated by each offset, so each trial lies in some split) and d_i is
the mean of the splits' differences. Each split's difference is symmetric
about 0 under the null as above; their mean keeps E[d_i] = 0, and the
sign-flip test on it is exact only up to the splits' dependence (one split,
the default with an even trial count, stays exact).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri.analysis.stats import holm, sign_flip_test
from sphri.analysis.swd import SharedSupportSW

#: (participant, cond_a, cond_b) -> (halves of a (2, P), halves of b (2, P)), a list of such splits, or None.
HalvesFn = Callable[[str, str, str], "tuple[np.ndarray, np.ndarray] | list[tuple[np.ndarray, np.ndarray]] | None"]

TABLE_COLUMNS = (
    "cond_a",
    "cond_b",
    "n_participants",
    "mean_between_swd_mm",
    "mean_within_swd_mm",
    "mean_diff_swd_mm",
    "p_value",
    "p_holm",
    "significant",
    "exact",
    "n_permutations",
)


@dataclass
class PairwiseComparison:
    """All pairwise condition tests of one analysis.

    ``table``: one row per pair (columns :data:`TABLE_COLUMNS`; SWD in mm,
    ``p_holm`` Holm-adjusted over the pairs, ``significant`` = p_holm <=
    alpha). ``per_participant``: participant, cond_a, cond_b, between_mm,
    within_a_mm, within_b_mm, diff_mm.
    """

    conditions: list[str]
    table: pd.DataFrame
    per_participant: pd.DataFrame
    alpha: float
    alternative: str
    swd_p: float
    n_projections: int

    def matrix(self, column: str) -> pd.DataFrame:
        """(C, C) symmetric matrix of a table column; diagonal: within-condition
        baseline for ``mean_between_swd_mm``, NaN otherwise."""
        c = self.conditions
        m = pd.DataFrame(np.nan, index=c, columns=c, dtype=float)
        for row in self.table.itertuples(index=False):
            v = float(getattr(row, column))
            m.loc[row.cond_a, row.cond_b] = v
            m.loc[row.cond_b, row.cond_a] = v
        if column == "mean_between_swd_mm":
            for cond, val in self.within_baseline().items():
                m.loc[cond, cond] = val
        return m

    def within_baseline(self) -> dict[str, float]:
        """Mean split-half SWD (mm) of each condition over participants and pairs."""
        pp = self.per_participant
        out = {}
        for cond in self.conditions:
            vals = np.concatenate(
                [
                    pp.loc[pp["cond_a"] == cond, "within_a_mm"].to_numpy(float),
                    pp.loc[pp["cond_b"] == cond, "within_b_mm"].to_numpy(float),
                ]
            )
            out[cond] = float(vals.mean()) if vals.size else float("nan")
        return out

    def write_csv(self, out_dir: str | Path, prefix: str = "swd") -> list[Path]:
        """``<prefix>_pairs.csv``, ``<prefix>_participants.csv``, ``<prefix>_matrix_mm.csv``,
        ``<prefix>_p_holm_matrix.csv``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = [
            out / f"{prefix}_pairs.csv",
            out / f"{prefix}_participants.csv",
            out / f"{prefix}_matrix_mm.csv",
            out / f"{prefix}_p_holm_matrix.csv",
        ]
        self.table.to_csv(paths[0], index=False, float_format="%.6g")
        self.per_participant.to_csv(paths[1], index=False, float_format="%.6g")
        self.matrix("mean_between_swd_mm").to_csv(paths[2], float_format="%.6g")
        self.matrix("p_holm").to_csv(paths[3], float_format="%.6g")
        return paths


def split_halves(ordinals: Sequence[int] | np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions (into ``ordinals``) of two alternating halves of ``k`` trials each.

    Trials are ordered by ``ordinals`` (ties by position); the first ``2 k``
    are dealt alternately to half 0 and half 1.
    """
    return rotated_halves(ordinals, k, 0)


def rotated_halves(ordinals: Sequence[int] | np.ndarray, k: int, r: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`split_halves` of the trial order rotated by ``r`` (``r = 0``: the same): with ``n`` trials,
    the rotations ``0 .. n - 1`` put every trial in some split when ``2 k < n``."""
    o = np.asarray(ordinals)
    if k < 1 or 2 * k > o.size:
        raise ValueError(f"cannot split {o.size} trials into two halves of {k}")
    pos = np.roll(np.argsort(o, kind="stable"), -int(r))[: 2 * k]
    return pos[0::2], pos[1::2]


def n_rotations(n_trials: int, k: int) -> int:
    """Rotations :func:`rotated_halves` needs so that each of ``n_trials`` trials enters (1 when ``2 k = n``)."""
    return 1 if 2 * k >= n_trials else int(n_trials)


@dataclass
class _PairPlan:
    """One pair's planned distances: the participants that enter, per split the indices of its four distances
    (a1-b2, a2-b1, a1-a2, b1-b2) into the flat distance list, and each participant's number of splits."""

    a: str
    b: str
    used: list[str]
    idx4: list[list[int]]
    n_splits: list[int]


def _plan_pairs(
    sw: SharedSupportSW, participants: Sequence[str], conditions: list[str], halves: HalvesFn
) -> tuple[list[_PairPlan], list[np.ndarray], list[np.ndarray]]:
    """Per pair of ``conditions`` (in :func:`itertools.combinations` order) the distances its test needs, each
    distance listed once: (plans, left masses, right masses), the masses (P,) on ``sw.support``. A
    within-condition split (the same cached halves, by identity) recurs in each pair it enters."""
    wa_all: list[np.ndarray] = []
    wb_all: list[np.ndarray] = []
    keep: list[object] = []  # keeps the ids below unique while planning
    jobs: dict[tuple, int] = {}

    def job(key: tuple, x: np.ndarray, y: np.ndarray) -> int:
        if key not in jobs:
            jobs[key] = len(wa_all)
            wa_all.append(x)
            wb_all.append(y)
        return jobs[key]

    plan = []
    for a, b in combinations(conditions, 2):
        p = _PairPlan(a, b, [], [], [])
        for part in participants:
            h = halves(part, a, b)
            if h is None:
                continue
            splits = h if isinstance(h, list) else [h]
            for split in splits:
                keep.append(split)
                ha, hb = (np.asarray(x, dtype=np.float64) for x in split)
                if ha.shape != (2, sw.support.shape[0]) or hb.shape != ha.shape:
                    raise ValueError(f"halves({part!r}, {a!r}, {b!r}) must be two (2, {sw.support.shape[0]}) arrays")
                ia, ib = id(split[0]), id(split[1])
                p.idx4.append(
                    [
                        job(("ab", ia, ib), ha[0], hb[1]),
                        job(("ba", ia, ib), ha[1], hb[0]),
                        job(("w", ia), ha[0], ha[1]),
                        job(("w", ib), hb[0], hb[1]),
                    ]
                )
            p.used.append(part)
            p.n_splits.append(len(splits))
        plan.append(p)
    return plan, wa_all, wb_all


def _all_distances(sw: SharedSupportSW, wa_all: list[np.ndarray], wb_all: list[np.ndarray]) -> np.ndarray:
    """(J,) sliced Wasserstein distance (mm) of each planned (left, right) pair of masses, in chunks of 128
    (each row is a whole-surface weighting)."""
    return np.concatenate(
        [np.zeros(0)]
        + [
            sw.distances(np.stack(wa_all[i : i + 128]), np.stack(wb_all[i : i + 128])) * 1e3
            for i in range(0, len(wa_all), 128)
        ]
    )


def _test_pair(
    p: _PairPlan, all_dist: np.ndarray, alternative: str, exact_max: int, n_permutations: int, seed: int
) -> tuple[dict, list[dict]]:
    """One pair's table row (without ``p_holm``, ``significant``) and its per-participant rows: the split-half
    distances (mm) averaged per participant, their between - within differences sign-flip tested with ``seed``."""
    n = len(p.used)
    row: dict[str, Any] = {"cond_a": p.a, "cond_b": p.b, "n_participants": n}
    if n == 0:
        row.update(
            mean_between_swd_mm=np.nan,
            mean_within_swd_mm=np.nan,
            mean_diff_swd_mm=np.nan,
            p_value=np.nan,
            exact=False,
            n_permutations=0,
        )
        return row, []
    flat = all_dist[np.asarray(p.idx4)]  # one row per split
    owner = np.repeat(np.arange(n), p.n_splits)
    dist = (
        np.stack([np.bincount(owner, flat[:, c], minlength=n) for c in range(4)], axis=1)
        / np.asarray(p.n_splits)[:, None]
    )
    between = dist[:, :2].mean(axis=1)
    within = dist[:, 2:].mean(axis=1)
    diff = between - within
    res = sign_flip_test(diff, alternative=alternative, exact_max=exact_max, n_permutations=n_permutations, seed=seed)
    row.update(
        mean_between_swd_mm=float(between.mean()),
        mean_within_swd_mm=float(within.mean()),
        mean_diff_swd_mm=res.statistic,
        p_value=res.p_value,
        exact=res.exact,
        n_permutations=res.n_permutations,
    )
    prows = [
        {
            "participant": part,
            "cond_a": p.a,
            "cond_b": p.b,
            "between_mm": bt,
            "within_a_mm": wa_,
            "within_b_mm": wb_,
            "diff_mm": df,
            "n_splits": ns,
        }
        for part, bt, wa_, wb_, df, ns in zip(p.used, between, dist[:, 2], dist[:, 3], diff, p.n_splits)
    ]
    return row, prows


def paired_swd_tests(
    sw: SharedSupportSW,
    participants: Sequence[str],
    conditions: Sequence[str],
    halves: HalvesFn,
    alpha: float = 0.05,
    alternative: str = "greater",
    exact_max: int = 12,
    n_permutations: int = 9999,
    seed: int = 0,
) -> PairwiseComparison:
    """Test every pair of ``conditions`` with the split-half paired design.

    ``halves(participant, a, b)`` returns the two halves' masses on
    ``sw.support`` for each condition (built with :func:`split_halves` at
    the pair's common ``k``), or None to leave the participant out.
    The i-th pair's sign-flip test draws with ``seed + i``.
    """
    conditions = list(conditions)
    if len(conditions) < 2:
        raise ValueError(f"need at least two conditions to compare, got {conditions}")
    plan, wa_all, wb_all = _plan_pairs(sw, participants, conditions, halves)
    all_dist = _all_distances(sw, wa_all, wb_all)
    rows, prows = [], []
    for idx, p in enumerate(plan):
        row, per_part = _test_pair(p, all_dist, alternative, exact_max, n_permutations, seed + idx)
        rows.append(row)
        prows += per_part
    table = pd.DataFrame(rows)
    table["p_holm"] = holm(table["p_value"].to_numpy(float))
    table["significant"] = table["p_holm"].to_numpy(float) <= alpha
    table = table[list(TABLE_COLUMNS)]
    per = pd.DataFrame(
        prows,
        columns=["participant", "cond_a", "cond_b", "between_mm", "within_a_mm", "within_b_mm", "diff_mm", "n_splits"],
    )
    return PairwiseComparison(conditions, table, per, float(alpha), alternative, sw.p, sw.n_projections)
