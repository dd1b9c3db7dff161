"""The requirement map's figure: one discrete row per false-on rate of deficits to the row's best, cells
meeting halfway between the swept pitches, and a symlog count axis that shows the clean row at 0."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from sphri.report.reqmap import _edges, _symlog_from_zero, deficit_grid


def curve(res, pitch, acc):
    return SimpleNamespace(points=pd.DataFrame({"res": res, "pitch_mm": pitch, "accuracy_mean": acc}))


def test_deficit_is_per_row_points_to_that_rows_best_with_gaps_left_empty():
    m = SimpleNamespace(
        rates=[0.0, 0.01],
        curves=[curve([2, 6, 12], [120.0, 40.0, 20.0], [0.40, 0.61, 0.60]), curve([2, 12], [120.0, 20.0], [0.3, 0.5])],
    )
    d, pitch, res = deficit_grid(m)
    assert res == [2, 6, 12] and pitch.tolist() == [120.0, 40.0, 20.0]
    assert d[0] == pytest.approx([21.0, 0.0, 1.0])  # a 1-point difference stays 1 point
    assert d[1, 0] == pytest.approx(20.0) and np.isnan(d[1, 1]) and d[1, 2] == pytest.approx(0.0)


def test_cells_meet_halfway_between_pitches_in_log_space():
    x = np.array([5.0, 10.0, 40.0])
    e = _edges(x)
    assert len(e) == 4 and np.all(np.diff(e) > 0) and np.all((e[:-1] < x) & (x < e[1:]))
    assert e[1:-1] == pytest.approx(np.sqrt(x[:-1] * x[1:]))  # geometric midpoints between neighbours
    assert e[0] * e[1] == pytest.approx(x[0] ** 2) and e[-1] * e[-2] == pytest.approx(x[-1] ** 2)  # ends centred
    assert _edges(np.array([7.0])) == pytest.approx([7.0 * np.exp(-0.25), 7.0 * np.exp(0.25)])


def test_the_count_axis_shows_zero_and_the_positive_counts_on_a_log_scale():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0.0, 0.09, 3.0], [1, 2, 3], "o")
    _symlog_from_zero(ax.xaxis, np.array([0.09, 3.0]))
    lo, hi = ax.get_xlim()
    assert ax.get_xscale() == "symlog" and lo < 0.0 < 0.09 and hi >= 3.0
    ticks = ax.xaxis.get_majorticklocs()
    assert ticks[0] == 0.0 and 0.01 in ticks and 1.0 in ticks
    plt.close(fig)


def test_filter_grid_measures_every_pair_against_the_best_pair_over_filters():
    from sphri.report.reqmap import filter_grid

    def fcurve(res, pitch, acc, required):
        c = curve(res, pitch, acc)
        c.recommended = {"res": required}
        return c

    maps = {
        "persistence": SimpleNamespace(
            rates=[0.0, 0.01],
            curves=[fcurve([2, 12], [120.0, 20.0], [0.50, 0.70], 12), fcurve([2, 12], [120.0, 20.0], [0.55, 0.58], 2)],
        ),
        "none": SimpleNamespace(
            rates=[0.0, 0.01, 0.05],  # a rate the other filter lacks is left out
            curves=[
                fcurve([2, 12], [120.0, 20.0], [0.52, 0.75], 12),
                fcurve([2, 12], [120.0, 20.0], [0.45, 0.50], 12),
                fcurve([2, 12], [120.0, 20.0], [0.3, 0.3], 2),
            ],
        ),
    }
    rates, names, d, pitch, required = filter_grid(maps)
    assert rates == [0.0, 0.01] and names == ["none", "persistence"] and pitch.tolist() == [120.0, 20.0]
    # rate 0: the best pair is none at 20 mm (0.75); rate 1 %: persistence at 20 mm (0.58), across filters
    assert d[0, 0] == pytest.approx([23.0, 0.0]) and d[1, 0] == pytest.approx([25.0, 5.0])
    assert d[0, 1] == pytest.approx([13.0, 8.0]) and d[1, 1] == pytest.approx([3.0, 0.0])
    assert required.tolist() == [[1, 1], [1, 0]]
