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
from sphri.sessions.plausibility import arm_reference, plausibility
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
    """Five push sessions of ``n`` frames each, the right hand on link 0 in the middle for ``on`` frames."""

    def __init__(self, n: int, on: int):
        self.links = ("torso",)
        self.frame_rate_hz = 30.0
        self.sessions = pd.DataFrame({"start": np.arange(5) * n, "n_frames": n})
        self.truth = pd.DataFrame(
            {
                "gesture": "push",
                "part": "torso_front_upper",
                "two_hands": False,
                "second_part": "",
                "touch_start_frame": 0,
                "touch_frames": n,
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


@pytest.mark.parametrize(("scale", "fill", "inside"), [(1.0, 1.0, True), (1.6, 1.0, False), (1.0, 3.0, False)])
def test_timing_band(scale, fill, inside):
    """A push as long as the arm study's with its contact fraction is inside; stretched 1.6x, or in contact
    3x as long (rub's signature), it is outside."""
    trial_s, frac = arm_reference("push")
    n = int(round(trial_s * scale * 30))
    on = int(round(min(frac * fill, 0.95) * n))
    ds = _Sessions(n, on)
    p = plausibility(ds, ds.contacts, _Robot(), 5.0)
    assert p["gestures"]["push"]["judged"]
    assert p["gestures"]["push"]["inside"] is inside
    assert p["timing_ok"] is inside
    assert p["on_drawn_part_share"] == 1.0


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
