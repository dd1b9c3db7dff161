"""The session format: written by the synthesizer, read back identically; broken files give named errors."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from hydra.utils import instantiate

from sphri.command import main as sphri_main
from sphri.config import ConfigError, compose
from sphri.sessions.contact import body_contacts
from sphri.sessions.episodes import part_of_rows, segment_episodes
from sphri.sessions.format import SessionData


def test_synthesizer_command_writes_sessions_that_load_back_identically(small, tmp_path):
    cfg, hand, robot, ds = small
    assert (
        sphri_main(["synthesize", "what=sessions", f"out={tmp_path}", "data.participants=2", "data.repetitions=1"]) == 0
    )
    loaded = instantiate(compose(["data=sessions", f"data.root={tmp_path}", "robot=reachy_full"]).data).load(
        hand, robot
    )
    assert loaded.synthetic and loaded.name == ds.name and loaded.links == ds.links
    pd.testing.assert_frame_equal(loaded.sessions, ds.sessions)
    assert np.array_equal(loaded.hand_poses, ds.hand_poses) and np.array_equal(loaded.link_poses, ds.link_poses)
    contact = instantiate(cfg.contact)
    a, b = body_contacts(ds, robot, contact), body_contacts(loaded, robot, contact)
    for f in ("frame", "hand", "link", "capsule", "point_m", "depth_m"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    ea = segment_episodes(ds, a, part_of_rows(a, robot))
    eb = segment_episodes(loaded, b, part_of_rows(b, robot))
    pd.testing.assert_frame_equal(ea, eb)
    # most sessions have an episode: a hand whose drawn spot other links block is moved clear of them and ends
    # with no contact (sessions v6: 23 of the full study's 180 sessions, 3 of these 10)
    assert len(ea) >= 0.6 * len(ds.sessions)


def test_loader_selects_participants_scenarios_and_repetitions(small, written):
    _, hand, robot, ds = small
    one = SessionData(root=str(written), participants=1, scenarios=["S1_attention", "S5_appreciation"]).load(
        hand, robot
    )
    assert list(one.sessions["participant"].unique()) == ["participant_01"]
    assert sorted(one.sessions["scenario"]) == ["S1_attention", "S5_appreciation"]


def test_broken_files_give_named_errors(copy_written, load_refused):
    root = copy_written("a")
    h = json.loads((root / "sessions.json").read_text())
    h["format"] = "something"
    (root / "sessions.json").write_text(json.dumps(h))
    load_refused(root, r"sessions.json: field 'format'")

    root = copy_written("b")
    m = json.loads((root / "participant_01" / "manifest.json").read_text())
    m["sessions"][0]["n_frames"] += 5
    (root / "participant_01" / "manifest.json").write_text(json.dumps(m))
    load_refused(root, r"participant_01/S\w+\.parquet: repetition 1 has \d+ rows but .*n_frames")

    root = copy_written("c")
    m = json.loads((root / "participant_02" / "manifest.json").read_text())
    del m["sessions"][1]["start_position"]
    (root / "participant_02" / "manifest.json").write_text(json.dumps(m))
    load_refused(root, r"manifest.json: sessions\[1\] is missing field\(s\) \['start_position'\]")

    root = copy_written("d")
    path = root / "participant_01" / "S3_move_aside.parquet"
    df = pd.read_parquet(path)
    df.loc[7, "right/index1_pos_x"] = np.nan
    df.drop(columns=["link/head_rot_w"]).to_parquet(path)
    load_refused(root, r"S3_move_aside.parquet: missing column\(s\) \['link/head_rot_w'\]")
    df.to_parquet(path)
    load_refused(root, r"S3_move_aside.parquet: repetition 1, frame 7: column 'right/index1_pos_x' is NaN")
    df = pd.read_parquet(path).fillna(0.0)
    df.loc[3, "link/torso_rot_w"] = 3.0
    df.to_parquet(path)
    load_refused(root, r"frame 3: link quaternion link/torso_rot_\* has norm")

    root = copy_written("e")
    (root / "participant_02" / "S1_attention.parquet").write_bytes(b"not parquet")
    load_refused(root, r"S1_attention.parquet: not a readable parquet file")

    with pytest.raises(ConfigError, match=r"data.root=None is invalid"):
        compose(["data=sessions"])


def test_bad_priors_are_named(small, tmp_path):
    from sphri.sessions.synthetic import PriorsError, SyntheticSessions

    _, hand, robot, _ = small
    text = SyntheticSessions().priors and open(SyntheticSessions().priors).read()
    bad = tmp_path / "p.yaml"
    bad.write_text(text.replace("shoulder_near: 5", "elbow_near: 5"))
    with pytest.raises(PriorsError, match=r"p.yaml: scenarios.S1_attention.parts.elbow_near: no such body part"):
        SyntheticSessions(participants=1, repetitions=1, priors=str(bad)).load(hand, robot)
    bad.write_text(text.replace("gestures: {tap: 6", "gestures: {tickle: 6"))
    with pytest.raises(PriorsError, match=r"scenarios.S1_attention.gestures.tickle: unknown gesture"):
        SyntheticSessions(participants=1, repetitions=1, priors=str(bad)).load(hand, robot)
    from sphri.sessions.synthetic import DEFAULT_PRIORS, load_priors

    parts = [p.name for p in robot.parts]
    with pytest.raises(PriorsError, match=r"scenarios\.\w+\.robot_motion=arm moves the joints \['l_shoulder_pitch'"):
        load_priors(DEFAULT_PRIORS, parts, ["neck", "l_shoulder"])
    assert load_priors(DEFAULT_PRIORS, parts, list(robot.tree.joint_names))["scenarios"]


def test_synthetic_sessions_follow_the_study_design(small):
    _, _, robot, ds = small
    s = ds.sessions
    assert len(s) == 2 * 5 and s.groupby("participant")["scenario"].nunique().eq(5).all()
    # cyclic Latin square: participants start with different scenarios
    first = s[s["order"] == 0].set_index("participant")["scenario"]
    assert first["participant_01"] != first["participant_02"]
    # S2: the base drives (its pose changes during the session); S3: it stands still
    base = ds.links.index("base")
    for scen, moves in (("S2_path_redirection", True), ("S3_move_aside", False)):
        r = s[s["scenario"] == scen].iloc[0]
        lp = ds.link_poses[r.start : r.start + r.n_frames, base, :3]
        assert (np.ptp(lp, axis=0).max() > 0.05) == moves
    assert set(ds.truth["part"]) <= {p.name for p in robot.parts}


def test_positions_in_millimetres_are_refused_and_links_without_poses_named(small, copy_written, load_refused, caplog):
    _, hand, robot, _ = small
    root = copy_written("mm")
    path = root / "participant_02" / "S4_behaviour_correction.parquet"
    df = pd.read_parquet(path)
    pos = [c for c in df.columns if c.endswith(("_pos_x", "_pos_y", "_pos_z"))]
    df[pos] = df[pos] * 1000.0
    df.to_parquet(path)
    load_refused(
        root,
        r"S4_behaviour_correction.parquet: repetition 1: hand positions lie "
        r"[\d.]+ from the origin .*millimetres or centimetres",
    )
    # a robot link the sessions never pose: named in a warning (no contact can be found on it)
    root = copy_written("nolink")
    h = json.loads((root / "sessions.json").read_text())
    h["links"] = [ln for ln in h["links"] if ln != "neck"]
    (root / "sessions.json").write_text(json.dumps(h))
    for pq in root.glob("participant_*/*.parquet"):
        d = pd.read_parquet(pq)
        d.drop(columns=[c for c in d.columns if c.startswith("link/neck_")]).to_parquet(pq)
    with caplog.at_level("WARNING", logger="sphri.sessions.format"):
        ds = SessionData(root=str(root)).load(hand, robot)
    assert "neck" not in ds.links
    assert any("['neck'] have no poses" in r.getMessage() for r in caplog.records)
