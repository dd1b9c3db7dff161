"""The recording formats, stated once: columns, manifest and header fields, versions.

sphri reads two kinds of recordings, and imports three kinds of hand-tracking logs:

- *gesture trials* on one robot link (``data=vr_gesture``; what ``sphri synthesize`` and
  ``sphri import`` write), :data:`GESTURE_COLUMNS`, :data:`GESTURE_MANIFEST` and
  :data:`GESTURE_TRIAL`;
- *whole-body sessions* (``data=sessions``), :data:`SESSION_COLUMNS`, :data:`SESSION_HEADER` and
  :data:`SESSION_MANIFEST`;
- the logs ``sphri import`` reads: :data:`OPENXR_LOG`, :data:`OVR_CAPSULE_LOG` and
  :data:`CAPSULE_LOG`.

The loaders (:mod:`sphri.data.format`, :mod:`sphri.data.vr_gesture`, :mod:`sphri.sessions.format`)
take their column and field lists from here, and ``docs/RECORDING_FORMAT.md`` is generated from it::

    python -m sphri.data.recording_schema --markdown > docs/RECORDING_FORMAT.md

(a maintainer's tool, not a verb of ``sphri``; ``tests/data/test_recording_schema.py`` fails when the
page is stale).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Version of the gesture-trial format that sphri writes (manifest key ``format_version``).
GESTURE_FORMAT_VERSION = 2
#: Version of the session format (header key ``version``).
SESSION_FORMAT = "sphri-sessions"
SESSION_FORMAT_VERSION = 1

#: The frame of each pose, as the page names it.
LINK_FRAME = "link"
WORLD_FRAME = "world"


@dataclass(frozen=True)
class Column:
    """One column (or a pattern of columns, ``{capsule}`` etc.) of a table."""

    name: str
    dtype: str
    """``string``, ``integer`` or ``float`` (what a reader accepts); :attr:`written` is what sphri writes."""
    written: str
    unit: str
    frame: str
    meaning: str


@dataclass(frozen=True)
class Field:
    """One field of a JSON manifest or header."""

    name: str
    type: str
    required: bool
    meaning: str


@dataclass(frozen=True)
class Version:
    number: int
    changes: str


#: Suffixes of a capsule's seven pose columns: position (m) then quaternion (x, y, z, w).
POSE_SUFFIXES: tuple[str, ...] = ("pos_x", "pos_y", "pos_z", "rot_x", "rot_y", "rot_z", "rot_w")


def _pose_columns(prefix: str, frame: str, what: str) -> tuple[Column, ...]:
    return (
        Column(f"{prefix}_pos_x/y/z", "float", "float32", "m", frame, f"position of {what}"),
        Column(
            f"{prefix}_rot_x/y/z/w", "float", "float32", "unit quaternion (x, y, z, w)", frame, f"rotation of {what}"
        ),
    )


GESTURE_META: tuple[Column, ...] = (
    Column("trial_id", "string", "string", "-", "-", "`{trial_ordinal:04d}_{gesture_label}`, e.g. `0001_stroke`"),
    Column("trial_ordinal", "integer", "int64", "-", "-", "1-based trial index within the participant (the key)"),
    Column("gesture_label", "string", "string", "-", "-", "hit, pat, poke, push, rub, stroke, tap or grab"),
    Column("frame", "integer", "int64", "frame", "-", "source frame number (session-relative), rising in a trial"),
    Column("frame_index_in_trial", "integer", "int64", "frame", "-", "0-based frame index within the trial"),
)
#: Every column of a participant's ``participant_XX.parquet``: one row per (trial, frame).
GESTURE_COLUMNS: tuple[Column, ...] = GESTURE_META + _pose_columns(
    "{capsule}", LINK_FRAME, "the capsule's joint (centre = pos + R(q) @ center_offset)"
)

GESTURE_MANIFEST: tuple[Field, ...] = (
    Field("participant_id", "string", True, "`participant_XX`, the folder's name"),
    Field("body_region", "string", True, "the robot region (link) the trials touch, the parent folder's name"),
    Field("num_trials", "integer", True, "number of entries of `trials`"),
    Field("num_frames_total", "integer", True, "sum of the trials' `frame_count`, the parquet file's row count"),
    Field("trials", "list of objects", True, "one entry per trial (below)"),
    Field("format_version", "integer", False, f"format version ({GESTURE_FORMAT_VERSION}); absent means 1"),
    Field("frame_rate_hz", "number", False, "frame rate in Hz, in [1, 1000]; absent means 30 Hz"),
    Field("reference_mesh", "string", False, "name of the robot link whose frame the poses are in"),
    Field("generator", "string", False, "`sphri.synthetic` for generated data (the loader labels it synthetic)"),
    Field("generator_config", "object", False, "the generator's settings (synthetic data)"),
)
GESTURE_TRIAL: tuple[Field, ...] = (
    Field("trial_ordinal", "integer", True, "positive, unique within the participant"),
    Field("trial_id", "string", True, "`{trial_ordinal:04d}_{gesture_label}`"),
    Field("gesture_label", "string", True, "the trial's gesture"),
    Field("frame_count", "integer", True, "the trial's rows in the parquet file"),
    Field("start_frame", "integer", False, "first value of the trial's `frame` column"),
    Field("end_frame", "integer", False, "last value of the trial's `frame` column"),
    Field("reference_pose_max_jitter_m", "number", False, "how far the compliant robot link moved (m)"),
    Field("reference_pose_max_jitter_deg", "number", False, "how far the robot link turned (degrees)"),
    Field("used_per_frame_fallback", "boolean", False, "the study's per-frame reference-pose fallback was used"),
    Field("source", "object", False, "what `sphri import` read: log kind, file, hand, resampling (frame counts)"),
)
GESTURE_VERSIONS: tuple[Version, ...] = (
    Version(
        1,
        "the reference study's release (dakaraisc/VR-gesture-dataset): parquet columns and manifest as above, "
        "without `format_version`, `frame_rate_hz`, `generator`, `generator_config` and the trials' `source`",
    ),
    Version(
        2,
        "manifests may carry `format_version`, `frame_rate_hz` (else 30 Hz) and `generator`/`generator_config` "
        "(synthetic data), trial entries `source` (imported logs); `assets/hand_capsule_definition.json` holds the "
        "hand model the poses were made for",
    ),
)

SESSION_COLUMNS: tuple[Column, ...] = (
    Column("repetition", "integer", "int16", "-", "-", "the session's repetition (manifest `repetition`)"),
    Column("frame", "integer", "int32", "frame", "-", "0..n-1 within the session"),
    *_pose_columns("{hand}/{capsule}", WORLD_FRAME, "a hand's capsule joint (hand: left, right)"),
    *_pose_columns("link/{link}", WORLD_FRAME, "the robot link's frame"),
)
SESSION_HEADER: tuple[Field, ...] = (
    Field("format", "string", True, f"`{SESSION_FORMAT}`"),
    Field("version", "integer", True, f"format version ({SESSION_FORMAT_VERSION})"),
    Field("name", "string", True, "the dataset's name"),
    Field("synthetic", "boolean", True, "true for generated data"),
    Field("robot", "string", True, "the robot config the links belong to"),
    Field("links", "list of strings", True, "the links whose poses are recorded, unique"),
    Field("hands", "list of strings", True, '`["left", "right"]`, the order of the hand columns'),
    Field("hand", "object", True, "the hand model: names, fingers, radius_m, height_m, axis, center_offset_m"),
    Field("frame_rate_hz", "number", False, "frame rate in Hz"),
)
SESSION_MANIFEST: tuple[Field, ...] = (
    Field("scenario", "string", True, "the scenario's name"),
    Field("repetition", "integer", True, ">= 1; with `scenario`, unique in the manifest"),
    Field("order", "integer", True, ">= 0, the session's place in the participant's visit"),
    Field("start_position", "string", True, "where the participant started"),
    Field("frame_rate_hz", "number", True, "frame rate in Hz, in [1, 1000]; one rate per dataset"),
    Field("n_frames", "integer", True, "the repetition's rows in `file`"),
    Field("file", "string", True, "parquet file inside the participant's folder (no absolute path, no `..`)"),
)
SESSION_VERSIONS: tuple[Version, ...] = (
    Version(1, "`sessions.json`, `participant_XX/manifest.json` and one parquet file per scenario, as above"),
)

# ----------------------------------------------------------------------------------------------- import logs
#: The 26 joints of ``XR_EXT_hand_tracking`` in ``XrHandJointEXT`` order (the integer ids 0..25).
OPENXR_JOINTS: tuple[str, ...] = (
    "palm",
    "wrist",
    "thumb_metacarpal",
    "thumb_proximal",
    "thumb_distal",
    "thumb_tip",
    *(
        f"{f}_{j}"
        for f in ("index", "middle", "ring", "little")
        for j in ("metacarpal", "proximal", "intermediate", "distal", "tip")
    ),
)
#: Capsule -> (joint, joint): a finger capsule is the bone between two consecutive joints; a palm capsule
#: (one joint) starts at that metacarpal joint and runs along the joint's forward axis (OpenXR -Z).
OPENXR_CAPSULES: dict[str, tuple[str, ...]] = {
    "wrist1": ("index_metacarpal",),
    "wrist2": ("middle_metacarpal",),
    "wrist3": ("ring_metacarpal",),
    "wrist4": ("little_metacarpal",),
    "thumb1": ("thumb_metacarpal", "thumb_proximal"),
    "thumb2": ("thumb_proximal", "thumb_distal"),
    "thumb3": ("thumb_distal", "thumb_tip"),
    **{
        f"{c}{k}": (f"{f}_{a}", f"{f}_{b}")
        for c, f in (("index", "index"), ("middle", "middle"), ("ring", "ring"), ("pinky", "little"))
        for k, (a, b) in enumerate((("proximal", "intermediate"), ("intermediate", "distal"), ("distal", "tip")), 1)
    },
}
#: ``OVRSkeleton.BoneId`` names of capsule-carrying bones -> capsule name stem (wrist: wrist1..4 in
#: ``capsule_index`` order; the others: thumb1..3 from Hand_Thumb1..3 and so on).
OVR_BONES: dict[str, str] = {
    "Hand_WristRoot": "wrist",
    **{
        f"Hand_{b}{k}": f"{c}{k}"
        for b, c in (("Thumb", "thumb"), ("Index", "index"), ("Middle", "middle"), ("Ring", "ring"), ("Pinky", "pinky"))
        for k in (1, 2, 3)
    },
}
HANDS: tuple[str, ...] = ("left", "right")
#: A log's interval between frames longer than this many median intervals is a tracking gap.
GAP_FACTOR = 1.5
#: The kinds of log ``sphri import`` reads, with their column specs below.
LOG_KINDS: tuple[str, ...] = ("openxr", "ovr", "capsules")

OPENXR_LOG: tuple[Column, ...] = (
    Column("time", "float", "float64", "s", "-", "timestamp of the frame; rows of one frame share it"),
    Column("hand", "string", "string", "-", "-", "left or right"),
    Column("joint", "string", "string", "-", "-", "an `XrHandJointEXT` name (`index_tip`) or its id 0..25"),
    Column("px, py, pz", "float", "float64", "m", LINK_FRAME, "joint position"),
    Column(
        "qx, qy, qz, qw",
        "float",
        "float64",
        "unit quaternion (x, y, z, w)",
        LINK_FRAME,
        "joint orientation (OpenXR: -Z along the bone towards the fingertip, +Y out of the back of the hand)",
    ),
)
OVR_CAPSULE_LOG: tuple[Column, ...] = (
    Column("time", "float", "float64", "s", "-", "timestamp of the frame"),
    Column("hand", "string", "string", "-", "-", "left or right"),
    Column("capsule_index", "integer", "int64", "-", "-", "index into `OVRSkeleton.Capsules`"),
    Column("bone_id", "string", "string", "-", "-", "`OVRSkeleton.BoneId` name of the capsule's bone"),
    Column("start_x, start_y, start_z", "float", "float64", "m", LINK_FRAME, "capsule start point (core segment)"),
    Column("end_x, end_y, end_z", "float", "float64", "m", LINK_FRAME, "capsule end point (core segment)"),
    Column("radius", "float", "float64", "m", "-", "capsule radius"),
)
CAPSULE_LOG: tuple[Column, ...] = (
    Column("time", "float", "float64", "s", "-", "timestamp of the frame"),
    Column("hand", "string", "string", "-", "-", "optional: left or right"),
    Column("capsule", "string", "string", "-", "-", "capsule name of the hand model (`index2`)"),
    Column("p0_x, p0_y, p0_z", "float", "float64", "m", LINK_FRAME, "one end of the capsule's core segment"),
    Column("p1_x, p1_y, p1_z", "float", "float64", "m", LINK_FRAME, "the other end"),
    Column("radius", "float", "float64", "m", "-", "capsule radius"),
)


def names(columns: Sequence[Column]) -> tuple[str, ...]:
    """The plain (non-pattern) column names of ``columns``."""
    return tuple(c.name for c in columns if "{" not in c.name)


def of_dtype(columns: Sequence[Column], dtype: str) -> tuple[str, ...]:
    """The plain column names of ``columns`` whose readers accept ``dtype``."""
    return tuple(c.name for c in columns if "{" not in c.name and c.dtype == dtype)


def required(fields: Sequence[Field]) -> tuple[str, ...]:
    return tuple(f.name for f in fields if f.required)


# ----------------------------------------------------------------------------------------------- the page
def _table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join(" --- " for _ in header) + "|"]
    out += ["| " + " | ".join(str(v) for v in r) + " |" for r in rows]
    return out


def _columns(cols: Sequence[Column]) -> list[str]:
    return _table(
        ("column", "dtype (read)", "written as", "unit", "frame", "meaning"),
        [(f"`{c.name}`", c.dtype, c.written, c.unit, c.frame, c.meaning) for c in cols],
    )


def _fields(fields: Sequence[Field]) -> list[str]:
    return _table(
        ("field", "type", "required", "meaning"),
        [(f"`{f.name}`", f.type, "yes" if f.required else "no", f.meaning) for f in fields],
    )


def documented_capsules() -> list[dict[str, Any]]:
    """The documented hand model's capsules (``conf/hand/quest_capsules.yaml``, the study's 19), as mappings."""
    from omegaconf import OmegaConf

    from sphri.config import CONF_DIR

    node = OmegaConf.to_container(OmegaConf.load(Path(CONF_DIR) / "hand" / "quest_capsules.yaml"))
    assert isinstance(node, dict)
    return list(node["capsules"])


def _hand_rows() -> list[tuple]:
    caps = documented_capsules()
    rows = []
    for c in caps:
        bones = OPENXR_CAPSULES.get(c["name"], ())
        rows.append(
            (
                f"`{c['name']}`",
                c["finger"],
                f"{c['radius_m'] * 1000:.2f}",
                f"{c['height_m'] * 1000:.2f}",
                f"{(c['height_m'] - 2 * c['radius_m']) * 1000:.2f}",
                "XYZ"[c["axis"]],
                ", ".join(f"{v * 1000:.2f}" for v in c["center_offset_m"]),
                " -> ".join(bones) if len(bones) == 2 else f"{bones[0]} (forward axis)" if bones else "-",
            )
        )
    return rows


#: The ``sphri import`` command and the frame its logs are in, the first paragraph of the page's log section.
IMPORT_PARAGRAPH = (
    "`sphri import KIND LOG out=DIR link=REGION participant=N gesture=G [rate_hz=30] [hand=right]",
    "[hand_size=1] [link_pose=x,y,z,qx,qy,qz,qw]` (KIND: openxr, ovr, capsules) adds the log as one trial to the gesture-trial dataset `DIR` (made when absent), resampled",
    "to `rate_hz`. Positions are metres in the link's frame; a log recorded in another frame (the room's, the",
    "headset's tracking space) gives the link's pose in that frame as `link_pose=x,y,z,qx,qy,qz,qw` (metres, a",
    "unit quaternion (x, y, z, w)), and the import takes every position and orientation into the link's frame",
    "(`p_link = R^T (p - t)`): the link must stand still during the log (a robot that moves needs its logs in",
    "the link's frame). The manifest keeps `link_pose` under the trial's `source`. CSV files have a header row; `.jsonl` files",
    "hold one object per row with the same keys (OpenXR: `position` [x, y, z] and `orientation`",
    "[x, y, z, w] instead of px..qw). A frame is the rows sharing one `time`.",
)


def _intro_lines() -> list[str]:
    """The lines of the page's title and the conventions every format shares; each section ends with a blank line."""
    return [
        "# Recording format",
        "",
        "<!-- generated by `python -m sphri.data.recording_schema --markdown` from sphri/data/recording_schema.py;"
        " edit that module, not this page -->",
        "",
        "sphri reads two kinds of recordings: **gesture trials** on one robot link (the layout of the VR gesture",
        "dataset; `data=vr_gesture data.root=DIR`) and **whole-body sessions** (`data=sessions data.root=DIR`).",
        "`sphri check-data DIR` checks a folder of either kind against this page; `sphri import` turns",
        "hand-tracking logs into gesture trials. Quaternions are (x, y, z, w), Hamilton, active: `R(q) @ v` takes a",
        "vector from the joint's local frame into the pose's frame. Positions are metres.",
        "",
        "Frames: **link** is the robot link's (mesh's) local frame, the frame the skin is designed on; **world** is",
        "the room, in which sessions also record every link's pose.",
        "",
    ]


