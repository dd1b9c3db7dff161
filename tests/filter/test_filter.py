"""Skin-side temporal filters: debounce (k consecutive frames on), causal median, shapes, config."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sphri import pipeline
from sphri.cache import StageCache
from sphri.config import ConfigError, compose
from sphri.filter.components import DebounceFilter, MedianFilter, NoFilter
from sphri.types import TaxelGeometry, WindowedFrames


def windows(x: np.ndarray) -> WindowedFrames:
    t, _, n = x.shape
    geom = TaxelGeometry(None, None, np.zeros((n, 3)), False, 0.0, 0.0)
    return WindowedFrames(
        x=x,
        y=np.zeros(t, np.int64),
        groups=np.array(["a"] * t),
        geometry=geom,
        trial_row=np.arange(t, dtype=np.int64),
        n_dropped=0,
    )


def brute_debounce(x: np.ndarray, k: int) -> np.ndarray:
    """On at t iff on in each of frames t-k+1 .. t (frames before 0 are off)."""
    out = np.zeros_like(x)
    for t in range(x.shape[1]):
        if t - k + 1 < 0:
            continue
        out[:, t] = x[:, t - k + 1 : t + 1].min(axis=1)
    return out


def brute_median(x: np.ndarray, k: int) -> np.ndarray:
    pad = np.concatenate([np.zeros((x.shape[0], k - 1, x.shape[2]), x.dtype), x], axis=1)
    return np.stack([np.median(pad[:, t : t + k], axis=1) for t in range(x.shape[1])], axis=1)


def test_debounce_needs_k_consecutive_frames_on():
    #                taxel 0: a 1-frame blip, a 2-frame run, a 3-frame run; taxel 1: always on
    seq = np.array([0, 1, 0, 1, 1, 0, 1, 1, 1, 0], dtype=np.float32)
    x = np.stack([seq, np.ones_like(seq)], axis=-1)[None]  # (1, 10, 2)
    out2 = DebounceFilter(frames=2).apply(windows(x)).x
    np.testing.assert_array_equal(out2[0, :, 0], [0, 0, 0, 0, 1, 0, 0, 1, 1, 0])
    np.testing.assert_array_equal(out2[0, :, 1], [0, 1, 1, 1, 1, 1, 1, 1, 1, 1])  # onset delayed by k-1
    out3 = DebounceFilter(frames=3).apply(windows(x)).x
    np.testing.assert_array_equal(out3[0, :, 0], [0, 0, 0, 0, 0, 0, 0, 0, 1, 0])
    np.testing.assert_array_equal(DebounceFilter(frames=1).apply(windows(x)).x, x)


@pytest.mark.parametrize("k", [1, 2, 3, 5])
def test_debounce_matches_brute_force_on_random_and_analogue_readings(k: int):
    rng = np.random.default_rng(k)
    binary = (rng.random((7, 12, 9)) < 0.6).astype(np.float32)
    analogue = rng.random((4, 12, 9)).astype(np.float32)
    for x in (binary, analogue):
        np.testing.assert_array_equal(DebounceFilter(frames=k).apply(windows(x)).x, brute_debounce(x, k))


@pytest.mark.parametrize("k", [1, 3, 5])
def test_median_is_the_causal_running_median(k: int):
    rng = np.random.default_rng(10 + k)
    x = (rng.random((5, 11, 6)) < 0.5).astype(np.float32)
    out = MedianFilter(frames=k).apply(windows(x)).x
    np.testing.assert_array_equal(out, brute_median(x, k))
    assert set(np.unique(out)) <= {0.0, 1.0}, "a binary reading stays binary with odd k"
    a = rng.random((3, 11, 6)).astype(np.float32)
    np.testing.assert_allclose(MedianFilter(frames=k).apply(windows(a)).x, brute_median(a, k))


def test_median_removes_isolated_blips_and_keeps_sustained_touch():
    seq = np.array([0, 0, 1, 0, 0, 1, 1, 1, 1, 0, 0], dtype=np.float32)
    out = MedianFilter(frames=3).apply(windows(seq[None, :, None])).x[0, :, 0]
    np.testing.assert_array_equal(out, [0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 0])


@pytest.mark.parametrize(
    "flt", [NoFilter(), DebounceFilter(frames=2), MedianFilter(frames=3)], ids=["none", "debounce", "median"]
)
def test_shapes_dtype_and_input_untouched(flt):
    rng = np.random.default_rng(0)
    x = (rng.random((4, 8, 5)) < 0.4).astype(np.float32)
    x[1, 5:] = 0.0  # a padded tail
    before = x.copy()
    w = windows(x)
    out = flt.apply(w)
    np.testing.assert_array_equal(x, before)
    assert out.x.shape == x.shape and out.x.dtype == np.float32
    assert out.geometry is w.geometry and out.y is w.y and out.groups is w.groups
    empty = flt.apply(windows(np.zeros((0, 8, 5), np.float32)))
    assert empty.x.shape == (0, 8, 5)
    with pytest.raises(ValueError, match="trials, L, N"):
        flt.apply(WindowedFrames(x[0], w.y, w.groups, w.geometry, w.trial_row, 0))


def test_debounce_filters_noise_in_padded_slots():
    """Salt-and-pepper blips in the padded tail (noise is applied there) are removed like any other."""
    rng = np.random.default_rng(1)
    x = np.zeros((50, 20, 30), np.float32)
    x[:, :5] = 1.0  # a 5-frame touch, then 15 padded slots
    blips = rng.random(x.shape) < 0.01
    x = np.where(blips, 1.0 - x, x).astype(np.float32)
    out = DebounceFilter(frames=2).apply(windows(x)).x
    tail = out[:, 6:]
    assert tail.mean() < 0.01 * 0.01 * 3, "one-frame blips survive debouncing only when two coincide"
    assert out[:, 1:5].mean() > 0.95


def test_filter_configs_compose_and_check_ranges():
    cfg = compose(["filter=debounce", "filter.frames=3"])
    assert cfg.filter.frames == 3 and cfg.filter._target_.endswith("DebounceFilter")
    assert compose([]).filter._target_.endswith("NoFilter"), "the default is no filter (the reference study)"
    assert compose(["filter=median"]).filter.frames == 3
    with pytest.raises(ConfigError, match="filter.frames"):
        compose(["filter=debounce", "filter.frames=0"])
    with pytest.raises(ConfigError, match="filter.frames"):
        compose(["filter=median", "filter.frames=2"])
    with pytest.raises(ConfigError):
        compose(["filter=none", "filter.frames=2"])  # no such key for no filter


def test_filter_change_recomputes_only_filter_and_evaluation(tmp_path: Path):
    cache = StageCache(tmp_path)
    base = ["+debug=fast", "tracking.enabled=false", f"cache.dir={tmp_path}", "layout.res=4"]
    first = pipeline.run(compose(base), cache)
    second = pipeline.run(compose([*base, "filter=debounce"]), cache)
    src = {n: r.source for n, r in second.stages.items()}
    assert src["data"] == "cache" and src["contact"] == "cache" and src["layout"] == "cache"
    assert src["filter"] == "computed" and src["evaluate"] == "computed"
    assert second.stages["evaluate"].key != first.stages["evaluate"].key
    assert second.config_hash != first.config_hash
