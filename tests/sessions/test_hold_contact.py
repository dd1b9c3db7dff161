"""Held gestures keep contact: on parts other than the arm's segments a rub or grab stays on its link's surface.

The gesture generator presses the hand into the drawn part for the whole contact phase; settling it out of the robot
(:func:`settle_hands`) used to leave it off its own link in part of that phase (the contact came in several runs).
:func:`hold_contact` pulls it back onto the surface. Measured on the study's robot (``robot=reachy2``, packaged)
with the study's random streams: the first held touches on non-limb parts.
"""

from __future__ import annotations

import numpy as np
import pytest

from sphri.sessions import synthetic as syn
from tests.sessions.conftest import generated, study_touches

N_TOUCHES = 6


def _runs(on: np.ndarray) -> int:
    return int((np.diff(np.r_[0, on.astype(np.int8)]) == 1).sum())


@pytest.fixture(scope="module")
def study():
    return study_touches(
        lambda dr: dr.gesture in ("rub", "grab") and not dr.part.startswith(("upper_arm", "forearm")), N_TOUCHES
    )


def _held_touches(study, monkeypatch, hold: bool) -> list[dict]:
    """Per picked session: the drawing hand's contact-phase frames on its own link (runs, share, deepest mm)."""
    gen, hand, robot, table, picks = study
    seen: dict = {}
    real = syn.hold_contact

    def spy(out, lk, robot_, hand_, own, phase, *a, **kw):
        seen.update(phase=phase[:, 1].copy(), own=own[1], lk=lk)
        return real(out, lk, robot_, hand_, own, phase, *a, **kw) if hold else (out, 0)

    monkeypatch.setattr(syn, "hold_contact", spy)
    rows = []
    for out, info in generated(study):
        m = seen["phase"]
        gap, _ = syn.own_link_gap(
            out[m, 1].astype(np.float64), seen["lk"][m, seen["own"]], robot, hand, seen["own"], 0.2
        )
        on = gap <= 0
        rows.append(dict(runs=_runs(on), on=float(on.mean()), deepest_mm=float(-gap.min() * 1e3), info=info))
    return rows


def test_held_gestures_on_non_limb_parts_keep_one_contact_run(study, monkeypatch):
    rows = _held_touches(study, monkeypatch, hold=True)
    assert len(rows) == N_TOUCHES
    assert np.median([r["runs"] for r in rows]) == 1
    assert np.median([r["on"] for r in rows]) >= 0.95
    assert max(r["deepest_mm"] for r in rows) <= 5.0 + 0.5  # within the compliance
    assert sum(r["info"]["held_frames"] for r in rows) > 0


def test_without_hold_contact_the_touch_breaks_up(study, monkeypatch):
    """The generator before hold_contact (settling only): the same touches lose their own link mid-contact."""
    rows = _held_touches(study, monkeypatch, hold=False)
    assert np.median([r["runs"] for r in rows]) > 2
    assert np.median([r["on"] for r in rows]) < 0.9
