"""Noise on the windows as the model sees them: padded slots included, seeded per (seed, trial, slot)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sphri import pipeline
from sphri.cache import StageCache
from sphri.config import compose
from sphri.noise.components import (
    CrosstalkNoise,
    DeadTaxelsNoise,
    GaussianNoise,
    NoNoise,
    SaltPepperNoise,
    apply_to_windows,
)
from sphri.types import SkinFrames, TaxelGeometry, WindowedFrames

#: Every noise kind, with settings under which it can change an all-zero frame when it is able to.
KINDS = {
    "salt_pepper": SaltPepperNoise(p=0.2),
    "salt_pepper_flip": SaltPepperNoise(p=0.2, mode="flip"),
    "gaussian": GaussianNoise(sigma=0.2),
    "dead_taxels_stuck_on": DeadTaxelsNoise(fraction=0.2, value=1.0),
    "dead_taxels_silent": DeadTaxelsNoise(fraction=0.2, value=0.0),
    "crosstalk": CrosstalkNoise(alpha=0.3),
    "none": NoNoise(),
}
#: Kinds that change a frame that reads nothing (crosstalk and silent dead taxels cannot: 0 stays 0).
CHANGE_ZEROS = {"salt_pepper", "salt_pepper_flip", "gaussian", "dead_taxels_stuck_on"}


def windows_with_padding(t=6, length=10, h=4, w=5, seed=0) -> tuple[WindowedFrames, np.ndarray]:
    """Windows whose trial i holds 3 + i real frames (random readings), the rest zero padding."""
    rng = np.random.default_rng(seed)
    n = h * w
    x = np.zeros((t, length, n), dtype=np.float32)
    real = np.zeros((t, length), dtype=bool)
    for i in range(t):
        k = min(length, 3 + i)
        x[i, :k] = rng.random((k, n)) < 0.3
        real[i, :k] = True
    uv = np.column_stack([np.repeat((np.arange(h) + 0.5) / h, w), np.tile((np.arange(w) + 0.5) / w, h)])
    geom = TaxelGeometry((h, w), uv, np.column_stack([uv, np.zeros(n)]), True, 0.24, 0.25)
    win = WindowedFrames(
        x=x,
        y=np.arange(t) % 8,
        groups=np.array(["a", "b"] * (t // 2)),
        geometry=geom,
        trial_row=np.arange(t, dtype=np.int64),
        n_dropped=0,
    )
    return win, real


@pytest.mark.parametrize("name", sorted(KINDS))
def test_every_noise_kind_reaches_the_padded_slots(name: str):
    noise = KINDS[name]
    win, real = windows_with_padding()
    before = win.x.copy()
    keys = np.arange(100, 100 + win.x.shape[0], dtype=np.int64)
    out = apply_to_windows(noise, win, keys, seed=3)
    np.testing.assert_array_equal(win.x, before)  # input untouched
    assert out.x.shape == win.x.shape and out.x.dtype == np.float32
    assert out.geometry is win.geometry and out.y is win.y
    pad = ~real
    assert pad.any()
    # every padded slot is exactly what the noise makes of an all-zero reading at that (trial, slot)
    t, length, n = win.x.shape
    for i in range(t):
        slots = np.flatnonzero(pad[i])
        if slots.size == 0:
            continue
        zeros = SkinFrames(np.zeros((slots.size, n), np.float32), win.geometry.grid_shape, win.geometry)
        expect = noise.apply(zeros, slots, np.full(slots.size, keys[i]), 3).values
        np.testing.assert_array_equal(out.x[i, slots], expect)
    if name in CHANGE_ZEROS:
        assert np.abs(out.x[pad]).sum() > 0, f"{name} left every padded slot clean"
        assert (np.abs(out.x[pad]).sum(axis=-1) > 0).mean() > 0.5, f"{name} left most padded slots clean"
    else:
        np.testing.assert_array_equal(out.x[pad], 0.0)  # coupling or silent taxels: nothing from nothing


@pytest.mark.parametrize("name", ["salt_pepper", "gaussian"])
def test_window_noise_depends_on_seed_trial_and_slot_only(name: str):
    noise = KINDS[name]
    win, _ = windows_with_padding()
    keys = np.arange(100, 100 + win.x.shape[0], dtype=np.int64)
    a = apply_to_windows(noise, win, keys, 1).x
    np.testing.assert_array_equal(a, apply_to_windows(noise, win, keys, 1).x)
    assert not np.array_equal(a, apply_to_windows(noise, win, keys, 2).x)
    # a window's noise does not depend on the other windows: a subset, reordered, gets the same noise
    sub = np.array([4, 1])
    part = WindowedFrames(win.x[sub], win.y[sub], win.groups[sub], win.geometry, win.trial_row[sub], 0)
    np.testing.assert_array_equal(apply_to_windows(noise, part, keys[sub], 1).x, a[sub])
    # the same trial key gives the same noise at the same slot; another key gives other noise
    swapped = apply_to_windows(noise, win, keys[::-1].copy(), 1).x
    assert not np.array_equal(swapped, a)


def test_window_noise_checks_its_arguments():
    win, _ = windows_with_padding()
    with pytest.raises(ValueError, match="trial_key"):
        apply_to_windows(NoNoise(), win, np.arange(3), 0)
    bad = WindowedFrames(win.x[0], win.y, win.groups, win.geometry, win.trial_row, 0)
    with pytest.raises(ValueError, match="trials, L, N"):
        apply_to_windows(NoNoise(), bad, np.arange(6), 0)


PURE = ["+debug=fast", "tracking.enabled=false", "noise.p=1", "noise.mode=replace", "layout.res=6"]


def test_pure_noise_leaves_nothing_to_learn(tmp_path: Path):
    """noise.p=1 (every reading replaced): no slot of any window tells a padded frame from a real one,
    and the Random Forest is at chance (0.125) under LOSO."""
    cfg = compose([*PURE, f"cache.dir={tmp_path}", "data.participants=4", "data.repetitions=6"])
    p = pipeline.make_pipeline(cfg, StageCache(tmp_path))
    x = p.get("filter").x
    plan = p.get("plan")
    padded = plan.frame_index[plan.kept] < 0
    assert padded.any(), "the debug data should have trials shorter than the window"
    assert (x.sum(axis=-1) > 0).all(), "an all-zero (clean) frame survived: padding would leak trial length"
    assert x[padded].mean() == pytest.approx(0.5, abs=0.02)
    assert x[~padded].mean() == pytest.approx(0.5, abs=0.02)
    result = pipeline.run(cfg, StageCache(tmp_path))
    acc = result.summary()["accuracy_mean"]
    # 192 test trials over the folds: at chance the accuracy is 0.125 +/- 0.024 (one binomial SD)
    assert 0.125 - 0.08 < acc < 0.125 + 0.08, f"pure noise gives accuracy {acc:.3f}, chance is 0.125"
