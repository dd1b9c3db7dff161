"""Data checked against what it claims (issue 29, item 3): copied participants, one trial in other
units, an index that reorders the poses, a stray mesh part deciding the units.

Each test names the issue's reproducer; each fails on the sphri before this change."""

from __future__ import annotations

import json
import logging
import shutil

import numpy as np
import pyarrow as pa
import pytest
import trimesh
from test_data_vr_gesture import edit_parquet, first_trial_rows, set_column

from sphri.data.format import manifest_path, parquet_path
from sphri.data.vr_gesture import DatasetError, VRGestureData
from sphri.robots.validate import MeshError, make_link

P2 = "participant_02"


def load(root, hand, robot=None, **kw):
    kw.setdefault("regions", ["arm"])
    return VRGestureData(root=str(root), **kw).load(hand=hand, robot=robot)


def copy_participant(root, src: str, dst: str, region: str = "arm", noise_m: float = 0.0) -> None:
    """Copy ``src``'s folder to ``dst`` (files and manifest renamed), positions moved by up to ``noise_m``."""
    shutil.copytree(root / region / src, root / region / dst)
    (root / region / dst / f"{src}.parquet").rename(parquet_path(root, region, dst))
    (root / region / dst / f"{src}_manifest.json").rename(manifest_path(root, region, dst))
    m = json.loads(manifest_path(root, region, dst).read_text())
    m["participant_id"] = dst
    manifest_path(root, region, dst).write_text(json.dumps(m))
    if noise_m:
        rng = np.random.default_rng(0)

        def jitter(t: pa.Table) -> pa.Table:
            for i, name in enumerate(t.column_names):
                if "_pos_" in name:
                    v = t.column(i).to_numpy() + rng.uniform(-noise_m, noise_m, t.num_rows)
                    t = t.set_column(i, t.schema.field(i), pa.array(v, t.schema.field(i).type))
            return t

        edit_parquet(root, jitter, region=region, pid=dst)


@pytest.mark.parametrize("noise_m", [0.0, 0.0005])
def test_copied_participant_is_refused_naming_both_ids(written, hand, noise_m):
    """Reproducer (issue 29): a participant duplicated under another id was accepted (LOSO 0.241 -> 0.658).
    Identical, and near-identical (positions moved by up to 0.5 mm), copies are refused by default."""
    load(written, hand)  # three different people: no false alarm
    copy_participant(written, P2, "participant_07", noise_m=noise_m)
    with pytest.raises(
        DatasetError,
        match=r"participant_02 and participant_07 hold near-identical recordings "
        r"\(16 of 16 trials.*data\.duplicates=warn",
    ):
        load(written, hand)


def test_copied_participant_warned_with_both_ids_when_allowed(written, hand, caplog):
    """Reproducer (issue 29): the copied participant of the test above, with ``data.duplicates=warn``."""
    copy_participant(written, P2, "participant_07")
    with caplog.at_level(logging.WARNING, logger="sphri.data.vr_gesture"):
        ds = load(written, hand, duplicates="warn")
    assert ds.repairs["duplicate_participants"] == 1
    assert "participant_02 and participant_07" in caplog.text
    assert sorted(ds.trials["participant"].unique()) == ["participant_01", P2, "participant_03", "participant_07"]
    assert load(written, hand, duplicates="off").repairs.get("duplicate_participants", 0) == 0


def test_one_trial_in_millimetres_is_refused_by_ordinal(written, hand, robot):
    """Reproducer (issue 29): one trial in mm among trials in metres was dropped as "no contact"."""

    def trial_in_mm(t: pa.Table) -> pa.Table:
        rows = first_trial_rows(t, 3)
        for name in t.column_names:
            if "_pos_" in name:
                v = t.column(name).to_numpy().copy()
                v[rows] *= 1000.0
                t = set_column(t, name, v)
        return t

    edit_parquet(written, trial_in_mm, pid=P2)
    with pytest.raises(
        DatasetError,
        match=rf"{P2}\.parquet: trial 3 \(0003_\w+\): .*looks like mm, the others like "
        r"data\.units=m",
    ):
        load(written, hand, robot)


