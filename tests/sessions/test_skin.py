"""The skin design's greedy patch order and budget curves on hand-made incidence matrices."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import sparse

from sphri.sessions.skin import budget_curves, first_rank, greedy_patches


def incidence(rows: list[list[int]], k: int) -> sparse.csr_matrix:
    r = [i for i, cols in enumerate(rows) for _ in cols]
    c = [j for cols in rows for j in cols]
    return sparse.csr_matrix((np.ones(len(c)), (r, c)), shape=(len(rows), k))


def test_greedy_takes_the_most_new_contact_per_area_and_passes_over_what_does_not_fit():
    # patch 0: 4 frames on 4 m^2 (1/m^2); patch 1: 3 frames on 1 m^2; patch 2: the same 3 frames on 1 m^2
    # (nothing new once 1 is in); patch 3: 1 frame on 0.5 m^2 (2/m^2)
    m = incidence([[0], [0], [0], [0], [1, 2], [1, 2], [1, 2], [3]], 5)
    area = np.array([4.0, 1.0, 1.0, 0.5, 2.0])
    order, new = greedy_patches(m, area)
    assert order.tolist()[:3] == [1, 3, 0] and new.tolist() == [3, 1, 4, 0, 0]
    assert order.tolist()[3:] == [2, 4]  # nothing new: smallest first
    # a 3 m^2 budget: patch 0 (4 m^2) does not fit
    order, new = greedy_patches(m, area, budget_m2=3.0)
    assert order.tolist() == [1, 3] and new.sum() == 4
    assert first_rank(m, np.array([1, 3])).tolist() == [2] * 4 + [0] * 3 + [1]


def test_budget_curves_in_sample_reach_one_and_held_out_pay_for_participants_who_differ():
    rng = np.random.default_rng(0)
    k, rows, unit, group = 30, [], [], []
    for p in range(8):
        own = rng.choice(k, 3, replace=False)  # each participant touches their own patches ...
        for f in range(60):
            rows.append([int(rng.choice(own)) if f % 3 else 0])  # ... and patch 0, which everyone touches
            unit.append(f"p{p}")
            group.append("A" if f % 2 else "B")
    m = incidence(rows, k)
    area = rng.uniform(0.5, 2.0, k)
    c = budget_curves(m, np.array(group), np.array(unit), ["A", "B"], area, pitch_mm=10.0, heldout_splits=5)
    assert set(c["scenario"]) == {"all", "A", "B"}
    for _, g in c.groupby(["scenario", "curve"]):
        assert g["captured"].is_monotonic_increasing
    ins = c[(c["scenario"] == "all") & (c["curve"] == "in_sample")]
    held = c[(c["scenario"] == "all") & (c["curve"] == "heldout")]
    assert ins["captured"].iloc[-1] == pytest.approx(1.0) and held["captured"].iloc[-1] == pytest.approx(1.0)
    assert held["captured"].mean() < ins["captured"].mean() - 0.02
    assert (held["n_splits"] == 10).all() and held["captured_sd"].gt(0).any()
    assert ins["area_cm2"].iloc[-1] == pytest.approx(area.sum() * 1e4)
    np.testing.assert_array_equal(ins["taxels"], np.floor(ins["area_cm2"] * 100 / 100 + 1e-9).astype(int))
    # one participant: no held-out curve
    one = budget_curves(m, np.array(group), np.full(len(rows), "p0"), ["A", "B"], area, 10.0)
    assert set(one["curve"]) == {"in_sample"}
    assert isinstance(one, pd.DataFrame)
