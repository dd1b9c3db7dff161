"""noise=threshold: seeded determinism, false-on/false-off rates against their closed forms, the physics
(less covered area -> more false-offs), crosstalk to neighbours and the AR(1) drift's correlation."""

from __future__ import annotations

import numpy as np
import pytest

from sphri.noise.components import ThresholdNoise, threshold_false_off_rate, threshold_false_on_rate
from sphri.types import SkinFrames, TaxelGeometry


def frames(values, area_mm2, h=None, w=None):
    m, n = values.shape
    h, w = (h, w) if h else (1, n)
    uv = np.column_stack([np.repeat((np.arange(h) + 0.5) / h, w), np.tile((np.arange(w) + 0.5) / w, h)])
    geom = TaxelGeometry(
        (h, w), uv, np.column_stack([uv, np.zeros(n)]), False, 0.1, 0.1, area_m2=np.full(n, area_mm2 * 1e-6)
    )
    return SkinFrames(values=values.astype(np.float32), grid_shape=(h, w), geometry=geom)


def keys(m, frames_per_trial=50):
    fi = np.arange(m, dtype=np.int64) % frames_per_trial
    return fi, np.arange(m, dtype=np.int64) // frames_per_trial


def test_same_seed_same_readings_other_seed_other_readings():
    v = np.full((400, 30), 0.3)
    fi, tk = keys(400)
    noise = ThresholdNoise(sigma_mm2=3.0, threshold_mm2=10.0, drift_sigma_mm2=2.0, drift_tau_ms=200.0)
    a = noise.apply(frames(v, 30.0), fi, tk, 7, frame_rate_hz=60.0).values
    b = noise.apply(frames(v, 30.0), fi, tk, 7, frame_rate_hz=60.0).values
    c = noise.apply(frames(v, 30.0), fi, tk, 8, frame_rate_hz=60.0).values
    assert a.dtype == np.float32 and set(np.unique(a)) <= {0.0, 1.0}
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    # a frame's reading does not depend on which other frames are passed (the drift runs from frame 0)
    part = noise.apply(frames(v[60:75], 30.0), fi[60:75], tk[60:75], 7, frame_rate_hz=60.0).values
    assert np.array_equal(part, a[60:75])


