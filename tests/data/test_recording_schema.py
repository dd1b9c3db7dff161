"""The recording formats' one source (sphri.data.recording_schema): the page is generated from it, the loaders read it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sphri.data import format as gesture_format
from sphri.data import recording_schema as schema
from sphri.sessions import format as session_format

ROOT = Path(__file__).resolve().parents[2]


def test_committed_page_is_the_generated_one():
    page = (ROOT / "docs" / "RECORDING_FORMAT.md").read_text()
    assert page == schema.markdown(), (
        "docs/RECORDING_FORMAT.md is stale: python -m sphri.data.recording_schema --markdown > docs/RECORDING_FORMAT.md"
    )


def test_page_names_every_column_field_capsule_and_version():
    page = schema.markdown()
    for cols in (schema.GESTURE_COLUMNS, schema.SESSION_COLUMNS, schema.OPENXR_LOG, schema.OVR_CAPSULE_LOG):
        for c in cols:
            assert f"| `{c.name}` | {c.dtype} | {c.written} | {c.unit} | {c.frame} |" in page, c.name
    for fields in (schema.GESTURE_MANIFEST, schema.GESTURE_TRIAL, schema.SESSION_HEADER, schema.SESSION_MANIFEST):
        for f in fields:
            assert f"| `{f.name}` |" in page, f.name
    for name in ("wrist1", "thumb3", "pinky3"):
        assert f"| `{name}` |" in page
    assert "| 18.23 | 87.32 | 50.86 | X |" in page  # wrist1's radius, height and core (mm) from the hand config
    for v in schema.GESTURE_VERSIONS + schema.SESSION_VERSIONS:
        assert f"| {v.number} | {v.changes} |" in page
    assert page.count("| `") > 60


def test_loaders_take_their_lists_from_the_schema():
    assert gesture_format.META_COLUMNS == (
        "trial_id",
        "trial_ordinal",
        "gesture_label",
        "frame",
        "frame_index_in_trial",
    )
    assert gesture_format.STRING_COLUMNS == ("trial_id", "gesture_label")
    assert gesture_format.MANIFEST_KEYS == tuple(f.name for f in schema.GESTURE_MANIFEST if f.required)
    assert "format_version" not in gesture_format.MANIFEST_KEYS  # version 1 files have none
    assert session_format.HEADER_KEYS == ("format", "version", "name", "synthetic", "robot", "links", "hands", "hand")
    assert session_format.ROW_COLUMNS == ("repetition", "frame")
    assert len(schema.OPENXR_JOINTS) == 26 and len(set(schema.OPENXR_CAPSULES)) == 19


def _manifest(tmp_path: Path, **extra) -> Path:
    m = {
        "participant_id": "participant_01",
        "body_region": "arm",
        "num_trials": 1,
        "num_frames_total": 3,
        "trials": [{"trial_ordinal": 1, "trial_id": "0001_tap", "gesture_label": "tap", "frame_count": 3}],
        **extra,
    }
    p = tmp_path / "m.json"
    p.write_text(json.dumps(m))
    return p


def test_manifest_versions_one_and_two_read_a_later_one_is_named(tmp_path):
    assert gesture_format.read_manifest(_manifest(tmp_path))["num_trials"] == 1
    assert gesture_format.read_manifest(_manifest(tmp_path, format_version=2))["format_version"] == 2
    with pytest.raises(
        gesture_format.ManifestError, match=r"m\.json: format_version=3: this sphri reads versions 1\.\.2"
    ):
        gesture_format.read_manifest(_manifest(tmp_path, format_version=3))


def test_markdown_command(capsys):
    assert schema.main(["--markdown"]) == 0
    assert capsys.readouterr().out == schema.markdown()
    assert schema.main([]) == 2
