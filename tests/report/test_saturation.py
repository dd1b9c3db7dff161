"""The saturation rule and its participant bootstrap, on synthetic curves."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from sphri.report.saturation import curve_stats, physical_interval, saturation, saturation_index


def saturating(n_part: int, points: np.ndarray, knee: int, noise: float, seed: int = 0) -> np.ndarray:
    """Accuracy rising linearly from 0.2 to 0.8 at index ``knee``, flat after; participant offsets + noise."""
    rng = np.random.default_rng(seed)
    curve = np.where(np.arange(len(points)) < knee, 0.2 + 0.6 * np.arange(len(points)) / knee, 0.8)
    return curve[None, :] + rng.normal(0, 0.03, (n_part, 1)) + rng.normal(0, noise, (n_part, len(points)))


def test_known_saturation_point_is_recovered():
    s = saturating(12, np.arange(10), knee=4, noise=0.005)
    sat = saturation(s, n_boot=500, seed=1)
    assert sat.index == 4
    assert sat.interval is not None and sat.interval[0] <= 4 <= sat.interval[1]
    assert sat.interval[1] - sat.interval[0] <= 1, "a sharp knee with small noise gives a tight interval"
    assert sat.stats.mean[sat.index] >= sat.stats.mean[sat.best_index] - sat.tolerance
    assert not sat.at_finest


def test_rule_is_one_standard_error_of_the_best():
    # participants' scores: best point 0.80 with sd 0.1 over 4 participants -> se 0.05
    best = np.array([0.7, 0.9, 0.7, 0.9])
    se = best.std(ddof=1) / 2
    just_in = best - 0.9 * se  # mean 0.80 - 0.9 se: within one se
    just_out = best - 1.1 * se
    assert saturation_index(np.stack([just_out, just_in, best], axis=1)) == 1
    assert saturation_index(np.stack([just_out, just_out, best], axis=1)) == 2
    # two standard errors admit the coarsest point too; a fixed tolerance of 0 admits only the best
    assert saturation_index(np.stack([just_out, just_in, best], axis=1), n_se=2.0) == 0
    assert saturation_index(np.stack([just_out, just_in, best], axis=1), tolerance=0.0) == 2
    sat = saturation(np.stack([just_out, just_in, best], axis=1), n_boot=0)
    assert sat.tolerance == pytest.approx(se)


def test_flat_curve_gives_the_coarsest_point():
    flat = np.full((6, 8), 0.6)
    assert saturation_index(flat) == 0
    rng = np.random.default_rng(3)  # participants differ (sd 0.05); the curve itself is flat up to 0.005
    noisy = 0.6 + rng.normal(0, 0.05, (10, 1)) + rng.normal(0, 0.005, (10, 8))
    assert saturation_index(noisy) == 0


def test_monotone_curve_gives_the_finest_point():
    s = np.linspace(0.2, 0.9, 7)[None, :] + np.random.default_rng(0).normal(0, 0.002, (5, 7))
    sat = saturation(s, n_boot=200)
    assert sat.index == 6 and sat.best_index == 6
    assert sat.at_finest
    assert sat.interval == (6, 6)


def test_nans_are_skipped_and_an_empty_point_is_never_chosen():
    s = saturating(8, np.arange(6), knee=2, noise=0.003)
    s[:, 0] = np.nan  # a failed job at the coarsest resolution
    s[2, 3] = np.nan  # one missing fold
    s[5, :] = np.nan  # a participant with no scores at all
    sat = saturation(s, n_boot=300)
    assert sat.index == 2
    assert sat.stats.n.tolist() == [0, 7, 7, 6, 7, 7]
    assert curve_stats(s).n.tolist() == [0, 7, 7, 6, 7, 7], "the all-NaN participant adds no count"
    assert np.isnan(sat.stats.mean[0])
    assert sat.n_participants == 7
    assert "missing" in sat.note
    assert sat.interval is not None and sat.interval[0] >= 1
    assert np.all(sat.boot_index >= 1)
    with pytest.raises(ValueError, match="no finite score"):
        saturation(np.full((3, 4), np.nan))


def test_one_participant_gives_no_interval_and_says_why():
    s = np.array([[0.3, 0.6, 0.79, 0.8]])
    sat = saturation(s, n_boot=1000)
    assert sat.interval is None and sat.boot_index is None and sat.n_boot == 0
    assert "one participant" in sat.note
    assert sat.index == 3, "without a standard error the tolerance is 0: the best point"
    assert saturation(s, tolerance=0.02).index == 2
    assert physical_interval(np.array([60.0, 30.0, 20.0, 15.0]), sat) is None


def test_bootstrap_is_reproducible_and_ends_are_sweep_points():
    s = saturating(10, np.arange(9), knee=5, noise=0.03, seed=7)
    a, b = saturation(s, n_boot=400, seed=5), saturation(s, n_boot=400, seed=5)
    assert a.interval == b.interval and np.array_equal(a.boot_index, b.boot_index)
    pitch = 240.0 / np.arange(1, 10)
    lo, hi = physical_interval(pitch, a)
    assert lo in pitch and hi in pitch and lo <= pitch[a.index] <= hi
    assert a.gap_interval is not None and a.gap_interval[0] <= a.gap <= a.gap_interval[1] + 1e-12


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="matrix"):
        saturation(np.zeros(5))
    with pytest.raises(ValueError, match="empty"):
        saturation(np.zeros((0, 3)))
    with pytest.raises(ValueError, match="tolerance"):
        saturation(np.zeros((2, 3)), tolerance=-0.1)
    with pytest.raises(ValueError, match="ci"):
        saturation(np.zeros((2, 3)), ci=1.5)
    with pytest.raises(ValueError, match="values has shape"):
        physical_interval(np.zeros(2), saturation(np.random.default_rng(0).random((3, 3)), n_boot=10))


@settings(max_examples=50, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 6), st.integers(1, 8)),
        elements=st.one_of(st.floats(0, 1), st.just(np.nan)),
    ),
    st.floats(0, 3),
)
def test_rule_properties(scores, n_se):
    if not np.isfinite(scores).any():
        return
    sat = saturation(scores, n_se=n_se, n_boot=20)
    m = sat.stats.mean
    thr = m[sat.best_index] - sat.tolerance - 1e-12
    assert np.isfinite(m[sat.index]) and m[sat.index] >= thr, "the chosen point is within tolerance"
    assert not np.any(m[: sat.index] >= thr), "no coarser point is"
    assert sat.index <= sat.best_index
    assert m[sat.best_index] == np.nanmax(m)
    if sat.interval is not None:
        assert 0 <= sat.interval[0] <= sat.interval[1] < scores.shape[1]


# -- the paired rule ---------------------------------------------------------------------------------

from sphri.report.saturation import Tolerance, paired_saturation  # noqa: E402


def test_paired_rule_ignores_a_tiny_consistent_late_gain_that_the_unpaired_rule_chases():
    """Every participant gains 0.6 points from res index 3 to 5: real (consistent), but smaller than 1 point.
    The unpaired one-SE rule (participants alike: small SE of the best mean) chases it to the finest point;
    the paired rule with a 1-point tolerance keeps the plateau's start."""
    rng = np.random.default_rng(0)
    curve = np.array([0.40, 0.60, 0.75, 0.800, 0.803, 0.806])
    s = curve[None, :] + rng.normal(0, 0.004, (18, 1)) + rng.normal(0, 0.0005, (18, 6))
    assert saturation_index(s) == 5, "unpaired one-SE rule chases the 0.6-point gain"
    sat = paired_saturation(s, "0.01", n_boot=300, seed=0)
    assert sat.index == 3 and sat.best_index == 5 and sat.rule == "paired"
    assert sat.deficit[3] == pytest.approx(0.006, abs=0.0005) and sat.deficit[5] == 0.0
    assert sat.interval == (3, 3)
    assert sat.tolerance == pytest.approx(0.01) and sat.tolerance_name == "0.01"


