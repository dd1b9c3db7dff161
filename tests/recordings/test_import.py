"""``sphri import``: OpenXR joint, OVR capsule and generic capsule logs -> gesture trials, and every refusal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from sphri.command import main
from sphri.data.format import read_manifest
from sphri.data.recording_schema import OPENXR_CAPSULES, OVR_BONES
from sphri.data.vr_gesture import VRGestureData
from sphri.hand.capsules import HandCapsules
from sphri.hand.kinematics import capsule_segments
from sphri.recordings.capsules import export_openxr

JOINTS = 26


def run_import(kind: str, log: Path, out: Path, *extra: str) -> int:
    return main(["import", kind, str(log), f"out={out}", "link=arm", "participant=1", "gesture=tap", *extra])


def load(out: Path, region: str = "arm"):
    hand = HandCapsules(definition_path=str(out / "assets" / "hand_capsule_definition.json")).build()
    return VRGestureData(root=str(out), regions=[region], min_frames=1).load(hand)


def segments(poses, hand):
    p0, p1 = capsule_segments(np.asarray(poses, np.float64), hand)
    return np.concatenate([p0, p1], axis=-1)


@pytest.fixture()
def openxr_log(rig_poses, hand, tmp_path):
    return export_openxr(rig_poses, hand, np.arange(len(rig_poses)) / 30.0, tmp_path / "hand.csv")


def test_openxr_round_trip_gives_the_same_capsule_segments(rig_poses, hand, openxr_log, tmp_path, capsys):
    out = tmp_path / "ds"
    assert run_import("openxr", openxr_log, out) == 0
    text = capsys.readouterr().out
    assert "as trial 0001_tap of participant_01 on arm" in text
    assert "40 source frames (median 30 Hz) resampled to 40 frames at 30 Hz" in text
    ds = load(out)
    assert ds.n_frames == 40 and ds.frame_rate_hz == 30.0
    err = np.abs(segments(ds.poses, ds.hand) - segments(rig_poses, hand)).max()
    assert err < 2e-6, err  # float32 on disk
    np.testing.assert_allclose(ds.hand.radius_m, hand.radius_m, rtol=1e-6)
    # a second log is the participant's next trial, with the next frame numbers
    assert run_import("openxr", openxr_log, out, "gesture=stroke") == 0
    m = read_manifest(out / "arm" / "participant_01" / "participant_01_manifest.json")
    assert [t["trial_id"] for t in m["trials"]] == ["0001_tap", "0002_stroke"]
    assert m["trials"][1]["start_frame"] == 41 and m["format_version"] == 2
    assert m["trials"][0]["source"]["kind"] == "openxr" and m["trials"][0]["source"]["frames"] == 40


def test_joint_ids_read_as_their_names(openxr_log, tmp_path):
    from sphri.data.recording_schema import OPENXR_JOINTS

    lines = _lines(openxr_log)
    for i in range(1, len(lines)):
        cells = lines[i].split(",")
        cells[2] = str(OPENXR_JOINTS.index(cells[2]))
        lines[i] = ",".join(cells)
    ids = tmp_path / "ids.csv"
    ids.write_text("\n".join(lines) + "\n")
    assert run_import("openxr", openxr_log, tmp_path / "a") == 0
    assert run_import("openxr", ids, tmp_path / "b") == 0
    np.testing.assert_array_equal(load(tmp_path / "a").poses, load(tmp_path / "b").poses)
    bom = tmp_path / "bom.csv"  # as spreadsheet programs save CSV
    bom.write_text("\ufeff" + openxr_log.read_text())
    assert run_import("openxr", bom, tmp_path / "c") == 0


def test_hand_size_scales_the_documented_capsules(openxr_log, hand, tmp_path):
    out = tmp_path / "ds"
    assert run_import("openxr", openxr_log, out, "hand_size=1.2") == 0
    np.testing.assert_allclose(load(out).hand.radius_m, 1.2 * hand.radius_m, rtol=1e-6)


def test_resampling_reports_gaps_and_downsampling(rig_poses, hand, tmp_path, capsys):
    keep = np.r_[0:10, 14:40]  # 90 Hz with a tracking gap from 0.1 s to 0.156 s
    log = export_openxr(rig_poses[keep], hand, keep / 90.0, tmp_path / "fast.csv")
    out = tmp_path / "ds"
    assert run_import("openxr", log, out, "rate_hz=30") == 0
    text = capsys.readouterr().out
    assert (
        "36 source frames (median 90 Hz) resampled to 14 frames at 30 Hz: 1 frame(s) interpolated across "
        "1 tracking gap(s), 22 source frame(s) dropped by downsampling"
    ) in text
    ds = load(out)
    assert ds.n_frames == 14
    got, want = segments(ds.poses, ds.hand), segments(rig_poses, hand)
    for k, src in ((0, 0), (3, 9), (5, 15), (13, 39)):  # output frame k at k / 30 s is source frame 3k
        assert np.abs(got[k] - want[src]).max() < 2e-6, k
    # frame 4 (0.133 s) lies in the gap: between its neighbours, not equal to either
    mid = got[4]
    assert np.abs(mid - want[9]).max() > 1e-4 and np.abs(mid - want[14]).max() > 1e-4


def _ovr_rows(poses, hand, start=0.0):
    p0, p1 = capsule_segments(poses, hand)
    index = {n: i for i, n in enumerate(hand.names)}
    bones = {v: k for k, v in OVR_BONES.items()}
    rows = ["time,hand,capsule_index,bone_id,start_x,start_y,start_z,end_x,end_y,end_z,radius"]
    for f in range(len(poses)):
        for k, name in enumerate(OPENXR_CAPSULES):
            bone = "Hand_WristRoot" if name.startswith("wrist") else bones[name]
            c = index[name]
            vals = [*p0[f, c], *p1[f, c], hand.radius_m[c]]
            rows.append(f"{start + f / 30.0!r},right,{k},{bone}," + ",".join(f"{v:.9g}" for v in vals))
    return rows


def test_ovr_and_capsule_logs_keep_their_segments_and_sizes(rig_poses, hand, tmp_path):
    scaled = hand.__class__(**{**hand.__dict__, "radius_m": hand.radius_m * 0.9})
    log = tmp_path / "ovr.csv"
    log.write_text("\n".join(_ovr_rows(rig_poses, scaled)) + "\n")
    out = tmp_path / "ovr"
    assert run_import("ovr", log, out) == 0
    ds = load(out)
    np.testing.assert_allclose(ds.hand.radius_m, 0.9 * hand.radius_m, rtol=1e-6)
    assert np.abs(segments(ds.poses, ds.hand) - segments(rig_poses, scaled)).max() < 2e-6
    # the same segments as JSON lines of the generic kind (no hand key)
    p0, p1 = capsule_segments(rig_poses, hand)
    lines = [
        json.dumps(
            {"time": f / 30.0, "capsule": n, "radius": float(hand.radius_m[c])}
            | dict(zip(["p0_x", "p0_y", "p0_z"], map(float, p0[f, c])))
            | dict(zip(["p1_x", "p1_y", "p1_z"], map(float, p1[f, c])))
        )
        for f in range(len(rig_poses))
        for c, n in enumerate(hand.names)
    ]
    log = tmp_path / "caps.jsonl"
    log.write_text("\n".join(lines) + "\n")
    out = tmp_path / "caps"
    assert run_import("capsules", log, out) == 0
    assert np.abs(segments(load(out).poses, hand) - segments(rig_poses, hand)).max() < 2e-6


#: A link standing 1.2 m in front of the tracking origin, 0.9 m up, turned 70 degrees about z and tilted 20
#: degrees about x: the room a headset logs in, not the link's frame.
LINK_IN_ROOM = (np.array([1.2, -0.3, 0.9]), Rotation.from_euler("zx", [70, 20], degrees=True))


def _link_pose_arg() -> str:
    t, r = LINK_IN_ROOM
    return "link_pose=" + ",".join(f"{x:.17g}" for x in [*t, *r.as_quat()])


def test_a_log_in_the_rooms_frame_comes_into_the_links_with_link_pose(rig_poses, hand, openxr_log, tmp_path):
    t, r = LINK_IN_ROOM
    df = pd.read_csv(openxr_log)
    df[["px", "py", "pz"]] = r.apply(df[["px", "py", "pz"]].to_numpy()) + t
    df[["qx", "qy", "qz", "qw"]] = (r * Rotation.from_quat(df[["qx", "qy", "qz", "qw"]].to_numpy())).as_quat()
    room = tmp_path / "room.csv"
    df.to_csv(room, index=False)
    assert run_import("openxr", room, tmp_path / "ds", _link_pose_arg()) == 0
    ds = load(tmp_path / "ds")
    assert np.abs(segments(ds.poses, ds.hand) - segments(rig_poses, hand)).max() < 5e-6
    m = read_manifest(tmp_path / "ds" / "arm" / "participant_01" / "participant_01_manifest.json")
    assert m["trials"][0]["source"]["link_pose"] == _link_pose_arg().split("=", 1)[1]
    # without it the trial lies where the room put it: metres away from the link
    assert run_import("openxr", room, tmp_path / "raw") == 0
    raw = load(tmp_path / "raw")
    assert np.abs(segments(raw.poses, raw.hand) - segments(rig_poses, hand)).max() > 0.5
    # a capsule-segment log takes both ends into the link's frame
    p0, p1 = capsule_segments(rig_poses, hand)
    rows = ["time,capsule,p0_x,p0_y,p0_z,p1_x,p1_y,p1_z,radius"]
    for f in range(len(rig_poses)):
        for c, n in enumerate(hand.names):
            a, b = r.apply(p0[f, c]) + t, r.apply(p1[f, c]) + t
            rows.append(",".join(map(str, [f / 30.0, n, *a, *b, float(hand.radius_m[c])])))
    caps = tmp_path / "caps.csv"
    caps.write_text("\n".join(rows) + "\n")
    assert run_import("capsules", caps, tmp_path / "caps", _link_pose_arg()) == 0
    got = load(tmp_path / "caps")
    assert np.abs(segments(got.poses, got.hand) - segments(rig_poses, hand)).max() < 5e-6


def test_synthetic_dataset_exported_and_imported_gives_the_same_contacts(synthetic, hand, robot, tmp_path):
    """sphri's synthetic hand (with its 0.3 mm per-capsule tracking noise, which no joint log can carry exactly)
    through an OpenXR joint log and back: the contact stage finds the same contacts, every matched distance within
    1 mm, and a contact found on one side only lies within 1 mm of the contact threshold on the other."""
    from sphri.contact import capsule_mesh_query
    from tests.recordings.conftest import load_component

    out = tmp_path / "ds"
    trials = synthetic.trials.sort_values("trial_ordinal")
    for r in trials.itertuples():
        p = synthetic.poses[r.start : r.start + r.n_frames]
        log = export_openxr(p, hand, np.arange(len(p)) / synthetic.frame_rate_hz, tmp_path / f"{r.trial_id}.csv")
        args = [f"gesture={r.gesture}", f"rate_hz={synthetic.frame_rate_hz:g}"]
        assert run_import("openxr", log, out, *args) == 0
    back = load(out)
    assert back.n_frames == synthetic.n_frames and list(back.trials["gesture"]) == list(trials["gesture"])
    contact = load_component("contact", "exact")
    a, b = contact.compute(synthetic, robot), contact.compute(back, robot)
    pa = dict(zip(zip(a.frame.tolist(), a.capsule.tolist()), a.distance_m))
    pb = dict(zip(zip(b.frame.tolist(), b.capsule.tolist()), b.distance_m))
    both = pa.keys() & pb.keys()
    assert len(both) > 500, len(both)
    assert max(abs(pa[k] - pb[k]) for k in both) < 1e-3
    one = sorted(pa.keys() ^ pb.keys())
    assert len(one) <= 0.01 * len(both), (len(one), len(both))
    link = robot.link_for("arm")
    for ds, keys in ((synthetic, [k for k in one if k not in pa]), (back, [k for k in one if k not in pb])):
        if not keys:
            continue
        f, c = np.array(keys).T
        p0, p1 = capsule_segments(ds.poses[f], hand)
        i = np.arange(len(f))
        q = capsule_mesh_query(link.vertices, link.faces, p0[i, c], p1[i, c], hand.radius_m[c], margin=2e-3)
        assert (np.abs(q.distance - hand.radius_m[c]) < 1e-3).all()


# --------------------------------------------------------------------------------------------- refusals
def _lines(log: Path) -> list[str]:
    return log.read_text().splitlines()


def _set(lines: list[str], lineno: int, col: int, value: str) -> None:
    cells = lines[lineno - 1].split(",")
    cells[col] = value
    lines[lineno - 1] = ",".join(cells)


def _frame_line(f: int, joint: int = 0) -> int:
    return 2 + f * JOINTS + joint


def _mutate(kind):
    def apply(lines: list[str]) -> str:
        if kind == "time_back":
            for j in range(JOINTS):
                _set(lines, _frame_line(5, j), 0, "0.0")
        elif kind == "nan":
            _set(lines, 10, 3, "nan")
        elif kind == "joint":
            _set(lines, 12, 2, "index_knuckle")
        elif kind == "ms":
            for i in range(1, len(lines)):
                cells = lines[i].split(",")
                cells[0] = repr(float(cells[0]) * 1000)
                lines[i] = ",".join(cells)
        elif kind == "joint_id":
            _set(lines, 13, 2, "26")
        elif kind == "missing":
            del lines[_frame_line(2, 25) - 1]
        elif kind == "mm":
            for i in range(1, len(lines)):
                cells = lines[i].split(",")
                cells[3:6] = [f"{float(v) * 1000:.6g}" for v in cells[3:6]]
                lines[i] = ",".join(cells)
        elif kind == "hand":
            _set(lines, 7, 1, "both")
        elif kind == "empty":
            return ""
        elif kind == "header_only":
            return lines[0] + "\n"
        elif kind == "truncated":
            return "\n".join(lines)[:-25]
        elif kind == "type":
            _set(lines, 20, 3, "abc")
        elif kind == "duplicate":
            lines[_frame_line(4) - 1 : _frame_line(4) - 1] = lines[_frame_line(3) - 1 : _frame_line(4) - 1]
        elif kind == "mixed":
            for j in range(JOINTS):
                _set(lines, _frame_line(10, j), 1, "left")
        elif kind == "other_hand":
            for i in range(1, len(lines)):
                _set(lines, i + 1, 1, "left")
        elif kind == "column":
            lines[:] = [ln.rsplit(",", 1)[0] for ln in lines]
        elif kind == "zero_quat":
            for c in (6, 7, 8, 9):
                _set(lines, _frame_line(1, 7), c, "0")
        elif kind == "coincide":
            a, b = _frame_line(3, 7), _frame_line(3, 8)  # index_proximal and index_intermediate
            cells = lines[b - 1].split(",")
            cells[3:6] = lines[a - 1].split(",")[3:6]
            lines[b - 1] = ",".join(cells)
        return "\n".join(lines) + "\n"

    return apply


REFUSALS = [
    ("time_back", f"line {_frame_line(5)}: field time=0 goes back (line {_frame_line(5) - 1} has 0.133333333)"),
    ("nan", "line 10: field px is 'nan': NaN or infinite values are not poses"),
    ("joint", "line 12: field joint='index_knuckle' is not an XR_EXT_hand_tracking joint"),
    ("ms", f"line {_frame_line(1)}: field time: frames lie 33.33 apart (median), where seconds give 0.0001 to 2"),
    ("joint_id", "line 13: field joint='26' is not an XR_EXT_hand_tracking joint (names like index_tip, or ids 0..25)"),
    ("missing", f"line {_frame_line(2)}: the frame at time=0.0666666667 misses joint(s) ['little_tip']"),
    ("mm", "fields px, py, pz: the hand spans"),
    ("hand", "line 7: field hand='both' is not a hand: left or right"),
    ("empty", "empty file (no rows)"),
    ("header_only", "empty file (a header, no rows)"),
    ("truncated", f"line {_frame_line(39, 25)}: truncated file: the last line stops mid-row"),
    ("type", "line 20: field px='abc' is not a number (wrong column type"),
    ("duplicate", f"line {_frame_line(4)}: field joint='palm' at time=0.1 repeats line {_frame_line(3)}: duplicate"),
    ("mixed", f"line {_frame_line(10)}: field hand='left' after rows of hand 'right': mixed hands"),
    ("other_hand", "line 2: field hand='left', but hand=right is expected"),
    ("column", "line 1: missing column(s) ['qw']"),
    ("zero_quat", f"line {_frame_line(1)}: fields qx, qy, qz, qw of joint 'index_proximal' at time=0.0333333333 are"),
    ("coincide", f"line {_frame_line(3)}: joints index_proximal and index_intermediate coincide at time=0.1"),
]


@pytest.mark.parametrize("kind, expected", REFUSALS, ids=[k for k, _ in REFUSALS])
def test_each_bad_log_is_one_line_naming_file_line_and_field(kind, expected, openxr_log, tmp_path, capsys):
    bad = tmp_path / f"{kind}.csv"
    bad.write_text(_mutate(kind)(_lines(openxr_log)))
    out = tmp_path / "ds"
    assert run_import("openxr", bad, out) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"sphri import: log error: {bad}: "), err[0]
    assert expected in err[0], err[0]
    assert not out.exists()  # nothing written


def test_wrong_units_name_the_likely_unit(openxr_log, tmp_path, capsys):
    bad = tmp_path / "mm.csv"
    bad.write_text(_mutate("mm")(_lines(openxr_log)))
    assert run_import("openxr", bad, tmp_path / "ds") == 2
    assert "wrong units, the positions look like mm; give metres" in capsys.readouterr().err


def test_json_lines_refusals(rig_poses, hand, openxr_log, tmp_path, capsys):
    rows = [ln.split(",") for ln in _lines(openxr_log)[1:]]
    recs = [
        {
            "time": float(r[0]),
            "hand": r[1],
            "joint": r[2],
            "position": [*map(float, r[3:6])],
            "orientation": [*map(float, r[6:10])],
        }
        for r in rows
    ]
    good = tmp_path / "hand.jsonl"
    good.write_text("".join(json.dumps(r) + "\n" for r in recs))
    assert run_import("openxr", good, tmp_path / "ok") == 0
    capsys.readouterr()
    cut = tmp_path / "cut.jsonl"
    cut.write_text(good.read_text()[:-30])
    assert run_import("openxr", cut, tmp_path / "a") == 2
    assert f"{cut}: line {len(recs)}: truncated file" in capsys.readouterr().err
    recs[3]["position"] = [0.1, 0.2]
    short = tmp_path / "short.jsonl"
    short.write_text("".join(json.dumps(r) + "\n" for r in recs))
    assert run_import("openxr", short, tmp_path / "b") == 2
    assert f"{short}: line 4: field position=[0.1, 0.2] must be a list of 3 numbers" in capsys.readouterr().err
    recs[3]["position"] = ["0.1", 0.2, 0.3]
    short.write_text("".join(json.dumps(r) + "\n" for r in recs))
    assert run_import("openxr", short, tmp_path / "c") == 2
    assert "line 4: field px='0.1' is not a number" in capsys.readouterr().err


def test_capsule_log_refusals(rig_poses, hand, tmp_path, capsys):
    rows = _ovr_rows(rig_poses[:5], hand)
    bad = tmp_path / "ovr.csv"
    rows[3] = rows[3].replace("Hand_WristRoot", "Hand_Thumb0")
    bad.write_text("\n".join(rows) + "\n")
    assert run_import("ovr", bad, tmp_path / "a") == 2
    assert f"{bad}: line 4: field bone_id='Hand_Thumb0' is not a capsule bone" in capsys.readouterr().err
    caps = tmp_path / "caps.csv"
    caps.write_text("time,capsule,p0_x,p0_y,p0_z,p1_x,p1_y,p1_z,radius\n0,index4,0,0,0,0.01,0,0,0.008\n")
    assert run_import("capsules", caps, tmp_path / "b") == 2
    assert f"{caps}: line 2: field capsule='index4' is not a capsule of the hand model" in capsys.readouterr().err


def test_a_participant_keeps_one_rate(openxr_log, tmp_path, capsys):
    out = tmp_path / "ds"
    assert run_import("openxr", openxr_log, out) == 0
    assert run_import("openxr", openxr_log, out, "rate_hz=60") == 1
    assert "frame_rate_hz=30.0 but this trial is at 60 Hz: one rate per dataset" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, line",
    [
        (["gesture=wave"], "sphri import: unknown gesture 'wave'; gesture is one of: hit"),
        (["rate_hz=0"], "sphri import: rate_hz=0 is invalid: must be in [1, 1000] Hz"),
        (["link=../x"], "sphri import: link=../x is invalid: must be a region name"),
        (["hand=middle"], "sphri import: unknown hand 'middle'; hand is one of: left, right"),
        (["link_pose=1,2,3"], "sphri import: link_pose=1,2,3 is invalid: must be 7 numbers x,y,z,qx,qy,qz,qw"),
        (["link_pose=0,0,0,0,0,0,2"], "sphri import: link_pose=0,0,0,0,0,0,2 is invalid: its quaternion"),
        (["link_pose=0,0,0,0,0,0,nan"], "sphri import: link_pose=0,0,0,0,0,0,nan is invalid: must be 7 finite"),
    ],
)
def test_bad_arguments(argv, line, openxr_log, tmp_path, capsys):
    assert run_import("openxr", openxr_log, tmp_path / "ds", *argv) == 2
    assert capsys.readouterr().err.startswith(line)
