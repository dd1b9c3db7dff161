"""``sphri check-data DIR``: gesture-trial and session folders against the recording format, every problem a line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from sphri.command import main


@pytest.fixture(scope="module")
def two(hand, robot):
    """Two participants' 8 gestures on the arm from sphri's synthetic generator."""
    from sphri.data.synthetic import SyntheticData

    return SyntheticData(seed=11, participants=2, repetitions=1, regions=["arm"]).load(hand=hand, robot=robot)


@pytest.fixture()
def gestures(two, robot, tmp_path) -> Path:
    from sphri.data.writer import write_dataset

    root = tmp_path / "gestures"
    write_dataset(two, robot, root)
    return root


def check(root: Path, capsys) -> tuple[int, list[str], str]:
    code = main(["check-data", str(root)])
    cap = capsys.readouterr()
    return code, cap.out.strip().splitlines(), cap.err


def test_a_good_gesture_folder_is_summarized(gestures, two, capsys):
    code, out, _ = check(gestures, capsys)
    assert code == 0, out
    assert out == [
        f"{gestures}: gesture trials, format version(s) [2]: 1 region(s) ['arm'], 2 participant(s), "
        f"{len(two.trials)} trials, {two.n_frames} frames at 30 Hz, 19 capsules"
    ]


def test_every_problem_of_a_gesture_folder_is_its_own_line(gestures, capsys):
    p1 = gestures / "arm" / "participant_01" / "participant_01.parquet"
    t = pq.read_table(p1)
    t = t.set_column(t.schema.get_field_index("frame"), "frame", t["frame"].cast(pa.float64()))
    t = t.drop_columns(["index3_rot_w"])
    pq.write_table(t, p1)
    m2 = gestures / "arm" / "participant_02" / "participant_02_manifest.json"
    m = json.loads(m2.read_text())
    m["num_trials"] += 1
    m2.write_text(json.dumps(m))
    code, out, err = check(gestures, capsys)
    assert code == 2
    assert out == [
        f"{p1}: missing column(s) ['index3_rot_w']",
        f"{p1}: column frame has type double, expected integers",
        f"{m2}: num_trials=9 but 8 trials are listed",
    ]
    assert err.strip() == f"sphri check-data: 3 problem(s) in {gestures}"


def test_rows_problems_name_file_trial_and_column(gestures, capsys):
    p2 = gestures / "arm" / "participant_02" / "participant_02.parquet"
    df = pd.read_parquet(p2)
    df.loc[df["trial_ordinal"] == 3, "gesture_label"] = "wave"
    df.to_parquet(p2, index=False)
    code, out, _ = check(gestures, capsys)
    assert code == 2
    assert out == [f"{p2}: trial 3: column gesture_label='wave' is not a known gesture {list_gestures()}"]


def list_gestures() -> str:
    from sphri.types import GESTURES

    return f"({list(GESTURES)})"


def test_an_imported_dataset_checks(rig_poses, hand, tmp_path, capsys):
    from sphri.recordings.capsules import export_openxr

    log = export_openxr(rig_poses, hand, np.arange(len(rig_poses)) / 30.0, tmp_path / "hand.csv")
    out = tmp_path / "ds"
    assert main(["import", "openxr", str(log), f"out={out}", "link=arm", "participant=4", "gesture=rub"]) == 0
    capsys.readouterr()
    code, lines, _ = check(out, capsys)
    assert code == 0 and "1 participant(s), 1 trials, 40 frames at 30 Hz" in lines[0]


@pytest.fixture()
def sessions(hand, tmp_path) -> Path:
    """Two participants, one scenario each, 12 frames of both hands and two links (world frame)."""
    from sphri.sessions.format import SessionDataset, make_sessions_frame, write_sessions

    rng = np.random.default_rng(2)
    n, c = 12, hand.n_capsules
    hp = np.zeros((2 * n, 2, c, 7), np.float32)
    hp[..., :3] = rng.normal(0.4, 0.05, (2 * n, 2, c, 3))
    hp[..., 6] = 1.0
    lp = np.zeros((2 * n, 2, 7), np.float32)
    lp[..., 6] = 1.0
    rows = [
        dict(participant=p, scenario="greet", repetition=1, order=0, start_position="front", start=i * n, n_frames=n)
        for i, p in enumerate(("participant_01", "participant_02"))
    ]
    ds = SessionDataset("toy", False, hand, make_sessions_frame(rows), hp, ("torso", "l_arm"), lp, 30.0, "reachy")
    root = tmp_path / "sessions"
    write_sessions(ds, root)
    return root


def test_sessions_folder_checks_and_names_each_broken_file(sessions, capsys):
    code, out, _ = check(sessions, capsys)
    assert code == 0
    assert out == [
        f"{sessions}: sessions, sphri-sessions version 1: 2 participant(s), 2 sessions, 24 frames at 30 Hz, "
        "2 link(s), hands ['left', 'right']"
    ]
    m1 = sessions / "participant_01" / "manifest.json"
    m = json.loads(m1.read_text())
    m["sessions"][0]["n_frames"] = 13
    m1.write_text(json.dumps(m))
    p2 = sessions / "participant_02" / "greet.parquet"
    df = pd.read_parquet(p2)
    df.loc[4, "right/index2_pos_y"] = np.nan
    df.to_parquet(p2, index=False)
    code, out, _ = check(sessions, capsys)
    assert code == 2
    assert out == [
        f"{sessions / 'participant_01' / 'greet.parquet'}: repetition 1 has 12 rows but {m1} field n_frames says 13",
        f"{p2}: repetition 1, frame 4: column 'right/index2_pos_y' is NaN/inf (1 values)",
    ]


def test_a_folder_of_neither_kind(tmp_path, capsys):
    assert check(tmp_path / "nowhere", capsys)[:2] == (2, [f"{tmp_path / 'nowhere'}: no such folder"])
    (tmp_path / "x").mkdir()
    code, out, _ = check(tmp_path / "x", capsys)
    assert code == 2 and len(out) == 1 and "not a recording folder (docs/RECORDING_FORMAT.md)" in out[0]
    shutil.rmtree(tmp_path / "x")
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "sessions.json").write_text('{"format": "sphri-sessions", "version": 7}')
    code, out, _ = check(tmp_path / "x", capsys)
    assert code == 2 and out == [
        f"{tmp_path / 'x' / 'sessions.json'}: missing field(s) ['name', 'synthetic', 'robot', 'links', 'hands', 'hand']"
    ]


def test_a_copied_participant_is_a_problem_as_the_loader_refuses_it(gestures, capsys):
    src, dst = gestures / "arm" / "participant_01", gestures / "arm" / "participant_03"
    dst.mkdir()
    shutil.copy(src / "participant_01.parquet", dst / "participant_03.parquet")
    m = json.loads((src / "participant_01_manifest.json").read_text())
    m["participant_id"] = "participant_03"
    (dst / "participant_03_manifest.json").write_text(json.dumps(m))
    code, out, _ = check(gestures, capsys)
    assert code == 2
    assert len(out) == 1 and out[0].startswith(
        f"{gestures}: participant_01 and participant_03 hold near-identical recordings (8 of 8 trials match"
    ), out