def test_reversed_frame_index_is_refused(written, hand):
    """Reproducer (issue 29): a reversed ``frame_index_in_trial`` was "kept; poses unaffected" while the
    loader reordered the poses by it."""

    def reverse(t: pa.Table) -> pa.Table:
        rows = first_trial_rows(t, 2)
        idx = t.column("frame_index_in_trial").to_numpy().copy()
        idx[rows] = idx[rows][::-1]
        return set_column(t, "frame_index_in_trial", idx)

    edit_parquet(written, reverse)
    with pytest.raises(
        DatasetError,
        match=r"participant_01\.parquet: trial 2: column frame goes backwards .* "
        r"frame_index_in_trial=1: the index disagrees with the recording order",
    ):
        load(written, hand)


def _box(extents, at=(0.0, 0.0, 0.0)):
    b = trimesh.creation.box(extents=extents)
    return np.asarray(b.vertices) + np.asarray(at), np.asarray(b.faces)


def _arm_with(part_v, part_f, arm=(0.06, 0.08, 0.24)):
    v, f = trimesh.creation.icosphere(subdivisions=2).vertices * 0.5, trimesh.creation.icosphere(subdivisions=2).faces
    v = np.asarray(v) * np.asarray(arm)  # a 24 cm arm-like ellipsoid of 320 faces
    return np.vstack([v, part_v]), np.vstack([f, np.asarray(part_f) + len(v)])


def test_stray_part_far_away_does_not_flip_units():
    """Reproducer (issue 29): a stray component 10 m from the arm flipped ``units=auto`` to mm (the arm
    shrank 1000x; the run reported a 0.6 mm pitch). The main part reads as metres, so the mesh is not
    scaled; the stray part would still distort the surface, so it is refused with the settings."""
    v, f = _arm_with(*_box((0.01, 0.01, 0.01), at=(10.0, 0.0, 0.0)))
    with pytest.raises(
        MeshError,
        match=r"its main part \(320 of 332 faces, 0\.24 across\) reads as metres but 1 "
        r"other part\(s\) stretch the mesh to 10 across: a stray part .*"
        r"set robot\.units=m to use the mesh as it is",
    ):
        make_link("arm", v, f, units="auto")
    link = make_link("arm", v, f, units="m")  # as the user says: kept, unscaled
    assert np.ptp(link.vertices[:, 2]) == pytest.approx(0.24, rel=1e-6) and np.ptp(link.vertices[:, 0]) > 9.0
    # a link in millimetres with a small part beside it is scaled, by its main part
    v, f = _arm_with(*_box((1.0, 1.0, 1.0), at=(300.0, 0.0, 0.0)), arm=(60.0, 80.0, 240.0))
    assert np.ptp(make_link("arm", v, f, units="auto").vertices[:, 2]) == pytest.approx(0.24, rel=1e-6)
    # the arm alone is unchanged
    assert np.ptp(
        make_link("arm", *_arm_with(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), units="auto").vertices[:, 2]
    ) == pytest.approx(0.24, rel=1e-6)


def test_major_parts_disagreeing_on_units_are_refused():
    """Two parts of equal weight, one 24 cm and one 240 units across: ambiguous, refused with the setting."""
    a_v, a_f = _box((0.06, 0.08, 0.24))
    b_v, b_f = _box((60.0, 80.0, 240.0), at=(500.0, 0.0, 0.0))
    v, f = np.vstack([a_v, b_v]), np.vstack([a_f, b_f + len(a_v)])
    with pytest.raises(MeshError, match=r"units are ambiguous: .*set robot\.units=m or robot\.units=mm"):
        make_link("arm", v, f, units="auto")
    assert np.ptp(make_link("arm", v, f, units="m").vertices[:, 2]) == pytest.approx(240.0)
