"""The on-disk layout of the VR gesture dataset, shared by reader and writer.

Layout (``dakaraisc/VR-gesture-dataset``)::

    ROOT/
      assets/arm_mesh.obj, torso_mesh.obj, hand_capsule_definition.json
      {region}/participant_XX/participant_XX.parquet            one row per (trial, frame)
      {region}/participant_XX/participant_XX_manifest.json      one entry per trial

Parquet columns: :data:`META_COLUMNS` then, for every capsule ``c`` of the
hand, ``c_pos_x/y/z`` (metres, link frame) and ``c_rot_x/y/z/w`` (unit
quaternion, same frame); every column and manifest field is listed in
:mod:`sphri.data.recording_schema` (``docs/RECORDING_FORMAT.md``). A manifest written by sphri carries
``"generator": "sphri.synthetic"`` (:data:`GENERATOR_KEY`), which makes the
loader label the dataset synthetic.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri.data import recording_schema as schema
from sphri.errors import read_json
from sphri.types import TRIAL_COLUMNS, HandModel, Link

#: Per-row metadata columns of a participant's parquet file (:data:`recording_schema.GESTURE_META`).
META_COLUMNS: tuple[str, ...] = schema.names(schema.GESTURE_META)
#: Metadata columns holding text, and those holding integers.
STRING_COLUMNS: tuple[str, ...] = schema.of_dtype(schema.GESTURE_META, "string")
INTEGER_COLUMNS: tuple[str, ...] = schema.of_dtype(schema.GESTURE_META, "integer")

#: Suffixes of a capsule's seven pose columns, in ``GestureDataset.poses`` order.
POSE_SUFFIXES: tuple[str, ...] = schema.POSE_SUFFIXES

#: Keys every manifest must have, and every manifest trial entry.
MANIFEST_KEYS: tuple[str, ...] = schema.required(schema.GESTURE_MANIFEST)
MANIFEST_TRIAL_KEYS: tuple[str, ...] = schema.required(schema.GESTURE_TRIAL)
#: The format version sphri writes into manifests (``format_version``; absent = 1).
FORMAT_VERSION = schema.GESTURE_FORMAT_VERSION

#: Manifest key (and its value) that marks a dataset written by sphri's generator.
GENERATOR_KEY = "generator"
GENERATOR_VALUE = "sphri.synthetic"

PARTICIPANT_RE = re.compile(r"^participant_(\d{2,})$")


def participant_id(number: int) -> str:
    """``participant_XX`` for a 1-based participant number."""
    return f"participant_{number:02d}"


def trial_id(ordinal: int, gesture: str) -> str:
    """``0001_stroke``: 4-digit ordinal and gesture label."""
    return f"{ordinal:04d}_{gesture}"


def pose_columns(names: Sequence[str]) -> list[str]:
    """The 7 * C pose columns for capsule ``names``, in poses order."""
    return [f"{n}_{s}" for n in names for s in POSE_SUFFIXES]


def participant_dir(root: Path, region: str, pid: str) -> Path:
    return Path(root) / region / pid


def parquet_path(root: Path, region: str, pid: str) -> Path:
    return participant_dir(root, region, pid) / f"{pid}.parquet"


def manifest_path(root: Path, region: str, pid: str) -> Path:
    return participant_dir(root, region, pid) / f"{pid}_manifest.json"


def make_trials_frame(records: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """A :attr:`GestureDataset.trials` table with :data:`TRIAL_COLUMNS` and fixed dtypes."""
    df = pd.DataFrame.from_records(list(records), columns=list(TRIAL_COLUMNS))
    for col in ("participant", "region", "trial_id", "gesture"):
        df[col] = df[col].astype(object)
    for col in ("trial_ordinal", "start", "n_frames"):
        df[col] = df[col].astype(np.int64)
    return df.reset_index(drop=True)


class ManifestError(ValueError):
    """A manifest is malformed or disagrees with its parquet file; names the file and trial."""


def read_manifest(path: Path) -> dict[str, Any]:
    """Read and structurally validate one ``participant_XX_manifest.json``.

    Checks the keys, that ``num_trials``/``num_frames_total`` agree with the
    trial list, that ordinals are unique positive integers, frame counts are
    non-negative integers, and ``trial_id`` is ``{ordinal:04d}_{gesture}``.
    Gesture labels are checked by the caller (it knows the allowed set).
    """
    path = Path(path)
    m = read_json(path, ManifestError, f"manifest not found: {path}", obj=True)
    missing = [k for k in MANIFEST_KEYS if k not in m]
    if missing:
        raise ManifestError(f"{path}: missing keys {missing}")
    trials = m["trials"]
    if not isinstance(trials, list):
        raise ManifestError(f"{path}: 'trials' must be a list, got {type(trials).__name__}")
    seen: set[int] = set()
    for i, t in enumerate(trials):
        if not isinstance(t, dict):
            raise ManifestError(f"{path}: trials[{i}] must be an object")
        miss = [k for k in MANIFEST_TRIAL_KEYS if k not in t]
        if miss:
            raise ManifestError(f"{path}: trials[{i}] misses keys {miss}")
        o, n = t["trial_ordinal"], t["frame_count"]
        if isinstance(o, bool) or not isinstance(o, int) or o < 1:
            raise ManifestError(f"{path}: trials[{i}].trial_ordinal={o!r} must be a positive integer")
        if o in seen:
            raise ManifestError(f"{path}: trial_ordinal {o} appears twice")
        seen.add(o)
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ManifestError(f"{path}: trial {o}: frame_count={n!r} must be a non-negative integer")
        for k in ("start_frame", "end_frame"):
            v = t.get(k, 0)
            if isinstance(v, bool) or not isinstance(v, int) or abs(v) >= 2**62:
                raise ManifestError(f"{path}: trial {o}: {k}={v!r} must be an integer (a frame number)")
        g = t["gesture_label"]
        if not isinstance(g, str):
            raise ManifestError(f"{path}: trial {o}: gesture_label={g!r} must be a string")
        if t["trial_id"] != trial_id(o, g):
            raise ManifestError(
                f"{path}: trial {o}: trial_id={t['trial_id']!r} disagrees with ordinal and gesture "
                f"(expected {trial_id(o, g)!r})"
            )
    version = m.get("format_version", 1)
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= FORMAT_VERSION:
        raise ManifestError(
            f"{path}: format_version={version!r}: this sphri reads versions 1..{FORMAT_VERSION} "
            "(docs/RECORDING_FORMAT.md)"
        )
    if "frame_rate_hz" in m:
        rate = m["frame_rate_hz"]
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not (1.0 <= rate <= 1000.0):
            raise ManifestError(f"{path}: frame_rate_hz={rate!r} is implausible: must be a number in [1, 1000] Hz")
    if m["num_trials"] != len(trials):
        raise ManifestError(f"{path}: num_trials={m['num_trials']} but {len(trials)} trials are listed")
    total = sum(int(t["frame_count"]) for t in trials)
    if m["num_frames_total"] != total:
        raise ManifestError(
            f"{path}: num_frames_total={m['num_frames_total']} but the trials' frame_count sum to {total}"
        )
    return m


def write_hand_definition(hand: HandModel, path: Path) -> None:
    """Write ``hand_capsule_definition.json`` in the study's (Unity) convention."""
    entries = []
    for i, name in enumerate(hand.names):
        bone = "wrist" if hand.fingers[i] == "palm" else name
        off = hand.center_offset_m[i]
        entries.append(
            {
                "capsule_index": i + 1,
                "column_prefix": name,
                "source_name": f"b_r_{bone}_CapsuleCollider",
                "height_m": float(hand.height_m[i]),
                "radius_m": float(hand.radius_m[i]),
                "orientation": float(hand.axis[i]),
                "center_offset_m": {"x": float(off[0]), "y": float(off[1]), "z": float(off[2])},
            }
        )
    Path(path).write_text(json.dumps(entries, indent=2) + "\n")


def write_obj(link: Link, path: Path) -> None:
    """Write a link's triangle mesh as a Wavefront OBJ (metres, link frame)."""
    lines = [f"# sphri link mesh: {link.name} (metres, link frame)", f"# Vertices: {len(link.vertices)}"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in np.asarray(link.vertices, dtype=np.float64)]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(link.faces, dtype=np.int64)]
    Path(path).write_text("\n".join(lines) + "\n")
