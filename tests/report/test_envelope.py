"""The envelope rule (sphri.report.saturation.envelope_saturation) on synthetic curves with a known answer:
a dip curve, a flat noisy curve (the winner's curse and the overshoot rate) and a clean saturating curve."""

from __future__ import annotations

import numpy as np
import pytest

from sphri.report.saturation import envelope_saturation, paired_saturation, rerun_noise


def replicates(
    curve: np.ndarray,
    rng: np.random.Generator,
    seeds: int = 3,
    participants: int = 18,
    noise: float = 0.034,
    spread: float = 0.05,
) -> np.ndarray:
    """(S, P, R) scores: ``curve`` + a participant offset (cancels in pairs) + rerun noise per seed and point."""
    offsets = rng.normal(0.0, spread, (1, participants, 1))
    return curve[None, None, :] + offsets + rng.normal(0.0, noise, (seeds, participants, curve.size))


def test_dip_curve_never_gives_a_point_followed_by_points_outside_the_tolerance():
    # Reaches 0.005 below the plateau at index 3, then dips 9 and 6 points (indices 5-6), then the plateau.
    curve = np.array([0.40, 0.55, 0.65, 0.695, 0.70, 0.61, 0.64, 0.70, 0.70, 0.70, 0.70, 0.70])
    rng = np.random.default_rng(1)
    s = replicates(curve, rng, noise=0.02)
    old = paired_saturation(s.mean(axis=0), "0.01", n_boot=0)
    assert old.index == 3, "the first-crossing rule stops before the dip (what this rule replaces)"
    sat, env = envelope_saturation(s, "0.01", n_boot=300, seed=0)
    assert sat.index == 7 and sat.rule == "envelope"
    assert env.outside[5] and env.outside[6] and not env.outside[7:].any()
    assert (curve.max() - curve[sat.index :] <= 0.01 + 1e-12).all()
    lo, hi = sat.interval
    assert lo <= sat.index <= hi and lo >= 7, "no resample may place the requirement before the dip"


def test_flat_noisy_curve_rarely_overshoots_the_plateau_start():
    # A truly flat 50-point curve (the plateau starts at index 0), rerun noise 0.034 per participant,
    # 18 participants, 3 seeds: the rule overshoots by more than 5 points in under 10 % of 200 draws.
    rng = np.random.default_rng(7)
    curve = np.full(50, 0.70)
    picks, old_picks, noise = [], [], []
    for _ in range(200):
        s = replicates(curve, rng)
        sat, env = envelope_saturation(s, "0.01", n_boot=0)
        picks.append(sat.index)
        noise.append(env.noise.per_participant)
        old_picks.append(paired_saturation(s[0], "0.01", n_boot=0).index)
    overshoot = np.mean(np.array(picks) > 5)
    assert overshoot < 0.10, f"overshoot rate {overshoot:.2f}"
    # The same draws under the first-crossing rule with one seed overshoot far more often (the winner's curse).
    assert np.mean(np.array(old_picks) > 5) > 0.2
    assert abs(np.mean(noise) - 0.034) < 0.002, "the rerun noise is measured between the seeds"


def test_cross_fitting_removes_the_winners_curse_on_a_flat_curve():
    rng = np.random.default_rng(3)
    curve = np.full(30, 0.6)
    crossfit, insample = [], []
    for _ in range(40):
        s = replicates(curve, rng)
        sat, env = envelope_saturation(s, "0.01", n_boot=0)
        assert env.crossfit
        crossfit.append(np.mean(sat.deficit))
        one, env1 = envelope_saturation(s[:1], "0.01", n_boot=0)
        assert not env1.crossfit and "no cross-fitting" in one.note
        insample.append(np.mean(one.deficit))
    # Deficit from a best point chosen on other seeds is unbiased (true deficit 0); chosen and measured on
    # the same runs it is the max of 30 noisy means (about 2 standard errors of 0.008 too high).
    assert abs(np.mean(crossfit)) < 0.002
    assert np.mean(insample) > 0.01


