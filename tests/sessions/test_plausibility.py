"""Synthetic hands stop at the skin of the drawn part; the plausibility checks catch hands that do not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hydra.utils import instantiate

from sphri.config import compose
from sphri.sessions import synthetic as syn
from sphri.sessions.contact import body_contacts
from sphri.sessions.plausibility import arm_reference, cost_sampling_interval, plausibility
from tests.sessions.conftest import SMALL


def _checks(cfg, robot, ds) -> dict:
    return plausibility(ds, body_contacts(ds, robot, instantiate(cfg.contact)), robot, 5.0)


def test_settled_hands_pass_penetration_and_drawn_part(small):
    cfg, _, robot, ds = small
    p = _checks(cfg, robot, ds)
    assert p["compliance_mm"] == 5.0
    assert p["penetration_p95_mm"] <= 5.0 and p["penetration_ok"]
    assert p["penetration_max_mm"] <= 5.0 + 0.5
    assert p["on_drawn_part_share"] >= 0.9 and p["on_drawn_part_ok"]
    assert (ds.truth["duration_scale"] == 1.0).all()
    # reported, not judged: the touches in which the drawing hand reaches the robot at all
    reached = sum(g["n_reached"] for g in p["gestures"].values())
    assert p["touches_reached_share"] == pytest.approx(reached / len(ds.truth), abs=1e-4)
    assert 0.5 <= p["touches_reached_share"] < 1.0  # the small sample has touches blocked by other links


def test_unsettled_stretched_hands_fail(small, tmp_path, monkeypatch):
    """The generator without settling and with the stretch [1.0, 1.6] fails both contact checks."""
    cfg, hand, robot, _ = small
    table = yaml.safe_load(syn.DEFAULT_PRIORS.read_text())
    for s in table["scenarios"].values():
        s["duration_scale"] = [1.0, 1.6]
    path = Path(tmp_path / "stretched.yaml")
    path.write_text(yaml.safe_dump(table))
    monkeypatch.setattr(syn, "settle_hands", lambda out, *a, **k: (out, 0))
    ds = instantiate(compose([*SMALL, f"data.priors={path}"]).data).load(hand, robot)
    p = _checks(cfg, robot, ds)
    assert p["penetration_p95_mm"] > 10.0 and not p["penetration_ok"]
    assert p["on_drawn_part_share"] < 0.9 and not p["on_drawn_part_ok"]
    assert not p["ok"]
    assert ds.truth["duration_scale"].max() > 1.2


def test_compliance_setting_bounds_penetration(small):
    cfg, hand, robot, _ = small
    ds = instantiate(compose([*SMALL, "data.compliance_mm=2", "data.scenarios=[S3_move_aside]"]).data).load(hand, robot)
    p = plausibility(ds, body_contacts(ds, robot, instantiate(cfg.contact)), robot, 2.0)
    assert p["penetration_max_mm"] <= 2.5 and p["penetration_ok"]


class _Sessions:
    """Five push sessions of ``n`` frames each (the whole session is the touch and the drawing hand's trial), the
    plan's contact phase ``plan`` frames in the middle, the right hand on link 0 in the middle for ``on``
    frames."""

    def __init__(self, n: int, on: int, plan: int):
        self.links = ("torso",)
        self.frame_rate_hz = 30.0
        self.sessions = pd.DataFrame({"start": np.arange(5) * n, "n_frames": n})
        first = (n - plan) // 2
        self.truth = pd.DataFrame(
            {
                "gesture": "push",
                "part": "torso_front_upper",
                "two_hands": False,
                "second_part": "",
                "touch_start_frame": 0,
                "touch_frames": n,
                "trial_frames": n,
                "plan_first_frame": first,
                "plan_last_frame": first + plan - 1,
            },
            index=range(5),
        )
        self.n_frames = 5 * n
        f = np.concatenate([s * n + (n - on) // 2 + np.arange(on) for s in range(5)])
        self.contacts = type(
            "C",
            (),
            dict(
                frame=f, hand=np.ones(f.size, np.int8), link=np.zeros(f.size, np.int16), depth_m=np.full(f.size, 0.002)
            ),
        )()

    def frame_session_index(self) -> np.ndarray:
        return np.repeat(np.arange(5), self.n_frames // 5)


class _Robot:
    parts = [type("P", (), dict(name="torso_front_upper", link="torso"))()]


@pytest.mark.parametrize(
    ("scale", "held", "ratio", "inside"),
    [(1.0, 1.0, 1.0, True), (1.0, 0.5, 0.5, False), (1.0, 0.3, 0.3, False), (1.6, 1.0, 1.0, False)],
)
def test_timing_is_paired_with_the_plan(scale, held, ratio, inside):
    """A push as long as the arm study's whose contact lasts exactly its planned phase is inside (paired ratio 1);
    contact cut short (half or a third of the plan) or the trial stretched 1.6x is outside."""
    trial_s, frac = arm_reference("push")
    n = int(round(trial_s * scale * 30))
    plan = int(round(frac * n))
    ds = _Sessions(n, int(round(held * plan)), plan)
    p = plausibility(ds, ds.contacts, _Robot(), 5.0)
    g = p["gestures"]["push"]
    assert g["judged"]
    assert g["contact_plan_ratio"] == pytest.approx(ratio, abs=0.02)
    assert g["duration_ratio"] == pytest.approx(scale, abs=0.02)
    assert g["inside"] is inside
    assert p["timing_ok"] is inside
    assert p["on_drawn_part_share"] == 1.0


def test_cost_calibration_is_reported_not_judged():
    """A contact fraction far from CoST's (3x the plan's length in contact would be, here the plan itself is
    3x CoST's) does not fail the check when contact holds for the plan: the CoST ratio is reported only."""
    trial_s, frac = arm_reference("push")
    n = int(round(trial_s * 30))
    plan = int(round(min(3 * frac, 0.95) * n))
    ds = _Sessions(n, plan, plan)
    g = plausibility(ds, ds.contacts, _Robot(), 5.0)["gestures"]["push"]
    assert g["contact_fraction_ratio"] > 2.0
    assert g["contact_plan_ratio"] == pytest.approx(1.0)
    assert g["inside"]
    lo, hi = g["cost_sampling_interval"]
    assert lo < 1.0 < hi


def test_cost_sampling_interval_widens_as_n_falls():
    widths = []
    for n in (3, 7, 20, 80):
        lo, hi = cost_sampling_interval("rub", n)
        assert lo < 1.0 < hi
        widths.append(hi - lo)
    assert widths == sorted(widths, reverse=True)
    assert widths[0] > 2 * widths[-1]
    assert cost_sampling_interval("rub", 7) == cost_sampling_interval("rub", 7)  # seeded


def test_generated_sessions_record_the_plan(small):
    """Version-5 sessions record the drawing hand's own trial and planned contact phase; the study-size block
    carries the paired and the CoST numbers."""
    cfg, _, robot, ds = small
    t = ds.truth
    assert (t["trial_frames"] <= t["touch_frames"]).all()
    assert ((0 <= t["plan_first_frame"]) & (t["plan_first_frame"] <= t["plan_last_frame"])).all()
    assert (t["plan_last_frame"] < t["trial_frames"]).all()
    g = _checks(cfg, robot, ds)["gestures"]
    assert g
    for v in g.values():
        assert {"duration_ratio", "contact_plan_ratio", "contact_fraction_ratio", "cost_sampling_interval"} <= set(v)
        assert v["contact_plan_ratio"] is None or v["contact_plan_ratio"] >= 0
        lo, hi = v["cost_sampling_interval"]
        assert lo < 1.0 < hi
    assert max(v["contact_plan_ratio"] or 0.0 for v in g.values()) > 0.5  # hands do hold contact


def test_duration_scale_is_optional_and_checked(small, tmp_path):
    _, _, robot, _ = small
    parts = [p.name for p in robot.parts]
    table = syn.load_priors(syn.DEFAULT_PRIORS, parts)
    assert all(s["duration_scale"] == [1.0, 1.0] for s in table["scenarios"].values())
    raw = yaml.safe_load(syn.DEFAULT_PRIORS.read_text())
    raw["scenarios"]["S1_attention"]["duration_scale"] = [1.5, 1.0]
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(raw))
    with pytest.raises(syn.PriorsError, match=r"S1_attention\.duration_scale=\[1\.5, 1\.0\] is invalid"):
        syn.load_priors(bad, parts)