def _format_lines(
    title: str,
    tree: Sequence[str],
    columns_intro: str,
    columns: Sequence[Column],
    field_tables: Sequence[tuple[str, Sequence[Field]]],
    versions: Sequence[Version],
) -> list[str]:
    """The lines of one recording format: its title, folder ``tree`` (below ``ROOT/``), parquet columns, each
    ``(label, fields)`` of its JSON files and its versions; each section ends with a blank line."""
    lines = [title, "", "```", "ROOT/", *tree, "```", "", columns_intro, "", *_columns(columns), ""]
    for label, fields in field_tables:
        lines += [label, "", *_fields(fields), ""]
    return lines + ["Versions:", "", *_table(("version", "what it is"), [(v.number, v.changes) for v in versions]), ""]


def _gesture_lines() -> list[str]:
    """The gesture-trial format: folder, parquet columns, manifest and versions."""
    return _format_lines(
        f"## Gesture trials (format version {GESTURE_FORMAT_VERSION})",
        [
            "  assets/hand_capsule_definition.json         the hand model (below), Unity convention",
            "  assets/{region}_mesh.obj                    the link's mesh (metres, link frame)",
            "  {region}/participant_XX/participant_XX.parquet            one row per (trial, frame)",
            "  {region}/participant_XX/participant_XX_manifest.json      one entry per trial",
        ],
        "Parquet columns, in this order; `{capsule}` is every capsule of the hand model, in its order:",
        GESTURE_COLUMNS,
        [("Manifest (`participant_XX_manifest.json`):", GESTURE_MANIFEST), ("Each entry of `trials`:", GESTURE_TRIAL)],
        GESTURE_VERSIONS,
    )


