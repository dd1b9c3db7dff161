"""Whole-body contact (culled == exhaustive == the arm-only stage per link), episodes, placement."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hydra.utils import instantiate

from sphri.data.format import make_trials_frame
from sphri.sessions.contact import BodyContacts, body_contacts
from sphri.sessions.episodes import segment_episodes
from sphri.sessions.gestures import _to_link
from sphri.sessions.placement import greedy_parts, name_parts, placement_table, sentence
from sphri.types import GestureDataset


@pytest.fixture(scope="module")
def contacts(small):
    cfg, _, robot, ds = small
    return body_contacts(ds, robot, instantiate(cfg.contact))


def test_culling_changes_nothing_but_the_work(small, contacts):
    cfg, _, robot, ds = small
    full = body_contacts(ds, robot, instantiate(cfg.contact), cull=False, chunk_frames=777)
    for f in ("frame", "hand", "link", "capsule", "point_m", "normal", "depth_m"):
        assert np.array_equal(getattr(contacts, f), getattr(full, f)), f
    assert contacts.stats["tested"] < 0.25 * contacts.stats["triples"]
    assert full.stats["tested"] == full.stats["triples"]
    assert contacts.n_contacts > 0 and len(set(contacts.link.tolist())) >= 5


def test_matches_the_arm_only_stage_on_each_link(small, contacts):
    """The rows on one link equal ContactStage.compute on the hand poses moved into that link's frame."""
    cfg, _, robot, ds = small
    stage = instantiate(cfg.contact)
    li = int(np.bincount(contacts.link[contacts.hand == 1]).argmax())
    name = ds.links[li]
    rows = np.flatnonzero((contacts.link == li) & (contacts.hand == 1))
    frames = np.unique(contacts.frame[rows])
    a, b = int(frames[0]), int(frames[-1]) + 1
    poses = _to_link(ds.hand_poses[a:b, 1], ds.link_poses[a:b, li])
    gd = GestureDataset(
        "t",
        True,
        ds.hand,
        make_trials_frame(
            [
                dict(
                    participant="p",
                    region=name,
                    trial_ordinal=1,
                    trial_id="0001_hit",
                    gesture="hit",
                    start=0,
                    n_frames=b - a,
                )
            ]
        ),
        poses.astype(np.float32),
        30.0,
    )
    ref = stage.compute(gd, robot)
    sel = rows[(contacts.frame[rows] >= a) & (contacts.frame[rows] < b)]
    # rows decided exactly at the contact boundary may differ by rounding of the two transforms
    got = set(zip(contacts.frame[sel] - a, contacts.capsule[sel]))
    want = set(zip(ref.frame, ref.capsule))
    assert len(got ^ want) <= max(1, len(want) // 200)
    both = sorted(got & want)
    gi = {k: i for i, k in enumerate(zip(contacts.frame[sel] - a, contacts.capsule[sel]))}
    wi = {k: i for i, k in enumerate(zip(ref.frame, ref.capsule))}
    gp = contacts.point_m[sel][[gi[k] for k in both]]
    wp = ref.point_m[[wi[k] for k in both]]
    assert np.abs(gp - wp).max() < 1e-5


def _fake(frames, n_frames=400, hand=None):
    k = len(frames)
    z3 = np.zeros((k, 3))
    return BodyContacts(
        n_frames,
        ("a", "b"),
        np.asarray(frames, np.int64),
        np.asarray(hand if hand is not None else [1] * k, np.int8),
        np.zeros(k, np.int16),
        np.zeros(k, np.int16),
        z3,
        z3 + [0, 0, 1],
        np.full(k, 0.01),
        np.full(k, 0.001),
    )


class _DS:
    frame_rate_hz = 10.0

    def __init__(self, n):
        self.sessions = pd.DataFrame(
            {
                "participant": ["p1", "p1"],
                "scenario": ["S1", "S2"],
                "repetition": [1, 1],
                "order": [0, 1],
                "start_position": ["front"] * 2,
                "start": [0, n // 2],
                "n_frames": [n // 2, n // 2],
            }
        )
        self.n = n

    @property
    def n_frames(self):
        return self.n

    def frame_session_index(self):
        return np.repeat([0, 1], self.n // 2)


def test_episodes_end_after_the_gap():
    # 10 Hz, gap 2 s = 20 frames: frames 10-14, then 30-33 (15 empty frames: same episode), then 60-61 (26: new one)
    fr = [10, 11, 12, 13, 14, 30, 31, 32, 33, 60, 61, 250]
    bc = _fake(fr)
    eps = segment_episodes(_DS(400), bc, np.array(["x"] * len(fr), dtype=object), gap_s=2.0, min_frames=3)
    s0 = eps[eps["session"] == 0]
    assert s0[["start_frame", "end_frame"]].values.tolist() == [[10, 33], [60, 61]]
    assert s0["coded"].tolist() == [True, False]
    s1 = eps[eps["session"] == 1]
    assert s1["start_frame"].tolist() == [250] and not s1["coded"].any()  # 1 contact frame < min_frames
    shorter = segment_episodes(_DS(400), bc, np.array(["x"] * len(fr), dtype=object), gap_s=1.0, min_frames=1)
    assert len(shorter[shorter["session"] == 0]) == 3


def test_greedy_placement_and_its_sentence():
    # frames x parts: part 0 cheap and hit often, part 1 expensive, part 2 hit by the rest
    m = np.array([[1, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1]], dtype=bool)
    area = np.array([0.01, 0.05, 0.02])
    assert greedy_parts(m, area, 0.03) == [0, 2]
    assert greedy_parts(m, area, 1.0) == [0, 2, 1]
    unit = np.array(["a", "a", "b", "b", "b"])
    tab = placement_table(m, np.array(["S"] * 5), unit, ["S"], ["shoulder_l", "torso", "shoulder_r"], area, 0.03)
    row = tab.iloc[0]
    assert row["parts"] == "shoulder_l;shoulder_r" and row["captured"] == pytest.approx(0.8)
    assert row["n_heldout_units"] == 2
    groups = {"shoulders": ("shoulder_l", "shoulder_r")}
    assert name_parts(["shoulder_l", "gripper_r", "shoulder_r"], groups) == ["shoulders", "gripper r"]
    text = sentence(row, groups)
    assert text.startswith(
        "[all] covering the shoulders (300 cm^2, 38 % of the reachable surface) captures 80 % of contact frames"
    )
