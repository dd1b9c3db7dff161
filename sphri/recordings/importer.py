"""``sphri import``: a hand-tracking log in, one gesture trial of sphri's capsule format out.

Three kinds of log (:mod:`sphri.data.recording_schema`, ``docs/RECORDING_FORMAT.md``):

- ``openxr``: the 26 joints of ``XR_EXT_hand_tracking`` per frame; capsules by
  :func:`sphri.recordings.capsules.openxr_poses`, sized by the hand model;
- ``ovr``: Meta's ``OVRSkeleton`` capsules (start, end, radius) per frame;
- ``capsules``: any log of capsule segments (name, p0, p1, radius) per frame.

The log is checked (:mod:`sphri.recordings.logs`, :mod:`sphri.recordings.frames`), resampled to
``rate_hz`` and added as the next trial of ``participant`` in ``out/<link>/`` (:func:`append_trial`).
The dataset keeps one hand model, ``out/assets/hand_capsule_definition.json``: the first import
writes it (``openxr``: the documented model, ``hand=quest_capsules``, times ``hand_size``; ``ovr`` and
``capsules``: the log's median capsule sizes); later imports place their capsules with it and report
how far the log's own capsule sizes differ. Load the result with
``data=vr_gesture data.root=OUT data.regions=[LINK] hand.definition_path=OUT/assets/hand_capsule_definition.json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri.data.format import participant_id, write_hand_definition
from sphri.data.recording_schema import (
    CAPSULE_LOG,
    OPENXR_CAPSULES,
    OPENXR_JOINTS,
    OPENXR_LOG,
    OVR_BONES,
    OVR_CAPSULE_LOG,
)
from sphri.data.writer import append_trial
from sphri.recordings.capsules import MIN_BONE_M, documented_hand, hand_from_segments, openxr_poses, segment_poses
from sphri.recordings.frames import Frames, check_hand, check_metres, resample, to_frames, to_link_frame
from sphri.recordings.logs import LogError, read_log
from sphri.types import HandModel

#: The capsules every import makes, in pose-column order (the study's 19).
CAPSULES: tuple[str, ...] = tuple(OPENXR_CAPSULES)
POSITION = ("px", "py", "pz", "qx", "qy", "qz", "qw")
SEGMENT = ("p0_x", "p0_y", "p0_z", "p1_x", "p1_y", "p1_z", "radius")
DEFINITION = Path("assets") / "hand_capsule_definition.json"


@dataclass
class Imported:
    """What one import did."""

    root: Path
    region: str
    participant: str
    ordinal: int
    gesture: str
    report: dict[str, Any]
    hand_note: str
    files: list[Path]


def _known(path: Path, df: pd.DataFrame, column: str, values: pd.Series, known: object, what: str) -> None:
    """Refuse the first row whose ``values`` (of ``column``) are not in ``known``: ``what`` it should be."""
    unknown = ~values.isin(known)
    if unknown.any():
        i = int(np.flatnonzero(unknown.to_numpy())[0])
        raise LogError(f"{path}: line {df['line'].iat[i]}: field {column}={df[column].iat[i]!r} is not {what}")


def _openxr(path: Path, df: pd.DataFrame) -> Frames:
    names = {n: n for n in OPENXR_JOINTS} | {str(i): n for i, n in enumerate(OPENXR_JOINTS)}
    joint = df["joint"].str.strip().str.lower()
    _known(path, df, "joint", joint, names, "an XR_EXT_hand_tracking joint (names like index_tip, or ids 0..25)")
    df = df.assign(joint=joint.map(names))
    used = sorted({j for bone in OPENXR_CAPSULES.values() for j in bone}, key=OPENXR_JOINTS.index)
    frames = to_frames(path, df, "joint", OPENXR_JOINTS, POSITION, used)
    absent = np.isnan(frames.values).any(axis=-1)  # a joint no capsule uses (palm, wrist) may be left out
    frames.values[absent] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    q = np.linalg.norm(frames.values[..., 3:], axis=-1)[:, [OPENXR_JOINTS.index(j) for j in used]]
    if (q < 1e-8).any():
        f, j = np.argwhere(q < 1e-8)[0]
        raise LogError(
            f"{path}: line {frames.line[f]}: fields qx, qy, qz, qw of joint {used[j]!r} at time="
            f"{frames.time_s[f]:.9g} are all 0: not a rotation"
        )
    index = {n: i for i, n in enumerate(OPENXR_JOINTS)}
    for cap, bone in OPENXR_CAPSULES.items():
        if len(bone) == 2:
            length = np.linalg.norm(frames.values[:, index[bone[1]], :3] - frames.values[:, index[bone[0]], :3], axis=1)
            if (length < MIN_BONE_M).any():
                f = int(np.flatnonzero(length < MIN_BONE_M)[0])
                raise LogError(
                    f"{path}: line {frames.line[f]}: joints {bone[0]} and {bone[1]} coincide at time="
                    f"{frames.time_s[f]:.9g}: capsule {cap} has no direction"
                )
    return frames


def _ovr_names(path: Path, df: pd.DataFrame) -> pd.DataFrame:
    bone = df["bone_id"].str.strip()
    _known(path, df, "bone_id", bone, OVR_BONES, f"a capsule bone of the hand model ({', '.join(OVR_BONES)})")
    names = bone.map(OVR_BONES).to_numpy(object)
    wrist = bone.to_numpy() == "Hand_WristRoot"
    slots = np.unique(df["capsule_index"].to_numpy()[wrist])
    if slots.size > 4:
        i = int(np.flatnonzero(wrist & (df["capsule_index"].to_numpy() == slots[4]))[0])
        raise LogError(
            f"{path}: line {df['line'].iat[i]}: field capsule_index={slots[4]}: a fifth capsule on Hand_WristRoot, "
            "where the hand model has wrist1..4"
        )
    rank = {int(s): k + 1 for k, s in enumerate(slots)}
    names[wrist] = [f"wrist{rank[int(s)]}" for s in df["capsule_index"].to_numpy()[wrist]]
    df = df.assign(capsule=names)
    clash = df.groupby("capsule")["capsule_index"].nunique()
    if (clash > 1).any():
        name = str(clash.index[clash.to_numpy() > 1][0])
        rows = df[df["capsule"] == name]
        i = int(np.flatnonzero((rows["capsule_index"] != rows["capsule_index"].iat[0]).to_numpy())[0])
        raise LogError(
            f"{path}: line {rows['line'].iat[i]}: field capsule_index={rows['capsule_index'].iat[i]} on bone "
            f"{rows['bone_id'].iat[i]}, which already has capsule_index {rows['capsule_index'].iat[0]}: one capsule "
            "per finger bone"
        )
    return df.rename(columns={f"{a}_{x}": f"{b}_{x}" for a, b in (("start", "p0"), ("end", "p1")) for x in "xyz"})


def _segments(path: Path, df: pd.DataFrame) -> Frames:
    _known(path, df, "capsule", df["capsule"], CAPSULES, f"a capsule of the hand model ({', '.join(CAPSULES)})")
    frames = to_frames(path, df, "capsule", CAPSULES, SEGMENT, CAPSULES)
    v = frames.values
    bad = (np.linalg.norm(v[..., 3:6] - v[..., :3], axis=-1) < MIN_BONE_M) | (v[..., 6] <= 0)
    if bad.any():
        f, c = np.argwhere(bad)[0]
        what = "its radius is not > 0" if v[f, c, 6] <= 0 else "its two ends coincide"
        raise LogError(f"{path}: line {frames.line[f]}: capsule {CAPSULES[c]} at time={frames.time_s[f]:.9g}: {what}")
    return frames


def _dataset_hand(root: Path) -> HandModel | None:
    if not (root / DEFINITION).is_file():
        return None
    from sphri.hand.capsules import HandCapsules

    hand = HandCapsules(definition_path=str(root / DEFINITION)).build()
    if tuple(hand.names) != CAPSULES:
        raise LogError(
            f"{root / DEFINITION}: its capsules {list(hand.names)[:4]}... are not the 19 capsules the import makes "
            f"({', '.join(CAPSULES)}): import into another folder"
        )
    return hand


def _size_note(label: str, hand: HandModel, ref: HandModel) -> str:
    dc = np.abs(hand.segment_length_m - ref.segment_length_m).max() * 1000
    dr = np.abs(hand.radius_m - ref.radius_m).max() * 1000
    return f"{label}; the log's capsules differ from it by up to {dc:.2f} mm in core length, {dr:.2f} mm in radius"


def import_log(
    kind: str,
    log: str | Path,
    out: str | Path,
    link: str,
    participant: int,
    gesture: str,
    rate_hz: float = 30.0,
    hand: str = "right",
    hand_size: float = 1.0,
    link_pose: str = "",
) -> Imported:
    """Check ``log`` (a ``kind`` of :data:`sphri.data.recording_schema.LOG_KINDS`), resample it to ``rate_hz``
    (Hz) and add it as one trial of ``gesture`` by participant number ``participant`` on ``link`` to the
    dataset ``out`` (see the module docstring); ``hand_size`` scales the documented hand (``openxr``).
    ``link_pose`` (``"x,y,z,qx,qy,qz,qw"``, the link's pose in the log's frame) takes a log recorded in the
    room's or a tracker's frame into the link's (:func:`sphri.recordings.frames.to_link_frame`); empty: the
    log is in the link's frame. Every problem of the log is one :class:`LogError` line naming the file, line
    and field."""
    path, root = Path(log), Path(out)
    spec = {"openxr": OPENXR_LOG, "ovr": OVR_CAPSULE_LOG, "capsules": CAPSULE_LOG}[kind]
    df = read_log(path, spec, optional=("hand",) if kind == "capsules" else ())
    check_hand(path, df, hand)
    existing = _dataset_hand(root)
    if kind == "openxr":
        frames = _openxr(path, df)
        model = documented_hand(hand_size)
        used = sorted({OPENXR_JOINTS.index(j) for bone in OPENXR_CAPSULES.values() for j in bone})
        check_metres(path, frames, "px, py, pz", frames.values[:, used, :3], model)
        if link_pose:
            frames = to_link_frame(frames, link_pose, (slice(0, 3),), quat=slice(3, 7))
        frames, report = resample(frames, rate_hz, quat=slice(3, 7))
        made, note = model, f"the documented hand model times hand_size={hand_size:g}"
    else:
        frames = _segments(path, _ovr_names(path, df) if kind == "ovr" else df)
        v = frames.values
        logged = hand_from_segments(CAPSULES, v[..., :3], v[..., 3:6], v[..., 6])
        check_metres(path, frames, "the capsule ends", v[..., :6].reshape(len(v), -1, 3), documented_hand())
        if link_pose:
            frames = to_link_frame(frames, link_pose, (slice(0, 3), slice(3, 6)))
        frames, report = resample(frames, rate_hz)
        spread = np.abs(np.linalg.norm(v[..., 3:6] - v[..., :3], axis=-1) - logged.segment_length_m).max() * 1000
        made, note = logged, f"the log's median capsule sizes (a capsule's length varies by up to {spread:.2f} mm)"
    use = made if existing is None else existing
    if existing is not None:
        note = _size_note("the dataset's hand model", made, existing)
    if kind == "openxr":
        poses = openxr_poses(frames.values, use)
    else:
        poses = segment_poses(frames.values[..., :3], frames.values[..., 3:6], use)
    pid = participant_id(participant)
    files: list[Path] = []
    if existing is None:
        (root / DEFINITION).parent.mkdir(parents=True, exist_ok=True)
        write_hand_definition(use, root / DEFINITION)
        files.append(root / DEFINITION)
    source = {"kind": kind, "file": path.name, "hand": hand, **report}
    if link_pose:
        source["link_pose"] = link_pose
    ordinal, written = append_trial(root, link, pid, gesture, poses, CAPSULES, rate_hz, source)
    return Imported(root, link, pid, ordinal, gesture, report, note, files + written)
