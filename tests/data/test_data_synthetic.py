"""The synthetic generator: schema, determinism, motion realism, per-gesture sanity, calibration."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from sphri.data.handfk import HandRig, matrix_to_quat, rotvec_to_matrix
from sphri.data.stats import calibration_checks, gesture_summary, trial_statistics
from sphri.data.synthetic import SyntheticData, inverse_smoothstep, smoothstep
from sphri.hand.kinematics import capsule_segments, quat_to_matrix
from sphri.types import GESTURES, TRIAL_COLUMNS, Link, Robot


def gen(hand, robot, **kw):
    return SyntheticData(**kw).load(hand=hand, robot=robot)


def test_schema(small, hand):
    assert small.name == "synthetic" and small.synthetic and small.frame_rate_hz == 30.0
    assert small.poses.dtype == np.float32 and small.poses.shape[1:] == (hand.n_capsules, 7)
    assert tuple(small.trials.columns) == TRIAL_COLUMNS
    t = small.trials
    assert len(t) == 3 * 2 * 8 * 2
    assert (t["start"].to_numpy() == np.r_[0, np.cumsum(t["n_frames"])[:-1]]).all()
    assert t["n_frames"].sum() == small.n_frames
    assert sorted(t["participant"].unique()) == ["participant_01", "participant_02", "participant_03"]
    for (_, _), g in t.groupby(["participant", "region"]):
        assert g["trial_ordinal"].tolist() == list(range(1, 17))
        assert (g["trial_id"] == [f"{o:04d}_{x}" for o, x in zip(g["trial_ordinal"], g["gesture"])]).all()
        assert (g["gesture"].value_counts() == 2).all() and set(g["gesture"]) == set(GESTURES)
    assert np.isfinite(small.poses).all()
    q = small.poses[..., 3:].astype(np.float64)
    assert np.allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-6)


def test_deterministic_and_seeded(hand, robot):
    a = gen(hand, robot, seed=3, participants=2, repetitions=1)
    b = gen(hand, robot, seed=3, participants=2, repetitions=1)
    c = gen(hand, robot, seed=4, participants=2, repetitions=1)
    assert np.array_equal(a.poses, b.poses) and a.trials.equals(b.trials)
    assert a.poses.shape != c.poses.shape or not np.array_equal(a.poses, c.poses)


def test_streams_per_participant_and_region(hand, robot, small):
    arm = gen(hand, robot, seed=7, participants=3, repetitions=2, regions=["arm"])
    sub = small.trials[small.trials.region == "arm"]
    assert arm.trials.drop(columns="start").equals(sub.drop(columns="start").reset_index(drop=True))
    ref = np.concatenate([small.poses[r.start : r.start + r.n_frames] for r in sub.itertuples()])
    assert np.array_equal(arm.poses, ref)
    two = gen(hand, robot, seed=7, participants=2, repetitions=2, regions=["arm"])
    n = int(two.trials.n_frames.sum())
    assert np.array_equal(two.poses, arm.poses[:n])


def _end_gaps(ds, robot, region, hand_query):
    """Distance (m) of the hand from the link in the first and last frame of every trial of ``region``."""
    t = ds.trials[ds.trials.region == region]
    ends = np.r_[t["start"].to_numpy(), (t["start"] + t["n_frames"] - 1).to_numpy()]
    q = hand_query(ds, robot.link_for(region), ends, margin=0.5)
    return (q.distance - np.tile(ds.hand.radius_m, len(ends))).reshape(len(ends), -1).min(axis=1)


def test_trials_start_and_end_at_rest_away_from_the_link(small, robot, hand, hand_query):
    # by default a few trials are mis-timed (started late, ended early): most still start and end at rest
    for region in ("arm", "torso"):
        assert (_end_gaps(small, robot, region, hand_query) > 0.08).mean() >= 0.9
    exact = gen(hand, robot, seed=7, participants=2, repetitions=2, boundary_early_rate=0.0, boundary_late_rate=0.0)
    gap = _end_gaps(exact, robot, "arm", hand_query)
    assert (gap > 0.08).all(), gap.min()


def test_tracking_holds_poses_and_jitters(small):
    same = np.all(small.poses[1:] == small.poses[:-1], axis=(1, 2))
    owner = small.frame_trial_index()
    same = same[owner[1:] == owner[:-1]]
    assert 0.02 < same.mean() < 0.4  # some frames hold the last tracking sample, most move


def test_hand_size_varies_per_participant(small, hand):
    c1, c2 = hand.names.index("middle1"), hand.names.index("middle2")
    length = {}
    for pid, g in small.trials.groupby("participant"):
        r = g.iloc[0]
        pos = small.poses[r.start : r.start + r.n_frames, :, :3].astype(np.float64)
        length[pid] = np.median(np.linalg.norm(pos[:, c2] - pos[:, c1], axis=1))
    nominal = hand.segment_length_m[c1]
    ratios = np.array(list(length.values())) / nominal
    assert ((ratios > 0.75) & (ratios < 1.25)).all() and np.ptp(ratios) > 0.005


def test_per_gesture_sanity(small, small_contacts, robot):
    stats = trial_statistics(small, small_contacts, robot)
    assert stats["contact"].mean() > 0.95
    names = np.array(small.hand.names)
    fingers = np.array(small.hand.fingers)
    owner = small.frame_trial_index()[small_contacts.frame]
    g_of = small.trials["gesture"].to_numpy()[owner]
    # poke: the index fingertip does most of the touching
    poke = small_contacts.capsule[g_of == "poke"]
    assert np.mean(np.isin(names[poke], ["index3", "index2"])) > 0.8 and np.mean(names[poke] == "index3") > 0.5
    # grab: thumb and fingers both touch in (nearly) every trial
    grab = np.flatnonzero(small.trials["gesture"] == "grab")
    parts = [set(fingers[small_contacts.capsule[owner == t]]) for t in grab]
    both = [("thumb" in p) and bool(p & {"index", "middle", "ring", "pinky"}) for p in parts]
    assert np.mean(both) >= 0.9


def test_calibration_holds_at_small_size(hand, robot, contacts_of):
    # the centre (median length, mean duration) is calibrated at any variability; at the calibrated
    # variability 6 participants are too few to pin medians within 20 % (the full-size check is in the README)
    ds = gen(hand, robot, seed=0, participants=6, repetitions=4, variability=0.25)
    stats = trial_statistics(ds, contacts_of(ds, robot), robot)
    # durations follow CoST's ordering over participants (one participant's ordering may differ: styles)
    dur = stats[stats.contact].groupby("gesture")["duration_s"].mean()
    assert dur.idxmax() == "rub" and dur.idxmin() == "hit"
    assert dur["grab"] > dur["pat"] and dur["push"] > dur["tap"] and dur["stroke"] > dur["poke"]
    summary = gesture_summary(stats)
    checks = calibration_checks(summary)
    failed = [(n, d) for n, ok, d in checks if not ok]
    assert len(checks) == 8 * 2 + 2 and not failed, failed


def test_any_link_shape(hand, contacts_of):
    m = trimesh.creation.capsule(height=0.3, radius=0.05, count=[24, 24])
    link = Link(name="bar", vertices=np.asarray(m.vertices), faces=np.asarray(m.faces, dtype=np.int64), watertight=True)
    box = trimesh.creation.box(extents=[0.4, 0.3, 0.2])
    slab = Link(
        name="slab", vertices=np.asarray(box.vertices), faces=np.asarray(box.faces, dtype=np.int64), watertight=True
    )
    robot = Robot(name="toy", links={"bar": link, "slab": slab}, regions={"arm": "bar", "chest": "slab"})
    ds = gen(hand, robot, participants=1, repetitions=1, regions=["arm", "chest"])
    stats = trial_statistics(ds, contacts_of(ds, robot), robot)
    assert stats["contact"].mean() > 0.9


def test_unknown_region_or_hand_fail_clearly(hand, robot):
    with pytest.raises(KeyError, match="no skin region 'leg'"):
        gen(hand, robot, participants=1, repetitions=1, regions=["leg"])
    from dataclasses import replace

    small_hand = replace(hand, names=hand.names[:-1] + ("little3",))
    with pytest.raises(ValueError, match=r"lacks \['pinky3'\]"):
        HandRig.from_hand(small_hand)
    with pytest.raises(ValueError, match="only read by data=vr_gesture"):
        SyntheticData(root="/x")


# -------------------------------------------------------------- kinematics
@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3))
def test_rotvec_and_quaternion_round_trip(w):
    r = rotvec_to_matrix(np.array(w))
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(r), 1.0)
    q = matrix_to_quat(r)
    assert q[3] >= 0 and np.allclose(quat_to_matrix(q), r, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-0.3, 1.6), min_size=20, max_size=20), st.floats(0.9, 1.1))
def test_fk_capsules_follow_the_hand_model(angles, scale):
    hand = _hand()
    rig = HandRig.from_hand(hand)
    fingers = np.array(angles).reshape(1, 5, 4)
    rot = rotvec_to_matrix(np.array([0.3, -0.2, 1.0]))[None]
    poses = rig.poses(fingers, rot, np.array([[0.1, -0.2, 0.3]]), scale)
    p0, p1 = capsule_segments(poses, hand)
    assert np.allclose(np.linalg.norm(p1 - p0, axis=-1)[0], hand.segment_length_m, atol=1e-9)
    # consecutive finger capsules are centred on consecutive bones: the joint between them is shared
    for chain in ("thumb", "index", "middle", "ring", "pinky"):
        i1, i2 = hand.names.index(f"{chain}1"), hand.names.index(f"{chain}2")
        end1 = p1[0, i1] + (scale - 1) * 0.5 * hand.segment_length_m[i1] * _unit(p1[0, i1] - p0[0, i1])
        start2 = p0[0, i2] - (scale - 1) * 0.5 * hand.segment_length_m[i2] * _unit(p1[0, i2] - p0[0, i2])
        assert np.allclose(end1, start2, atol=1e-9)


_HAND: dict = {}


def _hand():
    if "hand" not in _HAND:
        from omegaconf import OmegaConf

        from sphri.config import CONF_DIR
        from sphri.hand.capsules import HandCapsules

        cfg = OmegaConf.load(CONF_DIR / "hand" / "quest_capsules.yaml")
        _HAND["hand"] = HandCapsules(capsules=cfg.capsules).build()
    return _HAND["hand"]


def _unit(v):
    return v / np.linalg.norm(v)


def test_smoothstep_inverse():
    y = np.linspace(0, 1, 11)
    assert np.allclose(smoothstep(np.array([inverse_smoothstep(v) for v in y])), y, atol=1e-5)


def test_scaled_hand_model(robot, contacts_of):
    from omegaconf import OmegaConf

    from sphri.config import CONF_DIR
    from sphri.hand.capsules import HandCapsules

    cfg = OmegaConf.load(CONF_DIR / "hand" / "quest_capsules.yaml")
    big = HandCapsules(capsules=cfg.capsules, scale=1.3).build()
    assert np.isclose(HandRig.from_hand(big).palm_scale, 1.3)
    ds = gen(big, robot, participants=1, repetitions=1)
    stats = trial_statistics(ds, contacts_of(ds, robot), robot)
    assert stats["contact"].all()


@settings(max_examples=50, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=40), st.sets(st.integers(0, 39), max_size=5))
def test_hold_last_valid(bad_list, cuts):
    from sphri.data.repair import hold_last_valid

    n = len(bad_list)
    bad = np.array(bad_list)[:, None]
    values = np.arange(n, dtype=float)[:, None, None] * np.ones((1, 1, 2))
    starts = np.array(sorted({0} | {c for c in cuts if c < n}))
    out, orphan = hold_last_valid(values, bad, starts)
    seg = np.searchsorted(starts, np.arange(n), side="right") - 1
    for i in range(n):
        same = np.flatnonzero((seg == seg[i]) & ~bad[:, 0])
        if not bad[i, 0]:
            assert out[i, 0, 0] == i and not orphan[i, 0]
        elif same.size == 0:
            assert orphan[i, 0] and out[i, 0, 0] == i
        else:
            prev = same[same < i]
            want = prev[-1] if prev.size else same[same > i][0]
            assert out[i, 0, 0] == want and not orphan[i, 0]
