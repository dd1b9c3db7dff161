"""Sliced Wasserstein: exact 1-D formulas, known translations, shared-support fast path."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import wasserstein_distance

from sphri.analysis.swd import (
    SharedSupportSW,
    projection_directions,
    sliced_wasserstein,
    wasserstein_1d,
)

finite = st.floats(-100, 100, allow_nan=False, allow_infinity=False)


def mean_abs_cosine(dim: int) -> float:
    """E|<theta, e>| for theta uniform on S^(dim-1) and a fixed unit vector e."""
    return math.gamma(dim / 2.0) / (math.sqrt(math.pi) * math.gamma((dim + 1) / 2.0))


@settings(max_examples=50, deadline=None)
@given(
    u=st.lists(finite, min_size=1, max_size=30),
    v=st.lists(finite, min_size=1, max_size=30),
    data=st.data(),
)
def test_w1_matches_cdf_formula(u, v, data):
    """W1 = integral |F_u - F_v| (scipy's exact weighted formula)."""
    wu = data.draw(st.lists(st.floats(0.01, 10), min_size=len(u), max_size=len(u)))
    wv = data.draw(st.lists(st.floats(0.01, 10), min_size=len(v), max_size=len(v)))
    ours = wasserstein_1d(u, v, wu, wv, p=1)
    ref = wasserstein_distance(u, v, wu, wv)
    assert ours == pytest.approx(ref, rel=1e-9, abs=1e-9)


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 40), st.integers(0, 2**31 - 1), st.sampled_from([1.0, 2.0, 3.0]))
def test_wp_equal_sizes_is_sorted_matching(n, seed, p):
    """Uniform samples of equal size: W_p^p = mean |sort(u) - sort(v)|^p."""
    rng = np.random.default_rng(seed)
    u, v = rng.normal(size=n), rng.normal(2.0, 3.0, size=n)
    ref = np.mean(np.abs(np.sort(u) - np.sort(v)) ** p) ** (1 / p)
    assert wasserstein_1d(u, v, p=p) == pytest.approx(ref, rel=1e-10)


def test_w2_of_unequal_sizes_uses_quantiles():
    # u uniform on {0, 1}; v = {0, 0.5, 1} uniform: quantile functions differ on
    # (1/3, 1/2) (0 vs 0.5) and (1/2, 2/3) (1 vs 0.5): W2^2 = 2 * (1/6) * 0.25
    assert wasserstein_1d([0, 1], [0, 0.5, 1], p=2) == pytest.approx(np.sqrt(2 / 6 * 0.25))
    assert wasserstein_1d([0, 1], [0, 0.5, 1], p=1) == pytest.approx(2 / 6 * 0.5)


def test_zero_weights_are_ignored_and_order_does_not_matter():
    a = wasserstein_1d([3, 0, 1, 7], [2, 5], [1, 1, 1, 0], [1, 2], p=2)
    b = wasserstein_1d([0, 1, 3], [5, 2], None, [2, 1], p=2)
    assert a == pytest.approx(b)


@pytest.mark.parametrize("dim", [1, 2, 3, 5])
def test_mean_abs_cosine_matches_monte_carlo(dim):
    theta = projection_directions(200_000, dim, seed=1)
    assert mean_abs_cosine(dim) == pytest.approx(np.abs(theta[:, 0]).mean(), abs=3e-3)
    assert mean_abs_cosine(3) == pytest.approx(0.5)
    assert mean_abs_cosine(2) == pytest.approx(2 / np.pi)


@pytest.mark.parametrize("dim", [2, 3])
def test_translation_by_d_gives_d_times_mean_abs_cosine(dim):
    rng = np.random.default_rng(0)
    x = rng.normal(scale=0.02, size=(400, dim))
    w = rng.random(400)
    e = rng.normal(size=dim)
    e /= np.linalg.norm(e)
    d = 0.05
    sw1 = sliced_wasserstein(x, x + d * e, w, w, n_projections=4000, p=1, seed=3)
    assert sw1 == pytest.approx(d * mean_abs_cosine(dim), rel=0.03)
    sw2 = sliced_wasserstein(x, x + d * e, w, w, n_projections=4000, p=2, seed=3)
    assert sw2 == pytest.approx(d / np.sqrt(dim), rel=0.03)


def test_point_masses_and_identity():
    x, y = np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 0.3, 0.4]])
    theta = projection_directions(64, 3, seed=0)
    exact = np.mean(np.abs(theta @ (y - x)[0]))
    assert sliced_wasserstein(x, y, directions=theta) == pytest.approx(exact, rel=1e-12)
    pts = np.random.default_rng(1).normal(size=(50, 3))
    assert sliced_wasserstein(pts, pts[::-1]) == pytest.approx(0.0, abs=1e-12)


def test_symmetric_and_seeded():
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(30, 3)), rng.normal(1, 1, size=(20, 3))
    assert sliced_wasserstein(a, b, seed=5) == pytest.approx(sliced_wasserstein(b, a, seed=5))
    assert sliced_wasserstein(a, b, seed=5) == sliced_wasserstein(a, b, seed=5)
    assert sliced_wasserstein(a, b, seed=5) != sliced_wasserstein(a, b, seed=6)


def test_triangle_inequality_on_shared_support():
    rng = np.random.default_rng(4)
    sw = SharedSupportSW(rng.normal(size=(200, 3)), n_projections=64, p=2, seed=0)
    w = rng.random((3, 200)) ** 4
    ab, bc, ac = sw.distances(w[[0, 1, 0]], w[[1, 2, 2]])
    assert ac <= ab + bc + 1e-12


def test_shared_support_matches_general():
    rng = np.random.default_rng(3)
    support = rng.normal(size=(300, 3))
    wa, wb = rng.random(300) ** 3, rng.random(300) ** 3
    wa[:100] = 0  # sparse masses are fine
    for p in (1.0, 2.0):
        sw = SharedSupportSW(support, n_projections=50, p=p, seed=9)
        general = sliced_wasserstein(support, support, wa, wb, p=p, directions=sw.directions)
        assert sw.distance(wa, wb) == pytest.approx(general, rel=1e-9)
        assert sw.distance(wa, wa) == pytest.approx(0.0, abs=1e-12)
    # batched rows, scale of the masses does not matter
    d = sw.distances(np.stack([wa, 5 * wa]), np.stack([wb, wb]))
    assert d[0] == pytest.approx(d[1])


@pytest.mark.parametrize(
    "call,match",
    [
        (lambda: wasserstein_1d([0, 1], [1], p=0.5), "p=0.5"),
        (lambda: wasserstein_1d([0, 1], [1], u_weights=[0, 0]), "sums to zero"),
        (lambda: wasserstein_1d([0, np.nan], [1]), "NaN"),
        (lambda: wasserstein_1d([0, 1], [1], u_weights=[1, -1]), ">= 0"),
        (lambda: sliced_wasserstein(np.zeros((3, 2)), np.zeros((3, 3))), "same dimension"),
        (lambda: sliced_wasserstein(np.zeros((3, 2)), np.zeros((3, 2)), n_projections=0), "n_projections"),
        (lambda: SharedSupportSW(np.zeros((4, 3))).distances(np.zeros((1, 4)), np.ones((1, 4))), "no mass"),
        (lambda: SharedSupportSW(np.zeros((4, 3))).distances(np.ones((1, 5)), np.ones((1, 5))), r"\(Q, 4\)"),
    ],
)
def test_bad_inputs_raise(call, match):
    with pytest.raises(ValueError, match=match):
        call()
