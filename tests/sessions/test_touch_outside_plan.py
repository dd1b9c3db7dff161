"""A hand touches its part only in its planned contact phase (sessions version 6).

The gesture generator plans a touch by its effector point; in a finger-pad rub the other finger capsules reach the
surface about 7 frames before and after that plan (``outputs/bench/rub_overrun.json``), which made the study's rubs
touch 1.5x their plan. :func:`settle_hands` given the phase keeps the hand clear of its own link outside it.
Measured on the study's robot (``robot=reachy2``, packaged) with the study's random streams: its first rubs.
"""

from __future__ import annotations

import numpy as np
import pytest

from sphri.sessions import synthetic as syn
from tests.sessions.conftest import generated, study_touches

N_RUBS = 4


@pytest.fixture(scope="module")
def rubs():
    return study_touches(lambda dr: dr.gesture == "rub" and not dr.two_hands, N_RUBS)


def _outside_plan(rubs, monkeypatch, with_phase: bool) -> list[tuple[int, float]]:
    """Per picked rub: (frames of the touch outside its plan in which the drawing hand touches its own link, the
    smallest gap (mm) there)."""
    gen, hand, robot, table, picks = rubs
    seen: dict = {}
    real = syn.settle_hands

    def spy(out, lk, robot_, hand_, own, comp, away, *a, phase=None, **kw):
        seen.update(phase=None if phase is None else phase.copy(), own=own, lk=lk)
        return real(out, lk, robot_, hand_, own, comp, away, *a, phase=phase if with_phase else None, **kw)

    monkeypatch.setattr(syn, "settle_hands", spy)
    rows = []
    for out, info in generated(rubs):
        assert seen["phase"] is not None, "the session generator must pass the planned phase to settle_hands"
        start, n = info["touch_start_frame"], info["touch_frames"]
        window = np.zeros(len(out), dtype=bool)
        window[start : start + n] = True
        outside = window & ~seen["phase"][:, 1]
        own = seen["own"][1]
        gap, _ = syn.own_link_gap(out[outside, 1].astype(np.float64), seen["lk"][outside, own], robot, hand, own, 0.05)
        rows.append((int((gap <= 0).sum()), float(gap.min() * 1e3) if gap.size else np.inf))
    return rows


def test_a_rub_touches_its_part_only_in_its_plan(rubs, monkeypatch):
    rows = _outside_plan(rubs, monkeypatch, with_phase=True)
    assert len(rows) == N_RUBS
    assert all(n == 0 for n, _ in rows), rows
    assert min(g for _, g in rows) > 0, rows  # clear of the surface (contact rows are pushed off by the clearance)


def test_without_the_phase_a_rub_touches_before_or_after_its_plan(rubs, monkeypatch):
    rows = _outside_plan(rubs, monkeypatch, with_phase=False)
    assert sum(n for n, _ in rows) > 0, rows