def _session_lines() -> list[str]:
    """The whole-body session format: folder, parquet columns, header, manifest and versions."""
    return _format_lines(
        f"## Whole-body sessions (`{SESSION_FORMAT}` version {SESSION_FORMAT_VERSION})",
        [
            "  sessions.json                       the dataset header",
            "  participant_XX/manifest.json        {participant, sessions: [one entry per session]}",
            "  participant_XX/<scenario>.parquet   one row per (repetition, frame)",
        ],
        "Parquet columns; `{hand}` is left then right, `{link}` every name of the header's `links`:",
        SESSION_COLUMNS,
        [("Header (`sessions.json`):", SESSION_HEADER), ("Each entry of a manifest's `sessions`:", SESSION_MANIFEST)],
        SESSION_VERSIONS,
    )


def _hand_lines() -> list[str]:
    """The lines of the hand model: how a capsule is placed, and the default capsules' sizes (mm); each section ends with a blank line."""
    return [
        "## The hand model",
        "",
        "A capsule is a segment with a radius, attached to a tracked joint. With the joint's pose (position `pos`,",
        "rotation `R`), its centre is `pos + R @ center_offset`, its axis is the joint-local axis `axis`, and its",
        "core segment (`height - 2 radius` long, Unity's `height` being tip to tip) is centred there. The default",
        "(`hand=quest_capsules`) is the reference study's 19 capsules of the Meta Quest right hand; a dataset's",
        "`assets/hand_capsule_definition.json` (`hand.definition_path=...`) replaces it. Sizes in mm; the last",
        "column is the OpenXR bone `sphri import openxr` makes the capsule from:",
        "",
        *_table(
            ("capsule", "finger", "radius", "height", "core", "axis", "center_offset (x, y, z)", "OpenXR bone"),
            _hand_rows(),
        ),
        "",
    ]


