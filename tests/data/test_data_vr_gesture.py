"""The recorded-dataset loader: round trip, lazy reading, and one test per defect."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from sphri.data.format import ManifestError, manifest_path, parquet_path
from sphri.data.vr_gesture import DatasetError, VRGestureData

P1 = "participant_01"


def load(root: Path, hand, **kw):
    kw.setdefault("regions", ["arm"])
    return VRGestureData(root=str(root), **kw).load(hand=hand)


def edit_parquet(root: Path, edit, region: str = "arm", pid: str = P1) -> None:
    path = parquet_path(root, region, pid)
    table = pq.read_table(path)
    pq.write_table(edit(table), path)


def edit_manifest(root: Path, edit, region: str = "arm", pid: str = P1) -> None:
    path = manifest_path(root, region, pid)
    m = json.loads(path.read_text())
    edit(m)
    path.write_text(json.dumps(m))


def set_column(table: pa.Table, name: str, values) -> pa.Table:
    i = table.schema.get_field_index(name)
    return table.set_column(i, table.schema.field(i), pa.array(values, table.schema.field(i).type))


def first_trial_rows(table: pa.Table, ordinal: int = 1) -> np.ndarray:
    return np.flatnonzero(table.column("trial_ordinal").to_numpy() == ordinal)


# ------------------------------------------------------------------ round trip
def test_written_synthetic_loads_identically(written, small, hand):
    ds = load(written, hand, regions=["arm", "torso"])
    assert ds.synthetic and ds.name == "synthetic"
    assert ds.frame_rate_hz == small.frame_rate_hz
    assert ds.repairs == {}
    assert ds.poses.dtype == np.float32
    assert np.array_equal(ds.poses, small.poses)
    assert ds.trials.equals(small.trials)


def test_without_generator_key_it_is_recorded_data(written, hand):
    for region in ("arm", "torso"):
        for pid in ("participant_01", "participant_02", "participant_03"):
            edit_manifest(written, lambda m: (m.pop("generator"), m.pop("frame_rate_hz")), region, pid)
    ds = load(written, hand)
    assert not ds.synthetic and ds.name == "vr_gesture"
    assert ds.frame_rate_hz == 30.0


def test_selection_participants_gestures_repetitions(written, small, hand):
    ds = load(written, hand, participants=2, gestures=["poke", "grab"], repetitions=1)
    assert sorted(ds.trials["participant"].unique()) == ["participant_01", "participant_02"]
    assert set(ds.trials["gesture"]) == {"poke", "grab"}
    assert ds.trials.groupby(["participant", "gesture"]).size().max() == 1
    # each kept trial has exactly the in-memory poses
    ref = small.trials.set_index(["participant", "region", "trial_ordinal"])
    for _, t in ds.trials.iterrows():
        r = ref.loc[(t.participant, t.region, t.trial_ordinal)]
        assert np.array_equal(ds.poses[t.start : t.start + t.n_frames], small.poses[r.start : r.start + r.n_frames])
    # the first trial by ordinal of each gesture is the one kept
    first = small.trials[(small.trials.region == "arm") & small.trials.gesture.isin(["poke", "grab"])]
    first = (
        first[first.participant.isin(["participant_01", "participant_02"])]
        .groupby(["participant", "gesture"])
        .trial_ordinal.min()
    )
    got = ds.trials.set_index(["participant", "gesture"]).trial_ordinal
    assert got.sort_index().tolist() == first.sort_index().tolist()


def test_reads_lazily(written, hand, monkeypatch):
    # torso and participant_03 files are garbage: selecting arm and 2 participants never opens them
    for pid in ("participant_01", "participant_02", "participant_03"):
        parquet_path(written, "torso", pid).write_bytes(b"not parquet")
    parquet_path(written, "arm", "participant_03").write_bytes(b"not parquet")
    calls = []
    real = pq.read_table

    def spy(path, *a, **kw):
        calls.append((str(path), kw.get("columns"), kw.get("filters")))
        return real(path, *a, **kw)

    monkeypatch.setattr(pq, "read_table", spy)
    ds = load(written, hand, participants=2, gestures=["tap"])
    assert set(ds.trials["gesture"]) == {"tap"} and len(ds.trials) == 4
    assert len(calls) == 2 and all("/arm/" in c[0] for c in calls)
    for _, columns, filters in calls:
        assert len(columns) == 5 + 7 * hand.n_capsules  # only the hand's pose columns
        assert filters[0][0] == "trial_ordinal" and filters[0][1] == "in" and len(filters[0][2]) == 2


def test_unreadable_parquet_is_named(written, hand):
    parquet_path(written, "arm", P1).write_bytes(b"not parquet")
    with pytest.raises(DatasetError, match=r"participant_01\.parquet: not a readable parquet file"):
        load(written, hand)


def test_missing_region_and_files_are_named(written, hand, tmp_path):
    with pytest.raises(DatasetError, match=r"no such region folder.*found \['arm', 'torso'\]"):
        load(written, hand, regions=["leg"])
    parquet_path(written, "arm", P1).unlink()
    with pytest.raises(FileNotFoundError, match="participant_01.parquet"):
        load(written, hand)
    with pytest.raises(DatasetError, match="no such directory"):
        load(tmp_path / "nowhere", hand)


def test_participant_without_a_region_folder_is_skipped(written, hand):
    import shutil

    shutil.rmtree(written / "torso" / "participant_02")
    ds = load(written, hand, regions=["arm", "torso"])
    got = ds.trials.groupby("participant")["region"].unique().map(sorted).to_dict()
    assert got["participant_02"] == ["arm"] and got["participant_01"] == ["arm", "torso"]


# ---------------------------------------------------------------- bad columns
def test_missing_column(written, hand):
    edit_parquet(written, lambda t: t.drop_columns(["index2_rot_w"]))
    with pytest.raises(DatasetError, match=r"participant_01\.parquet: missing column\(s\) \['index2_rot_w'\]"):
        load(written, hand)


def test_misnamed_column(written, hand):
    edit_parquet(
        written, lambda t: t.rename_columns([("middle1_pos_X" if c == "middle1_pos_x" else c) for c in t.column_names])
    )
    with pytest.raises(DatasetError, match=r"missing column.*'middle1_pos_x'.*misnamed\? found 'middle1_pos_X'"):
        load(written, hand)


def test_text_in_a_pose_column(written, hand):
    def edit(t):
        i = t.schema.get_field_index("wrist1_pos_x")
        return t.set_column(i, "wrist1_pos_x", pa.array([str(v) for v in t.column(i).to_pylist()]))

    edit_parquet(written, edit)
    with pytest.raises(DatasetError, match="column wrist1_pos_x has type string, expected numbers"):
        load(written, hand)


# ------------------------------------------------------------- bad pose values
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nan_or_inf_position_holds_last_valid_pose(written, hand, small, bad, caplog):
    table = pq.read_table(parquet_path(written, "arm", P1))
    rows = first_trial_rows(table)
    k = int(rows[5])
    values = table.column("thumb2_pos_y").to_numpy().copy()
    values[k] = bad
    edit_parquet(written, lambda t: set_column(t, "thumb2_pos_y", values))
    with caplog.at_level(logging.WARNING):
        ds = load(written, hand)
    assert ds.repairs == {"held_invalid_pose": 1}
    assert "trial 1" in caplog.text and "thumb2" in caplog.text
    c = hand.names.index("thumb2")
    fi = int(table.column("frame_index_in_trial").to_numpy()[k])
    assert np.array_equal(ds.poses[fi, c], ds.poses[fi - 1, c])  # held from the previous frame
    others = np.ones(len(ds.poses), bool)
    others[fi] = False
    ref = load_reference(small)
    assert np.array_equal(ds.poses[others], ref[others])


def load_reference(small):
    t = small.trials[(small.trials.region == "arm")]
    return np.concatenate([small.poses[r.start : r.start + r.n_frames] for r in t.itertuples()])


def test_leading_invalid_pose_takes_the_next_valid_one(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    k = int(first_trial_rows(table)[0])
    values = table.column("wrist3_pos_z").to_numpy().copy()
    values[k] = np.nan
    edit_parquet(written, lambda t: set_column(t, "wrist3_pos_z", values))
    ds = load(written, hand)
    c = hand.names.index("wrist3")
    assert np.array_equal(ds.poses[0, c], ds.poses[1, c])
    assert ds.repairs["held_invalid_pose"] == 1


def scale_quaternion(root: Path, capsule: str, pick, factor: float) -> None:
    """Multiply the four quaternion columns of ``capsule`` by ``factor`` on the rows ``pick`` of participant 1's
    first arm trial (0 makes a zero quaternion, 1.7 a non-unit one)."""
    table = pq.read_table(parquet_path(root, "arm", P1))
    rows = first_trial_rows(table)[pick]
    cols = {}
    for s in "xyzw":
        v = table.column(f"{capsule}_rot_{s}").to_numpy().copy()
        v[rows] *= factor
        cols[f"{capsule}_rot_{s}"] = v

    def edit(t):
        for name, v in cols.items():
            t = set_column(t, name, v)
        return t

    edit_parquet(root, edit)


def test_zero_quaternion_is_held(written, hand):
    scale_quaternion(written, "index3", 3, 0.0)
    ds = load(written, hand)
    assert ds.repairs == {"held_invalid_pose": 1}
    c = hand.names.index("index3")
    assert np.array_equal(ds.poses[3, c], ds.poses[2, c])


def test_non_unit_quaternion_is_normalized(written, hand):
    scale_quaternion(written, "pinky1", slice(0, 4), 1.7)
    ds = load(written, hand)
    assert ds.repairs == {"normalized_quaternion": 4}
    q = ds.poses[:4, hand.names.index("pinky1"), 3:].astype(np.float64)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)


def test_capsule_never_tracked_drops_the_trial(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    rows = first_trial_rows(table, 2)
    v = table.column("ring1_pos_x").to_numpy().copy()
    v[rows] = np.nan
    edit_parquet(written, lambda t: set_column(t, "ring1_pos_x", v))
    ds = load(written, hand, participants=1)
    assert ds.repairs == {"dropped_untracked_trial": 1}
    assert 2 not in ds.trials["trial_ordinal"].tolist()
    assert len(ds.trials) == 15


# ----------------------------------------------------------- bad trial layout
def shorten_first_trial(root: Path, keep: int) -> None:
    table = pq.read_table(parquet_path(root, "arm", P1))
    rows = first_trial_rows(table)
    mask = np.ones(table.num_rows, bool)
    mask[rows[keep:]] = False
    edit_parquet(root, lambda t: t.filter(pa.array(mask)))

    def edit(m):
        t = next(t for t in m["trials"] if t["trial_ordinal"] == 1)
        t["frame_count"] = keep
        t["end_frame"] = t["start_frame"] + keep - 1
        m["num_frames_total"] = sum(t["frame_count"] for t in m["trials"])

    edit_manifest(root, edit)


def test_one_frame_trial_is_dropped_and_counted(written, hand, caplog):
    shorten_first_trial(written, 1)
    with caplog.at_level(logging.WARNING):
        ds = load(written, hand, participants=1)
    assert ds.repairs == {"dropped_short_trial": 1}
    assert "trial 1" in caplog.text and "min_frames" in caplog.text
    assert 1 not in ds.trials["trial_ordinal"].tolist() and len(ds.trials) == 15
    ds = load(written, hand, participants=1, min_frames=1)
    assert ds.repairs == {} and ds.trials["n_frames"].iloc[0] == 1


def test_duplicated_frame_index(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    rows = first_trial_rows(table, 3)
    v = table.column("frame_index_in_trial").to_numpy().copy()
    v[rows[10]] = v[rows[9]]
    edit_parquet(written, lambda t: set_column(t, "frame_index_in_trial", v))
    with pytest.raises(DatasetError, match=r"trial 3: column frame_index_in_trial has duplicated values \[9\]"):
        load(written, hand)


def test_missing_frame_index(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    rows = first_trial_rows(table, 2)
    v = table.column("frame_index_in_trial").to_numpy().copy()
    v[rows[4:]] += 1
    edit_parquet(written, lambda t: set_column(t, "frame_index_in_trial", v))
    with pytest.raises(DatasetError, match=r"trial 2: column frame_index_in_trial has missing values \[4\]"):
        load(written, hand)


def test_unknown_gesture_label(written, hand):
    def edit(m):
        m["trials"][0]["gesture_label"] = "wave"
        m["trials"][0]["trial_id"] = "0001_wave"

    edit_manifest(written, edit)
    with pytest.raises(
        DatasetError, match=r"manifest.json: trial 1: column gesture_label='wave' is not a known gesture"
    ):
        load(written, hand)


def test_unknown_gesture_label_in_parquet(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    labels = np.asarray(table.column("gesture_label").to_pylist(), dtype=object)
    labels[first_trial_rows(table, 1)] = "wave"
    edit_parquet(written, lambda t: set_column(t, "gesture_label", labels.tolist()))
    with pytest.raises(DatasetError, match=r"trial 1: column gesture_label='wave' is not a known gesture"):
        load(written, hand)


# ------------------------------------------------- manifest vs parquet
def test_manifest_frame_count_disagrees(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    rows = first_trial_rows(table, 4)
    mask = np.ones(table.num_rows, bool)
    mask[rows[-1]] = False
    edit_parquet(written, lambda t: t.filter(pa.array(mask)))

    def edit(m):  # totals follow the parquet; the trial's frame_count does not
        m["num_frames_total"] -= 1
        m["trials"][-1]["frame_count"] -= 1
        m["trials"][-1]["end_frame"] -= 1
        assert m["trials"][-1]["trial_ordinal"] != 4, "fixture: trial 4 must not be the last trial"

    edit_manifest(written, edit)
    with pytest.raises(ManifestError, match=r"trial 4: \d+ rows but the manifest's frame_count is \d+"):
        load(written, hand)


def test_manifest_total_disagrees(written, hand):
    edit_manifest(
        written,
        lambda m: m.update(
            num_frames_total=m["num_frames_total"] + 5,
            trials=m["trials"][:-1] + [dict(m["trials"][-1], frame_count=m["trials"][-1]["frame_count"] + 5)],
        ),
    )
    with pytest.raises(ManifestError, match=r"num_frames_total=\d+ but participant_01.parquet has \d+ rows"):
        load(written, hand)


def test_manifest_label_disagrees(written, hand):
    def edit(m):
        t = m["trials"][0]
        t["gesture_label"] = "hit" if t["gesture_label"] != "hit" else "pat"
        t["trial_id"] = f"0001_{t['gesture_label']}"

    edit_manifest(written, edit)
    with pytest.raises(ManifestError, match=r"trial 1: gesture_label '\w+' but the manifest says '\w+'"):
        load(written, hand)


def test_manifest_trial_without_rows(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    o = table.column("trial_ordinal").to_numpy().copy()
    o[first_trial_rows(table, 5)] = 99
    edit_parquet(written, lambda t: set_column(t, "trial_ordinal", o))
    with pytest.raises(ManifestError, match=r"trial 5 \(0005_\w+\) is in the manifest but has no rows"):
        load(written, hand)


def test_manifest_inconsistent_in_itself(written, hand):
    edit_manifest(written, lambda m: m.update(num_trials=3))
    with pytest.raises(ManifestError, match=r"num_trials=3 but 16 trials are listed"):
        load(written, hand)
    edit_manifest(written, lambda m: m.update(num_trials=16, participant_id="participant_09"))
    with pytest.raises(ManifestError, match="disagree with its folder"):
        load(written, hand)


def test_frame_numbers_off_the_manifest_are_counted(written, hand):
    table = pq.read_table(parquet_path(written, "arm", P1))
    edit_parquet(written, lambda t: set_column(t, "frame", table.column("frame").to_numpy() + 1000))
    ds = load(written, hand, participants=1)
    assert ds.repairs == {"frame_range_mismatch": 16}
