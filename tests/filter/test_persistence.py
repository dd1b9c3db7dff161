"""filter=persistence: debounce with its duration in milliseconds, converted at the windows' frame rate."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sphri.config import ConfigError, compose
from sphri.filter.components import DebounceFilter, PersistenceFilter, persistence_frames
from tests.filter.test_filter import brute_debounce, windows


def test_milliseconds_to_frames():
    assert persistence_frames(50, 30) == 2 and persistence_frames(100, 30) == 3
    assert persistence_frames(1000 / 30, 30) == 1, "exactly one frame's time is one frame"
    assert persistence_frames(0, 30) == 1 and persistence_frames(50, 60) == 3
    with pytest.raises(ValueError, match="frame rate"):
        persistence_frames(50, float("nan"))


@pytest.mark.parametrize(("ms", "rate", "k"), [(50, 30, 2), (100, 30, 3), (50, 60, 3), (10, 30, 1)])
def test_persistence_is_debounce_at_the_frame_rate(ms, rate, k):
    rng = np.random.default_rng(k)
    x = (rng.random((4, 12, 7)) < 0.6).astype(np.float32)
    w = dataclasses.replace(windows(x), frame_rate_hz=float(rate))
    out = PersistenceFilter(ms=ms).apply(w)
    np.testing.assert_array_equal(out.x, brute_debounce(x, k))
    np.testing.assert_array_equal(out.x, DebounceFilter(frames=k).apply(w).x)
    assert out.frame_rate_hz == rate


def test_windows_without_a_frame_rate_are_refused():
    with pytest.raises(ValueError, match="frame rate"):
        PersistenceFilter(ms=50).apply(windows(np.ones((1, 3, 2), np.float32)))


def test_config_composes_and_checks_range():
    assert compose(["filter=persistence"]).filter.ms == 50.0
    assert compose(["filter=persistence", "filter.ms=100"]).filter.ms == 100.0
    with pytest.raises(ConfigError):
        compose(["filter=persistence", "filter.ms=-1"])
