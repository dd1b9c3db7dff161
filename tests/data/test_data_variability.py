"""How varied the synthetic participants are: calibrated spread, variability knob, tracking knobs, stats flags."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sphri.config import ConfigError, compose
from sphri.data.gestures import Style
from sphri.data.lengths import compare, format_comparison, length_spread, length_table, manifest_lengths
from sphri.data.people import Spread
from sphri.data.reference_stats import VR_LENGTH_SPREAD
from sphri.data.synthetic import SyntheticData
from sphri.types import GESTURES


def spread_of(ds) -> dict:
    return length_spread(length_table(ds.trials, ds.frame_rate_hz))["arm"]


@pytest.fixture(scope="module")
def moderate(hand, robot):
    """10 participants x 6 repetitions on the arm (480 trials): enough to see the spread."""
    return SyntheticData(seed=1, participants=10, repetitions=6).load(hand=hand, robot=robot)


def test_spread_lands_in_the_calibrated_band(moderate):
    s = spread_of(moderate)
    ref = VR_LENGTH_SPREAD["arm"]
    ratios = np.array([s["gestures"][g]["sd_log"] / ref["gestures"][g]["sd_log"] for g in GESTURES])
    assert (ratios > 0.7).sum() >= 6 and (ratios < 1.4).sum() >= 6, ratios.round(2)
    # participants differ by a real person's order (0.079); 10 participants: wide sampling band
    assert 0.3 * ref["between_var"] < s["between_var"] < 3.0 * ref["between_var"], s["between_var"]
    assert s["participant_median_max"] / s["participant_median_min"] > 1.5
    assert s["max_frames"] > 300  # heavy tails


def test_variability_zero_makes_participants_interchangeable(hand, robot):
    ds = SyntheticData(seed=1, participants=6, repetitions=3, variability=0.0).load(hand=hand, robot=robot)
    s = spread_of(ds)
    assert s["between_var"] < 1e-3 and s["interaction_var"] < 1e-3
    assert s["participant_median_max"] / s["participant_median_min"] < 1.1
    # every participant's style is the population's (hand size included)
    sp = Spread(variability=0.0)
    a, b = (Style.draw(np.random.default_rng([1, k, 0]), sp, GESTURES) for k in (1, 2))
    assert a.scale == b.scale and a.speed == b.speed and a.duration_g == b.duration_g and a.habits == b.habits
    assert all(np.allclose(a.counts[g], b.counts[g]) for g in a.counts)
    assert not a.left_handed and not b.left_handed


def test_variability_scales_the_spread(hand, robot):
    lo = spread_of(SyntheticData(seed=2, participants=6, repetitions=3, variability=0.5).load(hand=hand, robot=robot))
    hi = spread_of(SyntheticData(seed=2, participants=6, repetitions=3, variability=1.5).load(hand=hand, robot=robot))
    assert hi["between_var"] > 2 * lo["between_var"]
    assert np.mean([hi["gestures"][g]["sd_log"] for g in GESTURES]) > np.mean(
        [lo["gestures"][g]["sd_log"] for g in GESTURES]
    )


def test_people_differ_per_gesture_not_by_one_factor():
    """Two participants' orderings of gestures by duration differ (participant x gesture effects)."""
    sp = Spread()
    styles = [Style.draw(np.random.default_rng([0, k, 0]), sp, GESTURES) for k in range(1, 7)]
    orders = {tuple(sorted(GESTURES, key=lambda g: s.duration_g[g])) for s in styles}
    assert len(orders) == len(styles)
    habits = np.array([[s.habits[h] for h in ("hit_fist", "pat_fingers", "push_tip")] for s in styles])
    assert habits.std(axis=0).min() > 0.1  # personal habits, not the population rate for everyone


def test_seeds_reproduce_exactly_with_every_spread(hand, robot):
    kw = dict(
        participants=2,
        repetitions=2,
        regions=["arm"],
        brush_rate=0.5,
        retouch_rate=0.5,
        deep_rate=0.5,
        boundary_early_rate=0.3,
        boundary_late_rate=0.3,
        long_trial_rate=0.2,
        jumps_per_trial=1.0,
    )
    a = SyntheticData(seed=5, **kw).load(hand=hand, robot=robot)
    b = SyntheticData(seed=5, **kw).load(hand=hand, robot=robot)
    assert np.array_equal(a.poses, b.poses) and a.trials.equals(b.trials)