@pytest.mark.parametrize(("sigma", "drift", "thr"), [(4.0, 0.0, 10.0), (2.0, 2.0, 5.0), (0.0, 5.0, 8.0)])
def test_false_on_rate_of_an_untouched_skin_is_the_normal_tail(sigma, drift, thr):
    m, n = 4000, 100
    fi, tk = keys(m)
    noise = ThresholdNoise(sigma_mm2=sigma, threshold_mm2=thr, drift_sigma_mm2=drift, drift_tau_ms=100.0)
    out = noise.apply(frames(np.zeros((m, n)), 25.0), fi, tk, 1, frame_rate_hz=90.0).values
    p = threshold_false_on_rate(sigma, thr, drift)
    assert p == pytest.approx(0.5 * __import__("math").erfc(thr / np.hypot(sigma, drift) / np.sqrt(2)))
    # drifting noise is correlated within a trial: the count's spread is wider than binomial; bound it by trials
    trials = out.reshape(m // 50, 50 * n).mean(axis=1)
    se = trials.std(ddof=1) / np.sqrt(len(trials))
    assert abs(out.mean() - p) < 4 * se + 1e-4, (out.mean(), p)


def test_false_off_rate_rises_as_covered_area_falls():
    # the same contact fraction on smaller taxels is less covered area: more false-offs at the same noise
    m, n, sigma, thr = 3000, 50, 4.0, 10.0
    fi, tk = keys(m)
    noise = ThresholdNoise(sigma_mm2=sigma, threshold_mm2=thr)
    rates = []
    for area in (12.0, 16.0, 25.0):
        out = noise.apply(frames(np.ones((m, n)), area), fi, tk, 3).values
        off = 1.0 - out.mean()
        expect = threshold_false_off_rate(area, sigma, thr)
        assert off == pytest.approx(expect, abs=4 * np.sqrt(expect * (1 - expect) / out.size) + 1e-4)
        rates.append(off)
    assert rates[0] > rates[1] > rates[2]
    assert threshold_false_off_rate(12.0, sigma, thr) == pytest.approx(
        0.5 * (1 + __import__("math").erf(-0.5 / 2**0.5))
    )


def test_without_noise_the_threshold_is_exact_and_crosstalk_reaches_only_neighbours():
    v = np.zeros((1, 25))
    v[0, 12] = 1.0  # centre of a 5 x 5 grid, fully covered 100 mm^2 taxel
    fi, tk = keys(1)
    clean = ThresholdNoise(sigma_mm2=0.0, threshold_mm2=10.0).apply(frames(v, 100.0, 5, 5), fi, tk, 0).values
    assert np.flatnonzero(clean[0]).tolist() == [12]
    leak = ThresholdNoise(sigma_mm2=0.0, threshold_mm2=10.0, crosstalk=0.2).apply(frames(v, 100.0, 5, 5), fi, tk, 0)
    assert np.flatnonzero(leak.values[0]).tolist() == [7, 11, 12, 13, 17]  # 20 mm^2 leaks onto the 4 edge neighbours
    weak = ThresholdNoise(sigma_mm2=0.0, threshold_mm2=10.0, crosstalk=0.05).apply(frames(v, 100.0, 5, 5), fi, tk, 0)
    assert np.flatnonzero(weak.values[0]).tolist() == [12]
    half = np.full((1, 25), 0.09)  # 9 mm^2 of 100: below the threshold
    assert (
        not ThresholdNoise(sigma_mm2=0.0, threshold_mm2=10.0).apply(frames(half, 100.0, 5, 5), fi, tk, 0).values.any()
    )


def test_drift_is_an_ar1_with_the_stated_time_constant():
    # threshold at 0 on an untouched skin: on <=> drift > 0; the on/on agreement at lag k follows the
    # bivariate normal orthant probability 1/4 + arcsin(rho^k) / (2 pi)
    m, n, fps, tau = 200 * 50, 200, 50.0, 100.0
    fi, tk = keys(m)
    noise = ThresholdNoise(sigma_mm2=0.0, threshold_mm2=0.0, drift_sigma_mm2=3.0, drift_tau_ms=tau)
    out = noise.apply(frames(np.zeros((m, n)), 20.0), fi, tk, 5, frame_rate_hz=fps).values.reshape(200, 50, n)
    rho = np.exp(-1000.0 / (fps * tau))
    for lag in (1, 5):
        both = (out[:, :-lag] * out[:, lag:]).mean()
        assert both == pytest.approx(0.25 + np.arcsin(rho**lag) / (2 * np.pi), abs=0.01)
    with pytest.raises(ValueError, match="frame rate"):
        noise.apply(frames(np.zeros((2, 3)), 20.0), fi[:2], tk[:2], 0)


def test_readings_outside_coverage_fractions_or_without_areas_are_refused():
    fi, tk = keys(2)
    with pytest.raises(ValueError, match="coverage fractions"):
        ThresholdNoise().apply(frames(np.full((2, 3), 2.0), 10.0), fi, tk, 0)
    bare = frames(np.zeros((2, 3)), 10.0)
    bare = SkinFrames(values=bare.values, grid_shape=bare.grid_shape, geometry=None)
    with pytest.raises(ValueError, match="area"):
        ThresholdNoise().apply(bare, fi, tk, 0)


def test_in_the_chain_the_drift_runs_at_the_windows_frame_rate():
    import dataclasses

    from sphri.noise.components import apply_to_windows
    from sphri.types import WindowedFrames

    t, length, n = 40, 50, 12
    f = frames(np.zeros((1, n)), 20.0)
    win = WindowedFrames(
        x=np.zeros((t, length, n), dtype=np.float32),
        y=np.arange(t) % 8,
        groups=np.array(["a", "b"] * (t // 2)),
        geometry=f.geometry,
        trial_row=np.arange(t, dtype=np.int64),
        n_dropped=0,
    )
    noise = ThresholdNoise(sigma_mm2=0.0, threshold_mm2=0.0, drift_sigma_mm2=3.0, drift_tau_ms=100.0)
    slow = apply_to_windows(noise, dataclasses.replace(win, frame_rate_hz=200.0), np.arange(t), 0).x
    fast = apply_to_windows(noise, dataclasses.replace(win, frame_rate_hz=10.0), np.arange(t), 0).x
    # frames 5 ms apart stay on or off together far more often than frames 100 ms apart: P(same sign) of two
    # normals correlated rho is 1/2 + arcsin(rho) / pi
    agree = [float((x[:, 1:] == x[:, :-1]).mean()) for x in (slow, fast)]
    rho = [np.exp(-5.0 / 100.0), np.exp(-100.0 / 100.0)]
    for a, r in zip(agree, rho):
        assert a == pytest.approx(0.5 + np.arcsin(r) / np.pi, abs=0.03)
    with pytest.raises(ValueError, match="frame rate"):
        apply_to_windows(noise, win, np.arange(t), 0)  # no frame rate known
