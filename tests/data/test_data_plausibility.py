"""Impossible data refused, named (issue 16, items 5 and 6): positions in mm or cm, implausible frame
rates, participants without usable trials, damaged parquet pages."""

from __future__ import annotations

import logging

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_data_vr_gesture import edit_manifest, edit_parquet

from sphri.data.format import ManifestError, parquet_path
from sphri.data.vr_gesture import DatasetError, VRGestureData

P2 = "participant_02"


def load(root, hand, robot=None, **kw):
    kw.setdefault("regions", ["arm"])
    return VRGestureData(root=str(root), **kw).load(hand=hand, robot=robot)


def scale_positions(table: pa.Table, factor: float) -> pa.Table:
    for i, name in enumerate(table.column_names):
        if "_pos_" in name:
            col = pa.array(table.column(i).to_numpy() * factor, table.schema.field(i).type)
            table = table.set_column(i, table.schema.field(i), col)
    return table


@pytest.mark.parametrize("unit,factor", [("mm", 1000.0), ("cm", 100.0)])
def test_one_participant_in_mm_or_cm_is_refused_and_named(written, hand, robot, unit, factor):
    edit_parquet(written, lambda t: scale_positions(t, factor), pid=P2)
    with pytest.raises(
        DatasetError, match=rf"{P2}\.parquet: {P2}'s hand positions are implausible.*data\.units={unit}"
    ):
        load(written, hand, robot)


def test_declared_units_are_scaled_to_metres(written, hand, robot, small):
    ref = load(written, hand, robot)
    for pid in ("participant_01", P2, "participant_03"):
        edit_parquet(written, lambda t: scale_positions(t, 1000.0), pid=pid)
    with pytest.raises(DatasetError, match="data.units=mm"):
        load(written, hand, robot)
    ds = load(written, hand, robot, units="mm")
    np.testing.assert_allclose(ds.poses, ref.poses, atol=1e-6)
    # positions in metres declared as mm are refused too (the hand would be 1000 times too small)
    with pytest.raises(DatasetError, match="data.units=m"):
        load(_fresh(written, small, robot), hand, robot, units="mm")


def _fresh(written, small, robot):
    from sphri.data.writer import write_dataset

    write_dataset(small, robot, written.parent / "fresh")
    return written.parent / "fresh"


def test_hand_far_from_the_robot_is_refused(written, hand, robot):
    def shift(t: pa.Table) -> pa.Table:
        for i, name in enumerate(t.column_names):
            if name.endswith("_pos_x"):
                t = t.set_column(i, t.schema.field(i), pa.array(t.column(i).to_numpy() + 50.0, t.schema.field(i).type))
        return t

    edit_parquet(written, shift, pid=P2)
    with pytest.raises(DatasetError, match=rf"{P2}'s hand stays .* from link 'l_arm'"):
        load(written, hand, robot)
    load(written, hand, None, participants=1)  # the others still load


@pytest.mark.parametrize("rate", [0, -30, 5000, "30"])
def test_implausible_manifest_frame_rate_is_refused(written, hand, rate):
    def edit(m):
        m["frame_rate_hz"] = rate

    edit_manifest(written, edit, pid=P2)
    with pytest.raises(ManifestError, match=rf"{P2}_manifest\.json: frame_rate_hz={rate!r} is implausible"):
        load(written, hand)


def test_participant_without_usable_trials_is_named(written, hand, caplog):
    """participant_02's thumb is never tracked: every trial dropped; the participant is named and counted."""

    def untrack(t: pa.Table) -> pa.Table:
        i = t.schema.get_field_index("thumb2_pos_y")
        return t.set_column(i, t.schema.field(i), pa.array(np.full(t.num_rows, np.nan), t.schema.field(i).type))

    edit_parquet(written, untrack, pid=P2)
    with caplog.at_level(logging.WARNING):
        ds = load(written, hand)
    assert P2 not in set(ds.trials["participant"]) and ds.trials["participant"].nunique() == 2
    assert ds.repairs["participant_without_trials"] == 1
    assert any(P2 in r.getMessage() and "no usable trial" in r.getMessage() for r in caplog.records)


def test_corrupted_parquet_page_names_the_file(written, hand):
    path = parquet_path(written, "arm", P2)
    pq.write_table(pq.read_table(path), path, compression="zstd")
    meta = pq.ParquetFile(path).metadata
    names = [meta.schema.column(i).name for i in range(meta.num_columns)]
    col = meta.row_group(0).column(names.index("index2_pos_x"))
    blob = bytearray(path.read_bytes())
    frame = blob.index(b"\x28\xb5\x2f\xfd", col.data_page_offset)  # the page's zstd frame, after its header
    for k in range(frame + 8, frame + 40):
        blob[k] ^= 0x5A
    path.write_bytes(bytes(blob))
    with pytest.raises(DatasetError, match=rf"{P2}\.parquet: cannot read its pose data") as err:
        load(written, hand)
    assert "decompress" in str(err.value).lower() or "zstd" in str(err.value).lower(), err.value