def test_jitter_mm_is_the_sd_of_the_tracked_hand_position(hand, robot):
    def wrist(jitter):
        ds = SyntheticData(seed=3, participants=1, repetitions=2, jitter_mm=jitter, jumps_per_trial=0.0).load(
            hand=hand, robot=robot
        )
        return ds.poses[:, 0, :3].astype(np.float64)

    # same seed, same draws: the difference is the jitter alone, one value per tracking sample
    quiet, shaky = wrist(0.0), wrist(8.0)
    assert quiet.shape == shaky.shape
    assert np.std(shaky - quiet) == pytest.approx(8e-3, rel=0.2)


def test_schema_checks_the_knobs():
    with pytest.raises(ConfigError, match="data.variability"):
        compose(["data.variability=-0.5"])
    with pytest.raises(ConfigError, match="data.jitter_mm"):
        compose(["data.jitter_mm=80"])
    with pytest.raises(ConfigError, match="data.brush_rate"):
        compose(["data.brush_rate=1.5"])
    cfg = compose(["data.variability=0.5", "data.jitter_mm=6"])
    assert cfg.data.variability == 0.5 and cfg.data.jitter_mm == 6.0


def _trials(lengths: dict[str, list[int]]) -> pd.DataFrame:
    rows = [
        {"participant": p, "region": "arm", "gesture": g, "n_frames": n}
        for p, ns in lengths.items()
        for g, n in zip(GESTURES * 4, ns)
    ]
    return pd.DataFrame(rows)


def test_length_spread_is_exact_on_a_hand_made_table():
    # participant B is twice as slow as A in every trial: log ratio ln 2, between variance (ln 2)^2 / 2
    a = [100] * 8 + [110] * 8
    t = _trials({"A": a, "B": [2 * n for n in a]})
    s = length_spread(length_table(t, 30.0))["arm"]
    assert s["between_var"] == pytest.approx(np.log(2) ** 2 / 2)
    assert s["interaction_var"] == pytest.approx(0.0, abs=1e-12)
    assert s["participant_median_min"] == 105 and s["participant_median_max"] == 210 and s["max_frames"] == 220
    assert s["gestures"]["hit"]["q50"] == pytest.approx(155.0)
    # frames are counted at 30 Hz: the same trials at 60 Hz are half as long
    assert length_spread(length_table(t, 60.0))["arm"]["max_frames"] == 110


def test_stats_flags_a_dataset_outside_the_real_spread():
    same = compare(VR_LENGTH_SPREAD, VR_LENGTH_SPREAD)
    assert len(same) == 2 * (8 * 6 + 6) and (same["flag"] == "ok").all()
    # interchangeable participants with fixed lengths: no spread at all
    t = _trials({p: [100 + i % 3 for i in range(32)] for p in ("A", "B", "C")})
    flat = compare(length_spread(length_table(t, 30.0)), VR_LENGTH_SPREAD)
    out = set(flat.loc[flat["flag"] == "OUTSIDE", "statistic"])
    assert {"sd_log", "between_var", "participant_median_max", "max_frames"} <= out
    assert "OUTSIDE" in format_comparison(flat, "flat") and "rows inside their band" in format_comparison(flat, "flat")


@pytest.mark.shared
def test_stored_reference_matches_the_manifests(shared_dir):
    s = length_spread(manifest_lengths(shared_dir / "vr-gesture-dataset", ["arm", "torso"]))
    for region in ("arm", "torso"):
        for k in ("between_var", "within_sd", "participant_median_min", "participant_median_max", "max_frames"):
            assert s[region][k] == pytest.approx(VR_LENGTH_SPREAD[region][k], abs=1e-3)
        for g in GESTURES:
            assert s[region]["gestures"][g]["sd_log"] == pytest.approx(
                VR_LENGTH_SPREAD[region]["gestures"][g]["sd_log"], abs=1e-3
            )
