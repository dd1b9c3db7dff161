"""Greedy coverage curve, the recommendation and its held-out check."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sphri.analysis.placement import _circular_range, coverage_curve, recommendation, region_text


def test_hand_computed_curve():
    # 4 elements of areas 1, 1, 2, 4; densities rank them 2 > 0 > 1 > 3
    density = np.array([0.5, 0.2, 0.9, 0.1])
    area = np.array([1.0, 1.0, 2.0, 4.0])
    # frames: 0 touches {2}, 1 touches {0, 3}, 2 touches {3}, 3 touches {1, 2}, 4 touches {0}
    frames = np.array([0, 1, 1, 2, 3, 3, 4])
    elements = np.array([2, 0, 3, 3, 1, 2, 0])
    c = coverage_curve(density, area, frames, elements, capture=0.6)
    assert c.order.tolist() == [2, 0, 1, 3]
    np.testing.assert_allclose(c.area_share, [0, 2 / 8, 3 / 8, 4 / 8, 1])
    # covering {2} captures frames 0 and 3; + {0}: frames 1 and 4; + {1}: none new; + {3}: frame 2
    np.testing.assert_allclose(c.frame_share, [0, 2 / 5, 4 / 5, 4 / 5, 1])
    assert c.k == 2 and c.area_at_capture == pytest.approx(3 / 8)
    assert c.mask.tolist() == [True, False, True, False]
    assert coverage_curve(density, area, frames, elements, capture=1.0).k == 4
    assert coverage_curve(density, area, frames, elements, capture=0.4).k == 1  # exactly 2/5 is enough
    r = c.resampled(5)
    assert r["frame_share"].tolist() == pytest.approx([0, 0.4, 0.8, 0.8, 1.0])


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 40), st.integers(1, 60), st.integers(0, 2**31 - 1), st.floats(0.05, 1.0))
def test_curve_is_monotone_and_reaches_everything(p, n_frames, seed, capture):
    rng = np.random.default_rng(seed)
    density = rng.random(p)
    area = rng.random(p) + 0.01
    per = rng.integers(1, 4, n_frames)
    frames = np.repeat(np.arange(n_frames), per)
    elements = rng.integers(0, p, frames.size)
    c = coverage_curve(density, area, frames, elements, capture)
    assert np.all(np.diff(c.area_share) > 0) and np.all(np.diff(c.frame_share) >= 0)
    assert c.frame_share[-1] == pytest.approx(1.0) and c.area_share[-1] == pytest.approx(1.0)
    assert c.frame_share[c.k] >= capture - 1e-12
    assert c.k == 0 or c.frame_share[c.k - 1] < capture - 1e-12
    assert c.n_frames == n_frames and c.mask.sum() == c.k


def test_no_frames_and_bad_inputs():
    c = coverage_curve(np.ones(3), np.ones(3), np.zeros(0, int), np.zeros(0, int))
    assert c.n_frames == 0 and c.k == 0
    assert "no contact frames" in recommendation(c, [], "cylinder", "l_arm")
    with pytest.raises(ValueError, match="capture"):
        coverage_curve(np.ones(3), np.ones(3), [0], [1], capture=0)
    with pytest.raises(ValueError, match="sorted"):
        coverage_curve(np.ones(3), np.ones(3), [1, 0], [1, 1])
    with pytest.raises(ValueError, match="sorted"):
        coverage_curve(np.ones(3), np.ones(3), [0], [3])


def test_circular_range_and_region_words():
    assert _circular_range(np.array([0.1, 0.2, 0.15])) == pytest.approx((0.1, 0.2))
    assert _circular_range(np.array([0.95, 0.02, 0.05])) == pytest.approx((0.95, 0.05))  # wraps the seam
    part = {
        "area_cm2": 12.34,
        "share": 1.0,
        "centroid_mm": [1.0, -40.0, -410.0],
        "u_range": (0.55, 0.98),
        "v_range": (0.95, 0.05),
    }
    assert region_text(part, "cylinder") == "12.3 cm^2 at (1, -40, -410) mm, h 0.55-0.98, a 342-18 deg"
    part["v_range"] = (0.30, 0.25)
    assert "all around" in region_text(part, "cylinder")
    assert region_text({"area_cm2": 1, "share": 1, "centroid_mm": [0, 0, 0]}, "mesh") == "1.0 cm^2 at (0, 0, 0) mm"
