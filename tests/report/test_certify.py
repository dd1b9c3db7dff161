"""The requirement rule (sphri.report.saturation.certified_saturation) on synthetic curves with a known answer.

The promise: the reported pitch and every finer one are truly within the tolerance used of the true best. On each
shape of :mod:`sphri.report.simulate` (18 participants, 3 seeds, rerun noise 0.026, a participant x resolution
effect of 0.02) it may be broken in at most 5 % of 200 seeded draws.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from sphri.report.saturation import (
    Tolerance,
    certified_saturation,
    certify_index,
    curve_stats,
    physical_interval,
    rerun_noise,
)
from sphri.report.simulate import GRID, SHAPES, Noise, draw, true_gap, violation_rate

DRAWS = 200


def new_rule(scores: np.ndarray) -> tuple[int, float]:
    return certify_index(scores, 0.01)


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_promise_kept_on_each_shape(shape):
    mu = SHAPES[shape](GRID)
    rate, t_med = violation_rate(new_rule, mu, Noise(), DRAWS, seed=11)
    print(f"{shape}: promise broken in {100 * rate:.1f} % of {DRAWS} draws; median tolerance used {t_med:.4f}")
    assert rate <= 0.05
    assert 0.01 < t_med < 0.06, "with 18 participants 1 point cannot be certified, a few points can"


def one_se_margin_rule(scores: np.ndarray) -> tuple[int, float]:
    """A rule whose burden of proof is on a point being bad: a point fails only when its deficit to the best mean
    exceeds 1 point by more than 2.71 paired standard errors (the promise it states: within 1 point)."""
    x = scores.mean(axis=0)
    best = int(np.argmax(x.mean(axis=0)))
    d = x[:, [best]] - x
    dm, dse = d.mean(axis=0), d.std(axis=0, ddof=1) / np.sqrt(d.shape[0])
    out = np.flatnonzero(dm > 0.01 + 2.71 * dse)
    return (int(out.max()) + 1 if out.size else 0), 0.01


def test_promise_check_catches_a_rule_that_puts_the_burden_on_badness():
    """The promise check can fail: the burden-of-badness rule breaks it on the noisy saturating curve."""
    rate, _ = violation_rate(one_se_margin_rule, SHAPES["saturating"](GRID), Noise(), DRAWS, seed=11)
    print(f"burden-of-badness rule: promise broken in {100 * rate:.1f} % of draws")
    assert rate > 0.5


def test_raised_tolerance_and_certificate():
    rng = np.random.default_rng(3)
    s = draw(SHAPES["flat"](GRID), Noise(), rng)
    sat, cert = certified_saturation(s, "0.01", n_boot=0)
    assert cert.raised and cert.tolerance_used == pytest.approx(cert.certifiable) == pytest.approx(sat.tolerance)
    assert cert.certifiable == pytest.approx(sat.bound[-1]), "T* is the finest point's bound"
    assert "cannot be certified" in sat.note and "smallest certifiable" in cert.describe()
    assert certified_saturation(s, float(sat.bound.max()), n_boot=0)[0].index == 0, "all points within the largest"
    loose, cert_l = certified_saturation(s, "0.2", n_boot=0)
    assert not cert_l.raised and loose.tolerance == 0.2 and not cert_l.outside.any()
    # the tolerance used is never below T*
    for t in (0.0, 0.005, cert.certifiable * 0.99):
        assert certified_saturation(s, t, n_boot=0)[1].tolerance_used >= cert.certifiable


def test_more_participants_certify_a_smaller_tolerance():
    mu = SHAPES["flat"](GRID)
    t = {p: violation_rate(new_rule, mu, Noise(participants=p), 30, seed=2)[1] for p in (6, 18, 54)}
    assert t[6] > t[18] > t[54]


def test_a_curve_still_rising_at_the_fine_end_needs_the_finest_point():
    mu = 0.4 + 0.4 * GRID / GRID[-1]  # 40 points of rise, 1.5 points between the two finest
    sat, cert = certified_saturation(draw(mu, Noise(), np.random.default_rng(0)), "0.01", n_boot=0)
    assert sat.index >= len(GRID) - 2 and true_gap(mu, sat.index) <= cert.tolerance_used


def test_bootstrap_interval_reproducible_and_contains_the_point():
    s = draw(SHAPES["saturating"](GRID), Noise(), np.random.default_rng(5))
    a, _ = certified_saturation(s, "0.03", n_boot=200, seed=4)
    b, _ = certified_saturation(s, "0.03", n_boot=200, seed=4)
    assert a.interval == b.interval and a.interval is not None
    assert a.interval[0] <= a.index <= a.interval[1]
    assert a.gap_interval is not None and a.gap_interval[0] <= a.gap <= a.gap_interval[1] + 1e-12
    pitch = 240.0 / GRID
    lo, hi = physical_interval(pitch, a)
    assert lo <= pitch[a.index] <= hi


def test_missing_scores_and_degenerate_inputs():
    s = draw(SHAPES["saturating"](GRID), Noise(), np.random.default_rng(6))
    s[0, 2, 4] = np.nan
    s[:, 5, :] = np.nan  # a participant with no score is dropped
    sat, cert = certified_saturation(s, "0.02", n_boot=50)
    assert sat.n_participants == 17 and "missing" in sat.note and cert.n_participants == 17
    one, cert1 = certified_saturation(np.array([[0.5, 0.7, 0.71]]), "0.02", n_boot=10)
    assert one.index == 2 and one.interval is None and not np.isfinite(cert1.certifiable)
    with pytest.raises(ValueError, match="no finite score"):
        certified_saturation(np.full((3, 4), np.nan))
    with pytest.raises(ValueError, match="shape"):
        certified_saturation(np.zeros(5))
    with pytest.raises(ValueError, match="standard errors"):
        Tolerance.parse("se")
    with pytest.raises(ValueError, match=r"\[0, 1\)"):
        Tolerance.parse("1.5")
    assert (
        Tolerance.parse("0.010").name == "0.01" and Tolerance.parse("0.01").describe() == "1 point of accuracy (0.01)"
    )
    assert curve_stats(np.array([[0.1, np.nan], [0.3, 0.5]])).n.tolist() == [2, 1]


def test_rerun_noise_measured_between_seeds():
    s = draw(SHAPES["flat"](GRID), Noise(seed_sd=0.03), np.random.default_rng(7))
    noise = rerun_noise(s)
    assert noise.source == "seeds" and noise.per_participant == pytest.approx(0.03, rel=0.15)
    assert rerun_noise(s[0]).source == "neighbours"


@settings(max_examples=40, deadline=None)
@given(
    arrays(
        np.float64,
        st.tuples(st.integers(1, 3), st.integers(1, 6), st.integers(1, 7)),
        elements=st.one_of(st.floats(0, 1), st.just(np.nan)),
    ),
    st.floats(0, 0.5),
)
def test_rule_properties(scores, tol):
    if not np.isfinite(scores).any():
        return
    sat, cert = certified_saturation(scores, tol, n_boot=10)
    m = sat.stats.mean
    assert np.isfinite(m[sat.index])
    assert cert.tolerance_used >= tol and not cert.tolerance_used < cert.certifiable
    if np.isfinite(cert.tolerance_used):
        fin = np.isfinite(m)
        assert np.all(sat.bound[sat.index :][fin[sat.index :]] <= cert.tolerance_used + 1e-9), "finer points certified"
        if sat.index > 0 and fin[: sat.index].any():
            prev = np.flatnonzero(fin[: sat.index])[-1]
            assert sat.bound[prev] > cert.tolerance_used, "the coarser neighbour is not"
    if sat.interval is not None:
        assert 0 <= sat.interval[0] <= sat.interval[1] < scores.shape[-1]
