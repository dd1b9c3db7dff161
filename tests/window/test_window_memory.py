"""Every config range physical (issue 29, item 3): window memory is estimated before allocating."""

from __future__ import annotations

import numpy as np
import pytest
from test_window_onset import contacts_at, dataset, toy_layout

from sphri.config import ConfigError
from sphri.types import Frames
from sphri.window import onset
from sphri.window.onset import OnsetWindow


def test_windows_larger_than_memory_allows_are_refused_with_the_estimate(monkeypatch):
    """Reproducer (issue 29): ``+debug=fast window.frames=100000`` tried a 5.2 GiB array. Here 2 windows
    x 50,000 frames x 200 taxels (0.0745 GiB) against 0.25 GiB available (a quarter of it allowed)."""
    monkeypatch.setattr(onset, "available_memory_bytes", lambda: float(1 << 28), raising=False)
    ds = dataset([10, 10])
    c = contacts_at([1, 12], ds.n_frames)
    plan = OnsetWindow(frames=50_000).plan(c, ds)
    lay, sm = toy_layout(200)
    frames = Frames(np.zeros((int((plan.frame_index >= 0).sum()), 200), np.uint8), (1, 200))
    with pytest.raises(
        onset.WindowMemoryError,
        match=r"window: the windows \(2 x 50000 x 200, 4 bytes each\) "
        r"would take 0\.0745 GiB, more than a quarter of the 0\.25 GiB .*"
        r"lower window\.frames \(now 50000\)",
    ):
        OnsetWindow(frames=50_000).assemble(frames, plan, ds, lay, sm)
    # the same windows within an explicit limit are built
    w = OnsetWindow(frames=50_000, max_memory_gib=0.1).assemble(frames, plan, ds, lay, sm)
    assert w.x.shape == (2, 50_000, 200)


def test_window_plan_is_estimated_too_and_the_limit_is_a_checked_setting():
    ds = dataset([10, 10])
    c = contacts_at([1, 12], ds.n_frames)
    with pytest.raises(
        onset.WindowMemoryError,
        match=r"the window plan \(2 x 100000, 3 arrays, 8 bytes each\) would "
        r"take 0\.00447 GiB, more than window\.max_memory_gib=0\.001",
    ):
        OnsetWindow(frames=100_000, max_memory_gib=0.001).plan(c, ds)
    for bad in (0, -1.0, float("inf")):
        with pytest.raises(ConfigError, match="window.max_memory_gib"):
            OnsetWindow(max_memory_gib=bad)