def test_paired_se_rule_ignores_a_gain_that_is_not_consistent_across_participants():
    """Resolution index 2 is 1 point better on average, but half the participants gain 6 points and half lose 4:
    the paired deficit of index 1 (0.01) is within one paired SE (0.052 / sqrt(16) = 0.013); the unpaired rule, whose
    tolerance is the best point's SE over (nearly identical) participants, chases it."""
    n = 16
    coarse = np.full(n, 0.80) + np.linspace(-0.001, 0.001, n)
    gain = np.where(np.arange(n) % 2 == 0, 0.06, -0.04)
    s = np.stack([coarse - 0.2, coarse, coarse + gain], axis=1)
    sat = paired_saturation(s, "se", n_boot=0)
    assert sat.best_index == 2 and sat.index == 1
    assert sat.deficit[1] == pytest.approx(0.01, abs=1e-9)
    assert sat.deficit_se[1] == pytest.approx(np.std(-gain, ddof=1) / np.sqrt(n))
    assert saturation_index(s, tolerance=0.005) == 2


def test_paired_rule_sees_a_consistent_gain_hidden_by_participant_differences():
    """Participants differ by +/- 15 points, but every one of them gains 3 points at the finest point: the
    unpaired one-SE rule (SE about 4 points) stops early, the paired rule (SE tolerance or 2 points) does not."""
    rng = np.random.default_rng(2)
    level = rng.normal(0.7, 0.15, 14)
    s = level[:, None] + np.array([0.0, 0.10, 0.12, 0.15])[None, :] + rng.normal(0, 0.002, (14, 4))
    assert saturation_index(s) <= 2
    assert paired_saturation(s, "se", n_boot=0).index == 3
    assert paired_saturation(s, "0.02", n_boot=0).index == 3
    assert paired_saturation(s, "0.05", n_boot=0).index == 2


def test_paired_bootstrap_interval_covers_the_point_and_repeats():
    s = saturating(12, np.arange(10), knee=4, noise=0.01, seed=4)
    a = paired_saturation(s, "0.02", n_boot=400, seed=3)
    b = paired_saturation(s, "0.02", n_boot=400, seed=3)
    assert a.interval == b.interval and a.interval[0] <= a.index <= a.interval[1]
    assert a.boot_index.shape == (400,)
    assert a.gap_interval is not None


def test_paired_rule_edge_cases():
    one = paired_saturation(np.array([[0.5, 0.7, 0.71]]), "0.02", n_boot=100)
    assert one.index == 1 and one.interval is None and "one participant" in one.note
    with_nan = np.array([[0.5, 0.8, 0.81], [0.5, np.nan, 0.79], [0.52, 0.78, 0.8]])
    sat = paired_saturation(with_nan, "0.02", n_boot=50)
    assert sat.index == 1 and "missing" in sat.note
    flat = paired_saturation(np.full((5, 4), 0.6), "se", n_boot=20)
    assert flat.index == 0 and flat.interval == (0, 0)
    with pytest.raises(ValueError, match="tolerance"):
        paired_saturation(np.zeros((3, 3)), "lots")
    with pytest.raises(ValueError, match="tolerance"):
        Tolerance.parse("1.5")
    assert Tolerance.parse("2se").n_se == 2.0 and Tolerance.parse("0.010").name == "0.01"
    assert Tolerance.parse("se").describe() == "one paired standard error"
    assert Tolerance.parse("0.01").describe() == "1 point of accuracy (0.01)"
