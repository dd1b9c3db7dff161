"""Fuzz campaign, target 4: session files of the scenario study (issue 29, item 5).

Written sessions (2 participants x 5 scenarios) are copied and corrupted once per case: one node of
``sessions.json`` or of a participant's ``manifest.json`` replaced by a value of the wrong type or
range, deleted or wrapped; a JSON or parquet file truncated or with bytes flipped; a pose cell set to
NaN or infinity; a column dropped. Each case must end in a named one-line error, a documented warning
or the uncorrupted sessions: never a traceback, never a silently changed result.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from fuzz_support import SILENT, UNCHANGED, WARNED, WarningCatcher, fuzz_settings, mutate_bytes, mutate_json
from hydra.utils import instantiate
from hypothesis import given
from hypothesis import strategies as st

from sphri.config import compose
from sphri.sessions.format import SessionData, write_sessions

SMALL = ["data=synthetic_sessions", "robot=reachy_full", "data.participants=2", "data.repetitions=1"]


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    cfg = compose(SMALL)
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    ds = instantiate(cfg.data).load(hand, robot)
    root = tmp_path_factory.mktemp("fuzz-sessions") / "s"
    write_sessions(ds, root)
    ref = SessionData(root=str(root)).load(hand, robot)
    return root, hand, robot, ref


def _same(a, b) -> bool:
    try:
        pd.testing.assert_frame_equal(a.sessions, b.sessions)
    except AssertionError:
        return False
    return (
        a.links == b.links
        and np.array_equal(a.hand_poses, b.hand_poses, equal_nan=True)
        and np.array_equal(a.link_poses, b.link_poses, equal_nan=True)
    )


KINDS = ["sessions.json field", "manifest field", "json bytes", "parquet bytes", "non-finite cell", "missing column"]


@fuzz_settings(small=12, large=160)
@given(kind=st.sampled_from(KINDS), data=st.data())
def test_corrupted_session_files(template, tally, kind, data):
    root0, hand, robot, ref = template
    with tempfile.TemporaryDirectory(prefix="sphri-fuzz-") as tmp:
        root = Path(tmp) / "s"
        shutil.copytree(root0, root)
        parquets = sorted(root.glob("participant_*/*.parquet"))
        if kind in ("sessions.json field", "manifest field"):
            path = (
                root / "sessions.json"
                if kind == "sessions.json field"
                else data.draw(st.sampled_from(sorted(root.glob("participant_*/manifest.json"))), label="manifest")
            )
            doc = json.loads(path.read_text())
            mutate_json(doc, data)
            path.write_text(json.dumps(doc, allow_nan=True))
        elif kind in ("json bytes", "parquet bytes"):
            files = sorted(root.rglob("*.json")) if kind == "json bytes" else parquets
            path = data.draw(st.sampled_from(files), label="file")
            if kind == "parquet bytes":  # column chunks only (a damaged footer can hang pyarrow: see RELIABILITY.md)
                blob = path.read_bytes()
                footer = int.from_bytes(blob[-8:-4], "little")
                i = data.draw(st.integers(4, len(blob) - 9 - footer), label="offset")
                b = bytearray(blob)
                b[i] ^= data.draw(st.integers(1, 255), label="xor")
                path.write_bytes(bytes(b))
            else:
                path.write_bytes(mutate_bytes(path.read_bytes(), data, header=b"{}")[1])
        else:
            path = data.draw(st.sampled_from(parquets), label="file")
            df = pd.read_parquet(path)
            cols = (
                [c for c in df.columns if c.endswith(("_pos_x", "_rot_w"))]
                if kind == "non-finite cell"
                else list(df.columns)
            )
            col = data.draw(st.sampled_from(cols), label="column")
            if kind == "missing column":
                df = df.drop(columns=[col])
            else:
                df.loc[data.draw(st.integers(0, len(df) - 1), label="row"), col] = data.draw(
                    st.sampled_from([np.nan, np.inf, -np.inf]), label="value"
                )
            df.to_parquet(path, index=False)
        with WarningCatcher() as warned:
            try:
                ds = SessionData(root=str(root)).load(hand, robot)
            except Exception as exc:  # noqa: BLE001 - judged: named, or re-raised as a traceback
                tally.add(kind, tally.named(kind, exc))
                return
        v = WARNED if warned.records else (UNCHANGED if _same(ds, ref) else SILENT)
        tally.add(kind, v)
        assert v != SILENT, f"{kind}: loaded without a warning into different sessions"


def test_a_flipped_bit_in_a_session_data_page_is_named(template, tmp_path):
    """Found by this campaign: a flipped bit inside a parquet data page of a session file loaded as
    changed poses without a word. Session files are written with page CRCs, verified when read."""
    from sphri.sessions.format import SessionFormatError

    root0, hand, robot, ref = template
    root = tmp_path / "s"
    shutil.copytree(root0, root)
    path = sorted(root.glob("participant_*/*.parquet"))[0]
    import pyarrow.parquet as pq

    md = pq.ParquetFile(path).metadata
    col = max((md.row_group(0).column(j) for j in range(md.num_columns)), key=lambda c: c.total_compressed_size)
    b = bytearray(path.read_bytes())
    b[col.data_page_offset + col.total_compressed_size // 2] ^= 1  # inside the largest column's values
    path.write_bytes(bytes(b))
    with pytest.raises(SessionFormatError, match=r"\.parquet: cannot read"):
        SessionData(root=str(root)).load(hand, robot)


def test_a_session_lost_from_the_manifest_is_warned(template, tmp_path, caplog):
    """Found by this campaign: a manifest with ``sessions[0]`` deleted loaded one session fewer without
    a word, its parquet file left unread. Now a warning names the file the manifest does not name."""
    import logging

    root0, hand, robot, ref = template
    root = tmp_path / "s"
    shutil.copytree(root0, root)
    path = root / "participant_01" / "manifest.json"
    m = json.loads(path.read_text())
    gone = m["sessions"].pop(0)["file"]
    path.write_text(json.dumps(m))
    with caplog.at_level(logging.WARNING, logger="sphri.sessions.format"):
        ds = SessionData(root=str(root)).load(hand, robot)
    assert len(ds.sessions) == len(ref.sessions) - 1
    assert f"not named by the manifest and are not read: {gone}" in caplog.text


@pytest.mark.parametrize(
    "where, field", [("manifest", "scenario"), ("manifest", "start_position"), ("header", "links")]
)
def test_a_name_field_wrapped_in_a_list_is_named(template, tmp_path, where, field):
    """Found by this campaign: ``sessions[0].scenario`` or ``sessions.json`` ``links`` wrapped in a list
    raised ``TypeError: unhashable type: 'list'`` (a traceback); ``start_position`` wrapped loaded a
    list into the sessions table without a word. Now one ``data error`` line naming the field."""
    from sphri.sessions.format import SessionFormatError

    root0, hand, robot, ref = template
    root = tmp_path / "s"
    shutil.copytree(root0, root)
    path = root / ("participant_01/manifest.json" if where == "manifest" else "sessions.json")
    doc = json.loads(path.read_text())
    node = doc["sessions"][0] if where == "manifest" else doc
    node[field] = [node[field]]
    path.write_text(json.dumps(doc))
    with pytest.raises(SessionFormatError, match=rf"{field}"):
        SessionData(root=str(root)).load(hand, robot)
