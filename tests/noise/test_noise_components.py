"""Noise: determinism per (seed, trial, frame), rates, dead taxels, crosstalk, range checks."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sphri.config import ConfigError
from sphri.noise.components import (
    CrosstalkNoise,
    DeadTaxelsNoise,
    GaussianNoise,
    NoNoise,
    SaltPepperNoise,
    dead_taxel_index,
)
from sphri.types import Frames, SkinFrames, TaxelGeometry

#: Hypothesis examples per property (SPHRI_DEEP_TESTS=1 for a deep run).
EXAMPLES = 500 if os.environ.get("SPHRI_DEEP_TESTS") else 50

ALL = [SaltPepperNoise(), SaltPepperNoise(mode="flip"), GaussianNoise(), DeadTaxelsNoise(), CrosstalkNoise(), NoNoise()]


def grid_frames(m=400, h=6, w=5, rate=0.2, seed=0, wrap=True):
    rng = np.random.default_rng(seed)
    v = (rng.random((m, h * w)) < rate).astype(np.uint8)
    uv = np.column_stack([np.repeat((np.arange(h) + 0.5) / h, w), np.tile((np.arange(w) + 0.5) / w, h)])
    geom = TaxelGeometry((h, w), uv, np.column_stack([uv, np.zeros(h * w)]), wrap, 0.24, 0.25)
    fi = np.arange(1000, 1000 + m, dtype=np.int64)
    tk = fi // 50
    return SkinFrames(values=v, grid_shape=(h, w), geometry=geom), fi, tk


@pytest.mark.parametrize("noise", ALL, ids=lambda n: f"{type(n).__name__}-{getattr(n, 'mode', '')}")
def test_deterministic_and_independent_of_other_frames(noise):
    f, fi, tk = grid_frames()
    before = f.values.copy()
    a = noise.apply(f, fi, tk, 7)
    b = noise.apply(f, fi, tk, 7)
    np.testing.assert_array_equal(a.values, b.values)
    np.testing.assert_array_equal(f.values, before)  # input untouched
    sub = np.array([5, 300, 17, 17])
    part = noise.apply(SkinFrames(f.values[sub], f.grid_shape, f.geometry), fi[sub], tk[sub], 7)
    np.testing.assert_array_equal(part.values, a.values[sub])
    assert np.isfinite(a.values.astype(float)).all()
    assert a.values.min() >= 0 and a.values.max() <= 1
    assert a.grid_shape == f.grid_shape and a.geometry is f.geometry


@pytest.mark.parametrize("noise", [SaltPepperNoise(), GaussianNoise()], ids=["salt_pepper", "gaussian"])
def test_seed_and_trial_change_the_noise(noise):
    f, fi, tk = grid_frames()
    a = noise.apply(f, fi, tk, 1).values
    assert not np.array_equal(a, noise.apply(f, fi, tk, 2).values)
    assert not np.array_equal(a, noise.apply(f, fi, tk + 1, 1).values)
    assert not np.array_equal(a, noise.apply(f, fi + 1, tk, 1).values)


def test_salt_pepper_rates():
    v = np.zeros((2000, 100), dtype=np.uint8)
    v[:, 50:] = 1
    f = Frames(v, None)
    fi, tk = np.arange(2000), np.arange(2000) // 50
    rep = SaltPepperNoise(p=0.02).apply(f, fi, tk, 0).values
    changed = (rep != v).mean()
    assert changed == pytest.approx(0.01, abs=0.0015)  # half of the p corruptions hit the value it had
    assert rep.dtype == np.uint8
    flip = SaltPepperNoise(p=0.02, mode="flip").apply(f, fi, tk, 0).values
    assert (flip != v).mean() == pytest.approx(0.02, abs=0.002)
    np.testing.assert_array_equal(SaltPepperNoise(p=0.0).apply(f, fi, tk, 0).values, v)
    allsalt = SaltPepperNoise(p=1.0, salt_vs_pepper=1.0).apply(f, fi, tk, 0).values
    assert allsalt.all()
    half = SaltPepperNoise(p=1.0).apply(f, fi, tk, 0).values
    assert half.mean() == pytest.approx(0.5, abs=0.01)
    fl = Frames(v.astype(np.float32) * 0.5, None)
    assert SaltPepperNoise().apply(fl, fi, tk, 0).values.dtype == np.float32


def test_salt_pepper_at_zero_skips_the_kernel_with_the_kernels_answer():
    """p = 0 returns a copy without running the kernel; the kernel itself gives the same readings."""
    from sphri.noise.components import _salt_pepper

    rng = np.random.default_rng(3)
    for v in ((rng.random((300, 40)) < 0.3).astype(np.uint8), rng.random((300, 40)).astype(np.float32)):
        fi, tk = np.arange(300, dtype=np.int64), np.arange(300, dtype=np.int64) // 50
        for mode in ("replace", "flip"):
            got = SaltPepperNoise(p=0.0, mode=mode).apply(Frames(v, None), fi, tk, 7).values
            ref = np.empty_like(v)
            _salt_pepper(v, ref, fi, tk, np.uint64(7), 0.0, 0.5, mode == "flip")
            np.testing.assert_array_equal(got, ref)
            assert got.dtype == v.dtype and got is not v and not np.shares_memory(got, v)


def test_gaussian_statistics():
    v = np.full((1000, 200), 0.5, dtype=np.float32)
    out = GaussianNoise(sigma=0.1).apply(Frames(v, None), np.arange(1000), np.zeros(1000, np.int64), 3).values
    assert out.dtype == np.float32
    assert out.mean() == pytest.approx(0.5, abs=0.002)
    assert out.std() == pytest.approx(0.1, rel=0.02)
    clipped = GaussianNoise(sigma=1.0).apply(Frames(v, None), np.arange(1000), np.zeros(1000, np.int64), 3).values
    assert clipped.min() == 0.0 and clipped.max() == 1.0


def test_dead_taxels_are_one_sensor():
    f, fi, tk = grid_frames(rate=1.0)  # all on: dead ones show as zeros
    out = DeadTaxelsNoise(fraction=0.2).apply(f, fi, tk, 5).values
    dead = np.flatnonzero(out[0] == 0)
    assert len(dead) == round(0.2 * 30)
    assert (out[:, dead] == 0).all() and (np.delete(out, dead, axis=1) == 1).all()  # same in every trial/frame
    np.testing.assert_array_equal(dead, dead_taxel_index(30, 0.2, 5))
    assert not np.array_equal(dead_taxel_index(30, 0.2, 5), dead_taxel_index(30, 0.2, 6))
    stuck = DeadTaxelsNoise(fraction=0.2, value=1.0).apply(Frames(np.zeros_like(f.values), f.grid_shape), fi, tk, 5)
    np.testing.assert_array_equal(np.flatnonzero(stuck.values[0]), dead)


def test_crosstalk_wraps_on_grids_and_uses_the_radius_rule_elsewhere():
    f, fi, tk = grid_frames(m=1, rate=0.0)
    f.values[0, 2 * 5 + 0] = 1  # row 2, column 0
    out = CrosstalkNoise(alpha=0.25).apply(f, fi, tk, 0).as_grid()[0]
    assert out[2, 0] == 1.0
    assert out[1, 0] == out[3, 0] == out[2, 1] == out[2, 4] == pytest.approx(0.25)  # column 4 across the seam
    assert out.sum() == pytest.approx(2.0)
    nowrap, _, _ = grid_frames(m=1, rate=0.0, wrap=False)
    nowrap.values[0, 10] = 1
    assert CrosstalkNoise(alpha=0.25).apply(nowrap, fi, tk, 0).as_grid()[0][2, 4] == 0.0
    # non-grid: taxels within 1.5 x the median nearest-neighbour spacing (here 0.01 m)
    pos = np.array([[0, 0, 0], [0.01, 0, 0], [0.02, 0, 0], [0.1, 0, 0], [0.11, 0, 0]], float)
    geom = TaxelGeometry(None, None, pos, False, 0.0, 0.0)
    v = np.array([[1, 0, 0, 0, 0]], dtype=np.uint8)
    ng = CrosstalkNoise(alpha=0.5).apply(SkinFrames(v, None, geom), np.array([0]), np.array([0]), 0).values
    np.testing.assert_allclose(ng[0], [1.0, 0.5, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="needs taxel positions"):
        CrosstalkNoise().apply(Frames(v, None), np.array([0]), np.array([0]), 0)


def test_input_checks_and_ranges():
    f, fi, tk = grid_frames(m=3)
    with pytest.raises(ValueError, match="trial_key must be"):
        SaltPepperNoise().apply(f, fi, tk[:2], 0)
    with pytest.raises(ValueError, match="seed"):
        SaltPepperNoise().apply(f, fi, tk, -1)


@pytest.mark.parametrize(
    "cls, bad",
    [
        (SaltPepperNoise, {"p": 1.5}),
        (SaltPepperNoise, {"mode": "swap"}),
        (GaussianNoise, {"sigma": -0.1}),
        (DeadTaxelsNoise, {"fraction": 2.0}),
        (CrosstalkNoise, {"alpha": -1.0}),
    ],
)
def test_out_of_range_settings_name_the_key(cls, bad):
    (key,) = bad
    with pytest.raises(ConfigError, match=f"noise.{key}"):
        cls(**bad)


@settings(max_examples=EXAMPLES, deadline=None)
@given(
    seed=st.integers(0, 2**31), trial=st.integers(-(2**62), 2**62), frame=st.integers(0, 2**40), p=st.floats(0.0, 1.0)
)
def test_noise_is_a_function_of_its_key(seed, trial, frame, p):
    v = np.zeros((2, 64), dtype=np.uint8)
    fi = np.array([frame, frame], dtype=np.int64)
    tk = np.array([trial, trial], dtype=np.int64)
    out = SaltPepperNoise(p=p, mode="flip").apply(Frames(v, None), fi, tk, seed).values
    np.testing.assert_array_equal(out[0], out[1])
    if p == 0.0:
        assert not out.any()
    if p == 1.0:
        assert out.all()
