"""The simulated CoST sensor (sphri.data.cost_sensor) and the spatial comparison of sphri.data.stats."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sphri.data.cost_sensor import SENSOR_COLUMNS, best_window, describe_sensor, sensor_grid, sensor_trials
from sphri.data.format import make_trials_frame
from sphri.data.lengths import COMPARISON_COLUMNS
from sphri.data.reference_stats import COST_AREA_FRACTION, COST_DURATION_MS
from sphri.data.stats import SPATIAL_STATISTICS, outside_area_lines, spatial_checks, spatial_comparison
from sphri.surface.cylinder import CylinderSurface
from sphri.testing.synthetic_contacts import make_contacts
from sphri.types import GestureDataset


def test_sensor_grid_has_costs_pitch_on_the_reachy_arm(robot):
    link = robot.link_for("arm")
    layout = sensor_grid(link, CylinderSurface().fit(link))
    assert layout.grid_shape == (12, 11)  # 24.1 cm long, 22.3 cm around
    assert abs(layout.pitch_u_m - 0.020) < 0.0005 and abs(layout.pitch_v_m - 0.020) < 0.0005
    assert "20.1 mm along" in describe_sensor(robot, "arm", CylinderSurface())


def test_best_window_wraps_around_the_link():
    on = np.zeros((12, 11))
    on[3:6, [9, 10, 0, 1]] = 1.0  # a touch across the seam
    on[0, 4] = 0.5
    i, j = best_window(on, wrap_v=True)
    cols = (j + np.arange(8)) % 11
    assert set([9, 10, 0, 1]) <= set(cols.tolist()) and i <= 3
    # without wrap the window cannot hold both sides of the seam
    i2, j2 = best_window(on, wrap_v=False)
    assert 0 <= j2 <= 3


def _dataset(hand, gestures_frames):
    """Trials of 30 frames each on the arm, one per (gesture, participant) entry."""
    rows, start = [], 0
    for k, (g, p) in enumerate(gestures_frames, 1):
        rows.append(
            dict(
                participant=p,
                region="arm",
                trial_ordinal=k,
                trial_id=f"{k:04d}_{g}",
                gesture=g,
                start=start,
                n_frames=30,
            )
        )
        start += 30
    poses = np.zeros((start, hand.n_capsules, 7), np.float32)
    poses[..., 6] = 1.0
    return GestureDataset(
        name="toy", synthetic=True, hand=hand, trials=make_trials_frame(rows), poses=poses, frame_rate_hz=30.0
    )


def test_known_patches_give_known_fractions_and_durations(hand, robot):
    """A 5 mm patch on a cell centre turns on exactly that cell (1/64); a 25 mm one the 3 x 3 cells around it
    (9/64: it reaches 15 mm into the edge neighbours and past the corners, not the next ring 30 mm away)."""
    link = robot.link_for("arm")
    surface = CylinderSurface()
    layout = sensor_grid(link, surface.fit(link))
    _, w = layout.grid_shape
    cell = 6 * w + 5
    p, n = layout.position_m[cell], layout.normal[cell]
    ds = _dataset(
        hand,
        [("poke", "participant_01"), ("grab", "participant_01"), ("hit", "participant_01"), ("grab", "participant_02")],
    )
    frame, radius = [], []
    frame += list(range(5, 15))
    radius += [0.005] * 10  # poke: frames 5..14
    frame += list(range(30 + 2, 30 + 8))
    radius += [0.025] * 6  # grab: frames 2..7 and 20..21 (gap)
    frame += [30 + 20, 30 + 21]
    radius += [0.005, 0.005]
    frame += list(range(90 + 0, 90 + 30))
    radius += [0.025] * 30  # grab 2: the whole trial
    k = len(frame)
    contacts = make_contacts(frame, np.tile(p, (k, 1)), np.tile(n, (k, 1)), radius, ds.n_frames)
    st = sensor_trials(ds, contacts, robot, surface)
    assert list(st.columns) == SENSOR_COLUMNS
    assert st["sensor_contact"].tolist() == [True, True, False, True]
    assert st["sensor_frames"].tolist() == [10, 8, 0, 30]
    assert np.isclose(st["area_fraction"][0], 1 / 64)
    assert np.isclose(st["area_fraction"][1], (6 * 9 + 2 * 1) / 8 / 64)  # mean over the contact frames only
    assert np.isnan(st["area_fraction"][2]) and st["duration_s"][2] == 0.0
    assert np.isclose(st["area_fraction"][3], 9 / 64)
    assert np.allclose(st["duration_s"][[0, 1, 3]], [10 / 30, 20 / 30, 30 / 30])  # first to last, gaps included

    table = spatial_comparison(st)
    assert list(table.columns) == COMPARISON_COLUMNS
    assert table["statistic"].unique().tolist() == [s[0] for s in SPATIAL_STATISTICS]
    area = table[table["statistic"] == "CoST sensor area mean"].set_index("gesture")
    assert area.index.tolist() == ["poke", "grab"]  # GESTURES order; hit never reached the sensor
    grab_mean = ((6 * 9 + 2) / 8 / 64 + 9 / 64) / 2
    assert (
        np.isclose(area.loc["grab", "value"], grab_mean)
        and area.loc["grab", "reference"] == COST_AREA_FRACTION["grab"][0]
    )
    assert np.isclose(area.loc["poke", "ratio"], (1 / 64) / COST_AREA_FRACTION["poke"][0])
    assert (area["flag"] == "OUTSIDE").all()  # far below CoST
    assert area.loc["poke", "band"] == "0.63-1.37x" and area.loc["grab", "band"] == "0.89-1.11x"  # cost_band
    assert outside_area_lines(table) == [
        f"arm: contact area outside its CoST band: poke {area.loc['poke', 'ratio']:.2f}x (band 0.63-1.37x), "
        f"grab {area.loc['grab', 'ratio']:.2f}x (band 0.89-1.11x)"
    ]
    dur = table[table["statistic"] == "CoST sensor dur mean ms"].set_index("gesture")
    assert (
        np.isclose(dur.loc["poke", "value"], 1000 * 10 / 30)
        and dur.loc["poke", "reference"] == COST_DURATION_MS["poke"][0]
    )
    assert dur.loc["poke", "flag"] == "OUTSIDE"  # 333 ms is 0.51x CoST's 650 ms
    sd = table[table["statistic"] == "CoST sensor area sd"].set_index("gesture")
    assert np.isnan(sd.loc["poke", "value"]) and sd.loc["poke", "flag"] == "OUTSIDE"  # one trial: no SD


@pytest.mark.parametrize("n_in, passes", [(6, True), (5, False)])
def test_spatial_check_needs_six_of_eight_gestures_in_band(n_in, passes):
    gestures = list(COST_AREA_FRACTION)
    rows = []
    for k, g in enumerate(gestures):
        ratio = 1.0 if k < n_in else 2.0
        rows.append(
            {
                "participant": "p",
                "region": "arm",
                "gesture": g,
                "sensor_contact": True,
                "sensor_frames": 5,
                "area_fraction": COST_AREA_FRACTION[g][0] * ratio,
                "duration_s": 1.0,
                "window_row": 0,
                "window_col": 0,
            }
        )
    table = spatial_comparison(pd.DataFrame(rows))
    ((name, ok, detail),) = spatial_checks(table)
    assert name == "arm CoST sensor area" and ok is passes and detail.startswith(f"{n_in}/8 gestures in band")


def test_cost_bands_are_the_sampling_intervals_of_costs_reported_numbers():
    from scipy.stats import chi2, t

    from sphri.data.lengths import cost_band
    from sphri.data.reference_stats import COST_PARTICIPANTS, COST_SOURCE

    assert COST_PARTICIPANTS == 31 and "Table 4" in COST_SOURCE and "Jung" in COST_SOURCE
    # grab's area: 0.59 (SD 0.17) over 31 participants -> 1 +/- t(0.975, 30) * (0.17 / 0.59) / sqrt(31)
    half = 2.0422724563 * (0.17 / 0.59) / 31**0.5
    assert cost_band("mean", *COST_AREA_FRACTION["grab"]) == pytest.approx((1 - half, 1 + half))
    assert half == pytest.approx(t.ppf(0.975, 30) * 0.17 / 0.59 / np.sqrt(31))
    # hit's duration: 337 (SD 403) -> about +/- 44 %
    assert cost_band("mean", *COST_DURATION_MS["hit"]) == pytest.approx((0.5610, 1.4390), abs=1e-3)
    # an SD: the chi-square interval with 30 degrees of freedom, whatever the SD's value
    assert cost_band("sd", *COST_AREA_FRACTION["poke"]) == pytest.approx(
        (np.sqrt(30 / chi2.ppf(0.975, 30)), np.sqrt(30 / chi2.ppf(0.025, 30)))
    )
    assert cost_band("sd", 1.0, 1.0) == pytest.approx((0.7991, 1.3367), abs=1e-3)
    # more participants, narrower band
    assert np.subtract(*cost_band("mean", 1.0, 1.0, n=558)[::-1]) < np.subtract(*cost_band("mean", 1.0, 1.0)[::-1])
    with pytest.raises(ValueError, match="mean"):
        cost_band("median", 1.0, 1.0)
    # the table's rows carry them: a ratio just inside poke's area band is ok, just outside is OUTSIDE
    lo, hi = cost_band("mean", *COST_AREA_FRACTION["poke"])
    for ratio, flag in ((hi - 0.01, "ok"), (hi + 0.01, "OUTSIDE"), (lo + 0.01, "ok"), (lo - 0.01, "OUTSIDE")):
        row = {
            "participant": "p",
            "region": "arm",
            "gesture": "poke",
            "sensor_contact": True,
            "sensor_frames": 5,
            "area_fraction": COST_AREA_FRACTION["poke"][0] * ratio,
            "duration_s": 1.0,
            "window_row": 0,
            "window_col": 0,
        }
        table = spatial_comparison(pd.DataFrame([row, row]))
        assert table.loc[table["statistic"] == "CoST sensor area mean", "flag"].item() == flag
