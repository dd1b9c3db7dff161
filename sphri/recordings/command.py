"""The verbs ``sphri import`` and ``sphri check-data``: their arguments and what they print."""

from __future__ import annotations

import dataclasses
import logging
import re
import sys

from sphri.args import arg
from sphri.data.recording_schema import HANDS, LOG_KINDS
from sphri.types import GESTURES


def _positive(v: float) -> str | None:
    return None if v > 0 else "must be > 0"


def _rate(v: float) -> str | None:
    return None if 1.0 <= v <= 1000.0 else "must be in [1, 1000] Hz"


def _participant(v: int) -> str | None:
    return None if 1 <= v <= 9999 else "must be in 1..9999 (participant_XX)"


def _link_pose(v: str) -> str | None:
    if not v:
        return None
    from sphri.recordings.frames import parse_link_pose

    try:
        parse_link_pose(v)
    except ValueError as e:
        return str(e)
    return None


def _link(v: str) -> str | None:
    ok = re.fullmatch(r"[A-Za-z0-9_-]+", v) and v != "assets"
    return None if ok else "must be a region name (letters, digits, _ and -; not assets), e.g. arm"


@dataclasses.dataclass
class ImportArgs:
    kind: str = arg(positional=True, choices=LOG_KINDS, help="the log's kind: openxr joints, ovr capsules or capsules")
    log: str = arg(positional=True, help="the log: a CSV file with a header row, or JSON lines (.jsonl)")
    out: str = arg(help="the gesture-trial dataset to add the trial to (made when absent)")
    link: str = arg(check=_link, help="the robot region whose link frame the log's positions are in, e.g. arm")
    participant: int = arg(check=_participant, help="the participant's number (folder participant_XX)")
    gesture: str = arg(choices=GESTURES, help="the trial's gesture")
    rate_hz: float = arg(30.0, check=_rate, help="the frame rate to resample to (Hz)")
    hand: str = arg("right", choices=HANDS, help="the hand the log must hold")
    hand_size: float = arg(1.0, check=_positive, help="openxr: factor on the documented hand model's capsule sizes")
    link_pose: str = arg(
        "",
        check=_link_pose,
        help="the link's pose in the log's frame, x,y,z,qx,qy,qz,qw (metres, unit quaternion) for a log recorded "
        "in the room's or a tracker's frame; empty: the log is in the link's frame",
    )


@dataclasses.dataclass
class CheckDataArgs:
    path: str = arg(positional=True, help="a gesture-trial or sessions folder")


def import_command(args: ImportArgs) -> int:
    """Convert a hand-tracking log (OpenXR joints, OVRSkeleton capsules, or capsule segments) into one trial of
    sphri's gesture-trial format, resampled to rate_hz; a malformed log is one line naming file, line and field."""
    from sphri.recordings.frames import describe
    from sphri.recordings.importer import DEFINITION, import_log

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    done = import_log(**dataclasses.asdict(args))  # the fields are import_log's parameters
    tid = f"{done.ordinal:04d}_{done.gesture}"
    print(f"imported {args.log} ({args.kind}, {args.hand} hand) as trial {tid} of {done.participant} on {done.region}")
    print(f"  {describe(done.report)}")
    print(f"  hand model: {done.hand_note}")
    print(
        f"  load it with: sphri data=vr_gesture data.root={done.root} data.regions=[{done.region}] "
        f"hand.definition_path={done.root / DEFINITION}"
    )
    return 0


def check_command(args: CheckDataArgs) -> int:
    """Check a recording folder (gesture trials or sessions) against docs/RECORDING_FORMAT.md: one line per
    problem (file, row or trial, field) and exit 2, or a short summary and exit 0."""
    from sphri.recordings.check import check_folder

    logging.basicConfig(level=logging.ERROR, format="%(levelname)s %(name)s: %(message)s")
    found = check_folder(args.path)
    for line in found.problems:
        print(line)
    if found.problems:
        print(f"sphri check-data: {len(found.problems)} problem(s) in {args.path}", file=sys.stderr)
        return 2
    print(found.summary)
    return 0
