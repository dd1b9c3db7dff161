"""Session files checked against what they claim (issue 29, item 3): manifest paths outside the
participant's folder, implausible frame rates, a participant copied under another id.

Each test names the issue's reproducer; each fails on the sphri before this change."""

from __future__ import annotations

import json
import logging
import math
import shutil

import pytest

from sphri.sessions.format import SessionData


def _edit(root, pid, edit):
    path = root / pid / "manifest.json"
    m = json.loads(path.read_text())
    edit(m)
    path.write_text(json.dumps(m))


def test_manifest_path_leaving_the_participant_folder_is_refused(written, copy_written, load_refused):
    """Reproducer (issue 29): a manifest path ``../participant_01/...`` was read (another participant's data)."""
    root = copy_written("up")
    other = json.loads((root / "participant_01" / "manifest.json").read_text())["sessions"][0]

    def borrow(m):  # participant_02's first session now names participant_01's file (counts made to agree)
        m["sessions"][0].update(
            file=f"../participant_01/{other['file']}",
            scenario=other["scenario"],
            repetition=other["repetition"],
            n_frames=other["n_frames"],
        )

    _edit(root, "participant_02", borrow)
    load_refused(
        root,
        r"participant_02/manifest\.json: sessions\[0\]\.file="
        r"'\.\./participant_01/.*no absolute path, no '\.\.'",
    )

    root = copy_written("abs")
    outside = str(written / "participant_02" / other["file"])
    _edit(root, "participant_01", lambda m: m["sessions"][1].update(file=outside))
    load_refused(root, r"participant_01/manifest\.json: sessions\[1\]\.file='/")

    # a link inside the folder that points out of it is refused too
    root = copy_written("link")
    entry = json.loads((root / "participant_01" / "manifest.json").read_text())["sessions"][0]
    target = root / "participant_01" / entry["file"]
    target.unlink()
    target.symlink_to(written / "participant_01" / entry["file"])
    load_refused(root, r"manifest\.json: field file=.* resolves outside")


@pytest.mark.parametrize("rate", [1e-9, 0, -30.0, 5000.0, math.inf, math.nan, "30"])
def test_implausible_session_frame_rate_is_refused(copy_written, load_refused, rate):
    """Reproducer (issue 29): ``frame_rate_hz=1e-9`` was accepted."""
    root = copy_written("rate")
    _edit(root, "participant_02", lambda m: [e.update(frame_rate_hz=rate) for e in m["sessions"]])
    load_refused(
        root,
        r"participant_02/manifest\.json: sessions\[0\]\.frame_rate_hz="
        r".* is implausible: must be a number in \[1, 1000\] Hz",
    )


def test_copied_participant_is_refused_or_warned_naming_both_ids(small, written, copy_written, load_refused, caplog):
    """Reproducer (issue 29): a participant duplicated under another id was accepted (held-out capture
    46 % -> 60 %)."""
    _, hand, robot, _ = small
    SessionData(root=str(written)).load(hand, robot)  # two different people: no false alarm
    root = copy_written("dup")
    shutil.copytree(root / "participant_01", root / "participant_05")
    load_refused(
        root,
        r"participant_01 and participant_05 hold near-identical recordings "
        r"\(5 of 5 sessions.*data\.duplicates=warn",
    )
    with caplog.at_level(logging.WARNING, logger="sphri.sessions.format"):
        ds = SessionData(root=str(root), duplicates="warn").load(hand, robot)
    assert "participant_01 and participant_05" in caplog.text
    assert sorted(ds.sessions["participant"].unique()) == ["participant_01", "participant_02", "participant_05"]