def test_clean_saturating_curve_gives_the_exact_answer():
    res = np.array([1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 18, 22, 27, 33, 40, 50], float)
    curve = 0.8 - 0.5 * np.exp(-res / 5.0)
    expected = next(i for i in range(res.size) if (curve.max() - curve[i:] <= 0.01).all())
    rng = np.random.default_rng(0)
    s = replicates(curve, rng, noise=0.0)
    sat, env = envelope_saturation(s, "0.01", n_boot=200)
    assert sat.index == expected == 11 and sat.best_index == res.size - 1
    assert sat.interval == (expected, expected)
    assert env.noise.per_participant == pytest.approx(0.0, abs=1e-12) and sat.tolerance == pytest.approx(0.01)
    assert not env.finest_outside and not sat.at_finest


def test_tolerance_is_raised_to_the_rerun_noise_and_says_where_the_noise_came_from():
    rng = np.random.default_rng(5)
    s = replicates(np.full(10, 0.5), rng, participants=4, noise=0.1)
    sat, env = envelope_saturation(s, "0.01", n_boot=0)
    assert env.noise.source == "seeds" and env.tolerance_floor == pytest.approx(env.noise.curve)
    assert env.noise.curve == pytest.approx(env.noise.per_participant / 2) and env.noise.curve > 0.03
    assert sat.tolerance == pytest.approx(env.tolerance_floor)
    assert "per participant" in env.noise.describe()
    off, env_off = envelope_saturation(s, "0.01", n_boot=0, noise_floor=False)
    assert off.tolerance == pytest.approx(0.01) and env_off.tolerance_floor == 0.0
    # One seed: the fallback estimates the noise from the jitter between neighbouring resolutions.
    flat = replicates(np.full(40, 0.5), rng, seeds=1, participants=18, noise=0.034)
    fallback = rerun_noise(flat)
    assert fallback.source == "neighbours" and fallback.per_participant == pytest.approx(0.034, rel=0.15)


def test_a_curve_that_falls_at_the_fine_end_is_flagged():
    curve = np.array([0.5, 0.7, 0.7, 0.7, 0.6])
    s = replicates(curve, np.random.default_rng(2), noise=0.005)
    sat, env = envelope_saturation(s, "0.01", n_boot=50)
    assert env.finest_outside and sat.index == 4 and "falls at the fine end" in sat.note


def test_envelope_rule_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="seeds, participants, points"):
        envelope_saturation(np.zeros((2, 2, 2, 2)))
    with pytest.raises(ValueError, match="empty"):
        envelope_saturation(np.zeros((3, 0, 4)))
    with pytest.raises(ValueError, match="no finite score"):
        envelope_saturation(np.full((2, 3, 4), np.nan))
    with pytest.raises(ValueError, match="alpha"):
        envelope_saturation(np.zeros((2, 3, 4)), alpha=1.5)
    with pytest.raises(ValueError, match="tolerance"):
        envelope_saturation(np.zeros((2, 3, 4)), "lots")


def test_requirement_map_flags_the_dip_and_lines_curves_up_by_false_on_rate():
    from types import SimpleNamespace

    import pandas as pd

    from sphri.report.analysis import RequirementMap, requirement_maps

    rng = np.random.default_rng(4)
    dip_curve = np.array([0.40, 0.66, 0.70, 0.61, 0.64, 0.70, 0.70])
    flat_rise = np.array([0.40, 0.60, 0.69, 0.70, 0.70, 0.70, 0.70])

    def curve(values: np.ndarray, rate: float, noise_key: str) -> SimpleNamespace:
        sat, env = envelope_saturation(replicates(values, rng, noise=0.01), "0.01", n_boot=0)
        points = pd.DataFrame({"false_on_rate": rate, "res": np.arange(1, 8), "pitch_u_mm": 10.0 / np.arange(1, 8)})
        return SimpleNamespace(
            sat=sat, envelope=env, points=points, has_pitch=True, keys={"noise.p": noise_key, "model": "rf"}
        )

    clean, noisy = curve(flat_rise, 0.0, "0"), curve(dip_curve, 0.02, "0.02")
    (m,) = requirement_maps([noisy, clean])
    assert isinstance(m, RequirementMap) and m.rates == [0.0, 0.02] and m.curves == [clean, noisy]
    assert m.label == "model=rf", "the noise keys set the rate; the other keys name the map"
    assert m.dip_index(noisy) == 3 and noisy.sat.index == 5, "the trough after the first crossing, and the rule past it"
    assert m.dip_index(clean) is None
    # two curves at the same rate (another noise setting varies) are not a map
    assert requirement_maps([clean, curve(flat_rise, 0.0, "0b")]) == []
