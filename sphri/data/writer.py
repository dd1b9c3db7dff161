"""Write a :class:`GestureDataset` to disk in the VR gesture dataset's layout.

The written folder loads with ``data=vr_gesture data.root=DIR`` and gives the
same trials and bit-identical poses (float32 in both). Manifests of a
synthetic dataset carry ``"generator": "sphri.synthetic"`` plus the frame
rate and the generator's settings, so the loader labels it synthetic.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from sphri.data.format import (
    FORMAT_VERSION,
    GENERATOR_KEY,
    GENERATOR_VALUE,
    META_COLUMNS,
    ManifestError,
    manifest_path,
    parquet_path,
    pose_columns,
    read_manifest,
    trial_id,
    write_hand_definition,
    write_obj,
)
from sphri.types import GestureDataset, Robot

log = logging.getLogger(__name__)

#: Rows per parquet row group (about 9 trials).
ROW_GROUP_ROWS = 1024


def write_dataset(
    dataset: GestureDataset, robot: Robot, out: str | Path, meta: dict[str, Any] | None = None
) -> list[Path]:
    """Write ``dataset`` under ``out`` (parquet + manifest per participant and region, ``assets/``).

    ``assets/`` gets ``hand_capsule_definition.json`` (Unity convention) and
    ``{region}_mesh.obj`` for every skin region of the robot (its link's
    mesh, metres, link frame), so ``robot=reachy_vr`` finds both hulls. ``meta`` is added to every manifest of a synthetic dataset (e.g. the
    generator's config). Returns the files written.
    """
    out = Path(out)
    written: list[Path] = []
    assets = out / "assets"
    assets.mkdir(parents=True, exist_ok=True)
    hand_path = assets / "hand_capsule_definition.json"
    write_hand_definition(dataset.hand, hand_path)
    written.append(hand_path)
    trials = dataset.trials
    # every skin region's mesh, like the study's assets (arm_mesh.obj, torso_mesh.obj), touched or not
    regions = list(dict.fromkeys(list(robot.regions) + trials["region"].tolist()))
    for region in regions:
        path = assets / f"{region}_mesh.obj"
        write_obj(robot.link_for(region), path)
        written.append(path)
    cols = pose_columns(dataset.hand.names)
    for (pid, region), group in trials.groupby(["participant", "region"], sort=False):
        link_name = robot.link_for(region).name
        written += _write_participant(dataset, group, out, str(pid), str(region), link_name, cols, meta)
    log.info("wrote %d trials (%d frames) to %s", len(trials), dataset.n_frames, out)
    return written


def _write_participant(
    dataset, group, out: Path, pid: str, region: str, link_name: str, cols: list[str], meta: dict[str, Any] | None
) -> list[Path]:
    group = group.sort_values("trial_ordinal")
    starts = group["start"].to_numpy(np.int64)
    counts = group["n_frames"].to_numpy(np.int64)
    rows = np.concatenate([np.arange(s, s + n) for s, n in zip(starts, counts)])  # a group is never empty
    poses = dataset.poses[rows].reshape(len(rows), -1).astype(np.float32, copy=False)
    ordinals = group["trial_ordinal"].to_numpy(np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]])
    # session frame numbers: trials back to back from 1, like the study's manifests
    first = 1 + offsets
    within = np.arange(len(rows)) - np.repeat(offsets, counts)
    columns = (
        np.repeat(group["trial_id"].to_numpy(object), counts).tolist(),
        np.repeat(ordinals, counts),
        np.repeat(group["gesture"].to_numpy(object), counts).tolist(),
        np.repeat(first, counts) + within,
        within,
    )
    table = _table(columns, poses, cols)
    ppath = parquet_path(out, region, pid)
    _write_parquet(table, ppath)
    manifest: dict[str, Any] = {
        "participant_id": pid,
        "body_region": region,
        "format_version": FORMAT_VERSION,
        "reference_mesh": link_name,
        "num_trials": int(len(group)),
        "num_frames_total": int(counts.sum()),
        "trials": [
            {
                "trial_ordinal": int(o),
                "trial_id": str(t),
                "gesture_label": str(g),
                "frame_count": int(n),
                "start_frame": int(f),
                "end_frame": int(f + n - 1),
                "reference_pose_max_jitter_m": 0.0,
                "reference_pose_max_jitter_deg": 0.0,
                "used_per_frame_fallback": False,
            }
            for o, t, g, n, f in zip(ordinals, group["trial_id"], group["gesture"], counts, first)
        ],
    }
    manifest["frame_rate_hz"] = float(dataset.frame_rate_hz)
    if dataset.synthetic:
        manifest[GENERATOR_KEY] = GENERATOR_VALUE
        if meta:
            manifest["generator_config"] = meta
    mpath = manifest_path(out, region, pid)
    mpath.write_text(json.dumps(manifest, indent=2) + "\n")
    return [ppath, mpath]


def append_trial(
    root: str | Path,
    region: str,
    pid: str,
    gesture: str,
    poses: np.ndarray,
    hand_names: tuple[str, ...],
    frame_rate_hz: float,
    source: dict[str, Any] | None = None,
) -> tuple[int, list[Path]]:
    """Add one trial of ``poses`` (F, C, 7), metres and quaternions xyzw in the link frame, to participant
    ``pid`` in ``region`` of the gesture-trial dataset ``root`` (its files made when absent). The trial takes
    the next ordinal and frame numbers; ``source`` goes into its manifest entry. A participant recorded at
    another ``frame_rate_hz``, or with other capsules, is refused (:class:`ManifestError`). Returns the
    trial's ordinal and the files written."""
    root = Path(root)
    mpath, ppath = manifest_path(root, region, pid), parquet_path(root, region, pid)
    poses = np.asarray(poses, dtype=np.float32)
    cols = pose_columns(hand_names)
    if mpath.is_file():
        manifest = read_manifest(mpath)
        rate = manifest.get("frame_rate_hz")
        if rate is not None and float(rate) != float(frame_rate_hz):
            raise ManifestError(
                f"{mpath}: frame_rate_hz={rate} but this trial is at {frame_rate_hz:g} Hz: one rate per dataset"
            )
        old = pq.read_table(ppath)
        missing = [c for c in cols if c not in old.column_names]
        if missing:
            raise ManifestError(f"{ppath}: has no column(s) {missing[:5]}: its hand has other capsules")
    else:
        manifest = {
            "participant_id": pid,
            "body_region": region,
            "format_version": FORMAT_VERSION,
            "num_trials": 0,
            "num_frames_total": 0,
            "trials": [],
        }
        old = None
    trials = manifest["trials"]
    ordinal = max((int(t["trial_ordinal"]) for t in trials), default=0) + 1
    first = max((int(t.get("end_frame", 0)) for t in trials), default=0) + 1
    n = len(poses)
    tid = trial_id(ordinal, gesture)
    columns = ([tid] * n, np.full(n, ordinal), [gesture] * n, first + np.arange(n), np.arange(n))
    table = _table(columns, poses.reshape(n, -1), cols)
    if old is not None:
        table = pa.concat_tables([old.select(table.column_names).cast(table.schema), table])
    entry: dict[str, Any] = {
        "trial_ordinal": ordinal,
        "trial_id": tid,
        "gesture_label": gesture,
        "frame_count": n,
        "start_frame": int(first),
        "end_frame": int(first + n - 1),
    }
    if source:
        entry["source"] = source
    trials.append(entry)
    manifest.update(
        format_version=FORMAT_VERSION,
        num_trials=len(trials),
        num_frames_total=int(sum(int(t["frame_count"]) for t in trials)),
        frame_rate_hz=float(frame_rate_hz),
    )
    _write_parquet(table, ppath)
    mpath.write_text(json.dumps(manifest, indent=2) + "\n")
    return ordinal, [ppath, mpath]


def _table(columns: tuple, poses: np.ndarray, cols: list[str]) -> pa.Table:
    """A participant file's table: ``columns``, the per-row values of :data:`META_COLUMNS` in their order, then the
    pose columns ``cols`` of ``poses`` (R, 7 * C) float32."""
    types = (pa.string(), pa.int64(), pa.string(), pa.int64(), pa.int64())
    arrays = {c: pa.array(v, t) for c, v, t in zip(META_COLUMNS, columns, types)}
    for j, c in enumerate(cols):
        arrays[c] = pa.array(poses[:, j], pa.float32())
    return pa.table(arrays)


def _write_parquet(table: pa.Table, ppath: Path) -> None:
    ppath.parent.mkdir(parents=True, exist_ok=True)
    # page CRCs: a flipped bit in a data page is an error when read, not a silently changed pose
    pq.write_table(table, ppath, row_group_size=ROW_GROUP_ROWS, compression="zstd", write_page_checksum=True)
