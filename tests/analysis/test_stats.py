"""Sign-flip permutation test, Holm correction and the paired split-half SWD design."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from sphri.analysis.compare import paired_swd_tests, split_halves
from sphri.analysis.stats import holm, sign_flip_test
from sphri.analysis.swd import SharedSupportSW


def brute_force_p(d, alternative):
    """Exact p by enumeration; d are multiples of 1/8, so sums (and ties) are exact."""
    d = np.asarray(d, float)
    t = d.sum()
    null = np.array([np.sum(np.array(s) * d) for s in itertools.product([-1, 1], repeat=d.size)])
    if alternative == "greater":
        return np.mean(null >= t)
    if alternative == "less":
        return np.mean(null <= t)
    return np.mean(np.abs(null) >= abs(t))


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.integers(-40, 40).map(lambda i: i / 8), min_size=1, max_size=9),
    st.sampled_from(["greater", "less", "two-sided"]),
)
def test_exact_test_enumerates_every_sign_flip(d, alternative):
    res = sign_flip_test(d, alternative=alternative)
    assert res.exact and res.n_permutations == 2 ** len(d) and res.n == len(d)
    assert res.p_value == pytest.approx(brute_force_p(d, alternative), abs=1e-12)
    # an exact p is a multiple of 2^-n and never below it
    assert res.p_value * 2 ** len(d) == pytest.approx(round(res.p_value * 2 ** len(d)))
    assert res.p_value >= 2.0 ** -len(d)


def test_ties_count_as_extreme_whatever_the_scale():
    for scale in (1e-150, 1.0, 1e150):
        assert sign_flip_test([scale]).p_value == 0.5  # {+d, -d}: only +d reaches d
        assert sign_flip_test([scale, -scale]).p_value == 0.75  # sums d-d, d+d, -d-d, -d+d: three reach 0
        assert sign_flip_test([scale, -scale], alternative="two-sided").p_value == 1.0


def test_exact_up_to_threshold_then_monte_carlo_with_stated_count():
    d = np.linspace(0.1, 1.0, 12)
    assert sign_flip_test(d, exact_max=12).exact
    assert sign_flip_test(d, exact_max=12).p_value == pytest.approx(2.0**-12)
    d13 = np.linspace(0.1, 1.0, 13)
    mc = sign_flip_test(d13, exact_max=12, n_permutations=999, seed=1)
    assert not mc.exact and mc.n_permutations == 999
    # all positive: only the observed arrangement (and MC draws of all +) reach T
    assert mc.p_value == pytest.approx(1 / 1000, abs=2 / 1000)
    assert mc.p_value >= 1 / 1000  # the observed vector is counted: never 0
    # Monte-Carlo p approximates the exact one
    rng = np.random.default_rng(0)
    d = rng.normal(0.3, 1.0, 14)
    exact = sign_flip_test(d, exact_max=14).p_value
    approx = sign_flip_test(d, exact_max=0, n_permutations=20000, seed=2).p_value
    assert approx == pytest.approx(exact, abs=0.01)
    assert sign_flip_test(d, exact_max=0, seed=4).p_value == sign_flip_test(d, exact_max=0, seed=4).p_value


def test_sign_flip_bad_inputs():
    with pytest.raises(ValueError, match="at least one"):
        sign_flip_test([])
    with pytest.raises(ValueError, match="NaN"):
        sign_flip_test([1.0, np.nan])
    with pytest.raises(ValueError, match="alternative"):
        sign_flip_test([1.0], alternative="bigger")
    with pytest.raises(ValueError, match="exact_max"):
        sign_flip_test([1.0], exact_max=30)


def test_holm_known_values():
    p = np.array([0.01, 0.04, 0.03, 0.005])
    # sorted 0.005, 0.01, 0.03, 0.04 -> x4, x3, x2, x1 = 0.02, 0.03, 0.06, 0.04 -> cummax 0.02 0.03 0.06 0.06
    assert holm(p) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])
    out = holm([0.01, np.nan, 0.02])
    assert np.isnan(out[1]) and out[0] == pytest.approx(0.02) and out[2] == pytest.approx(0.02)
    assert holm(np.array([[0.01, 0.2], [0.03, 0.04]])).shape == (2, 2)
    with pytest.raises(ValueError):
        holm([1.5])


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0, 1), min_size=1, max_size=20))
def test_holm_is_monotone_and_bounded(p):
    adj = holm(p)
    p = np.asarray(p)
    assert np.all(adj >= p - 1e-15) and np.all(adj <= 1.0)
    assert np.all(adj <= np.minimum(1.0, p * p.size) + 1e-15)
    order = np.argsort(p, kind="stable")
    assert np.all(np.diff(adj[order]) >= -1e-15)


def test_split_halves_alternate_by_ordinal():
    a, b = split_halves([4, 1, 3, 2, 5], 2)
    assert list(a) == [1, 2] and list(b) == [3, 0]  # ordinals 1,3 vs 2,4
    with pytest.raises(ValueError):
        split_halves([1, 2, 3], 2)


# ----------------------------------------------------------------------------- the paired design


class Simulated:
    """Participants touching a square: per-participant centre, per-condition shift.

    Each trial is 15 contact points around the participant's centre plus the
    condition's shift; halves are histograms on a fixed support.
    """

    def __init__(self, rng, n_participants, shifts, trials=4, spread=0.12, support=None):
        self.support = support
        self.tree = cKDTree(support)
        self.rng = rng
        self.data = {}
        for i in range(n_participants):
            centre = rng.normal(0.5, 0.1, 2)
            for c, shift in shifts.items():
                self.data[(f"p{i}", c)] = [
                    centre + np.asarray(shift) + rng.normal(0, spread, (15, 2)) for _ in range(trials)
                ]

    def mass(self, trials):
        idx = self.tree.query(np.concatenate(trials))[1]
        return np.bincount(idx, minlength=len(self.support)).astype(float)

    def halves(self, part, a, b):
        ta, tb = self.data[(part, a)], self.data[(part, b)]
        k = min(len(ta), len(tb)) // 2
        out = []
        for t in (ta, tb):
            h0, h1 = split_halves(np.arange(len(t)), k)
            out.append(np.stack([self.mass([t[i] for i in h0]), self.mass([t[i] for i in h1])]))
        return out[0], out[1]


SUPPORT = np.random.default_rng(123).random((300, 2)) * 1.6 - 0.3


def run_design(seed, shifts, n_participants=8, n_projections=32):
    rng = np.random.default_rng(seed)
    sim = Simulated(rng, n_participants, shifts, support=SUPPORT)
    sw = SharedSupportSW(SUPPORT, n_projections=n_projections, p=1, seed=seed)
    parts = [f"p{i}" for i in range(n_participants)]
    return paired_swd_tests(sw, parts, list(shifts), sim.halves, alpha=0.05, seed=seed)


def test_same_distribution_false_positive_rate_at_most_alpha():
    """Two conditions from one distribution: raw p <= 0.05 in about 5 % of
    repetitions (exact test: 8 participants, 256 sign flips)."""
    reps = 200
    rejections = 0
    ps = []
    for r in range(reps):
        res = run_design(r, {"a": (0, 0), "b": (0, 0)})
        p = float(res.table["p_value"].iloc[0])
        ps.append(p)
        rejections += p <= 0.05
    rate = rejections / reps
    # binomial(200, 0.05): mean 10, sd 3.1 -> allow up to 0.05 + 2.5 sd
    assert rate <= 0.05 + 2.5 * np.sqrt(0.05 * 0.95 / reps), rate
    # and the p-values are not degenerate (the test is not simply conservative)
    assert 0.3 < np.mean(ps) < 0.7


def test_holm_family_of_null_pairs_keeps_familywise_error():
    reps = 40
    any_rejection = 0
    for r in range(reps):
        res = run_design(1000 + r, {"a": (0, 0), "b": (0, 0), "c": (0, 0), "d": (0, 0)}, n_participants=6)
        assert len(res.table) == 6
        any_rejection += bool(res.table["significant"].any())
    assert any_rejection / reps <= 0.05 + 2.5 * np.sqrt(0.05 * 0.95 / reps)


def test_clearly_different_distributions_are_detected():
    detected = 0
    for r in range(20):
        res = run_design(500 + r, {"a": (0, 0), "b": (0.25, 0.0), "c": (0.0, 0.0)})
        t = res.table.set_index(["cond_a", "cond_b"])
        detected += bool(t.loc[("a", "b"), "significant"]) and bool(t.loc[("b", "c"), "significant"])
        assert t.loc[("a", "b"), "mean_diff_swd_mm"] > 0
        assert res.matrix("p_holm").loc["a", "b"] == t.loc[("a", "b"), "p_holm"]
    assert detected >= 18


def test_monte_carlo_design_and_outputs(tmp_path):
    rng = np.random.default_rng(7)
    sim = Simulated(rng, 14, {"x": (0, 0), "y": (0.3, 0)}, support=SUPPORT)
    sw = SharedSupportSW(SUPPORT, n_projections=16, seed=0)
    parts = [f"p{i}" for i in range(14)] + ["nobody"]

    def halves(part, a, b):
        return None if part == "nobody" else sim.halves(part, a, b)

    res = paired_swd_tests(sw, parts, ["x", "y"], halves, exact_max=12, n_permutations=500)
    row = res.table.iloc[0]
    assert row["n_participants"] == 14 and not row["exact"] and row["n_permutations"] == 500
    assert row["p_value"] == pytest.approx(1 / 501)
    mat = res.matrix("mean_between_swd_mm")
    assert np.isfinite(mat.to_numpy()).all()  # diagonal holds the within baseline
    assert mat.loc["x", "x"] < mat.loc["x", "y"]
    paths = res.write_csv(tmp_path)
    assert all(p.is_file() for p in paths)
    with pytest.raises(ValueError, match="two conditions"):
        paired_swd_tests(sw, parts, ["x"], halves)