def _import_lines() -> list[str]:
    """The lines of the logs ``sphri import`` reads: how they become trials, what is refused, each log's columns; each section ends with a blank line."""
    return [
        "## Logs `sphri import` reads",
        "",
        *IMPORT_PARAGRAPH,
        "",
        "Each frame of the output lies at `k / rate_hz` after the log's first time; positions are interpolated",
        "linearly, orientations by slerp. The import says how many source frames it read and their median rate,",
        f"the tracking gaps (intervals over {GAP_FACTOR:g} median intervals) and the output frames interpolated",
        "across them, and how many source frames fewer downsampling made; the trial's manifest entry keeps these",
        "counts under `source`. The dataset keeps one hand model, `assets/hand_capsule_definition.json`: the first",
        "import writes it (`openxr`: the model below times `hand_size`; `ovr`, `capsules`: the log's median",
        "capsule sizes); later imports place their capsules with it and say how far the log's sizes differ. Load",
        "the result with `sphri data=vr_gesture data.root=DIR data.regions=[REGION]",
        "hand.definition_path=DIR/assets/hand_capsule_definition.json`.",
        "",
        "Refused, one line naming the file, line and field, exit 2: an empty or truncated file, a missing column,",
        "a value of the wrong type, a NaN or infinite value, time going back, a joint or capsule twice at one time",
        "(a duplicate frame), a frame missing a joint or capsule that a capsule needs, an unknown joint, bone or",
        "capsule, an unknown hand, mixed hands or another hand than `hand=`, positions that cannot be metres (a",
        "hand spanning 100 or 1000 times a hand: cm, mm), a time that cannot be seconds (frames less than 0.1 ms",
        "or more than 2 s apart: ms, ns), a zero quaternion, two joints of a bone at one place.",
        "",
        "`sphri.recordings.capsules.export_openxr(poses, hand, time_s, path)` writes capsule poses as an `openxr`",
        "log, placing each joint where consecutive capsules' bones meet; importing it gives back the capsule",
        "segments (within 2 µm for the synthetic hand's kinematics; the synthetic dataset's 0.3 mm per-capsule",
        "tracking noise does not fit 26 joints, and its contacts come back with distances within 1 mm).",
        "",
        "**`openxr`**: one row per joint and frame, the 26 joints of `XR_EXT_hand_tracking`. A finger capsule is",
        "the bone between two consecutive joints: centred on it, along it, the hand model's size times",
        "`hand_size`; a palm capsule starts at its metacarpal joint and runs along that joint's forward axis.",
        "",
        *_columns(OPENXR_LOG),
        "",
        "Joint ids: " + ", ".join(f"{i} `{j}`" for i, j in enumerate(OPENXR_JOINTS)) + ".",
        "",
        "**`ovr`**: one row per capsule and frame, as `OVRSkeleton.Capsules` gives them. Each capsule is taken as",
        "it is (core segment from start to end, its radius); the written hand model has their median sizes.",
        "",
        *_columns(OVR_CAPSULE_LOG),
        "",
        "Bones: " + ", ".join(f"`{b}`" for b in OVR_BONES) + " (`Hand_WristRoot` carries wrist1..4, in",
        "`capsule_index` order).",
        "",
        "**`capsules`**: a generic log of capsule segments, one row per capsule and frame, capsule names of the",
        "hand model. Taken as it is, like `ovr`.",
        "",
        *_columns(CAPSULE_LOG),
        "",
    ]


def markdown() -> str:
    """``docs/RECORDING_FORMAT.md``: the reference page of every format above."""
    sections = (_intro_lines, _gesture_lines, _session_lines, _hand_lines, _import_lines)
    return "\n".join(line for section in sections for line in section())


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m sphri.data.recording_schema --markdown``: print the reference page."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv != ["--markdown"]:
        print("usage: python -m sphri.data.recording_schema --markdown", file=sys.stderr)
        return 2
    sys.stdout.write(markdown())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
