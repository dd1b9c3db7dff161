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
    manifest_path,
    parquet_path,
    pose_columns,
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
        link = robot.link_for(region)
        path = assets / f"{region}_mesh.obj"
        write_obj(link, path)
        written.append(path)
    names = dataset.hand.names
    cols = pose_columns(names)
    for (pid, region), group in trials.groupby(["participant", "region"], sort=False):
        link = robot.link_for(region)
        written += _write_participant(dataset, group, out, str(pid), str(region), link.name, cols, meta)
    log.info("wrote %d trials (%d frames) to %s", len(trials), dataset.n_frames, out)
    return written


def _write_participant(
    dataset, group, out: Path, pid: str, region: str, link_name: str, cols: list[str], meta: dict[str, Any] | None
) -> list[Path]:
    group = group.sort_values("trial_ordinal")
    starts = group["start"].to_numpy(np.int64)
    counts = group["n_frames"].to_numpy(np.int64)
    rows = (
        np.concatenate([np.arange(s, s + n) for s, n in zip(starts, counts)]) if len(group) else np.zeros(0, np.int64)
    )
    poses = dataset.poses[rows].reshape(len(rows), -1).astype(np.float32, copy=False)
    ordinals = group["trial_ordinal"].to_numpy(np.int64)
    # session frame numbers: trials back to back from 1, like the study's manifests
    first = 1 + np.concatenate([[0], np.cumsum(counts)[:-1]]) if len(group) else np.zeros(0, np.int64)
    within = (
        np.arange(len(rows)) - np.repeat(np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) if len(group) else rows
    )
    arrays = {
        "trial_id": pa.array(np.repeat(group["trial_id"].to_numpy(object), counts).tolist(), pa.string()),
        "trial_ordinal": pa.array(np.repeat(ordinals, counts), pa.int64()),
        "gesture_label": pa.array(np.repeat(group["gesture"].to_numpy(object), counts).tolist(), pa.string()),
        "frame": pa.array(np.repeat(first, counts) + within, pa.int64()),
        "frame_index_in_trial": pa.array(within, pa.int64()),
    }
    for j, c in enumerate(cols):
        arrays[c] = pa.array(poses[:, j], pa.float32())
    table = pa.table(arrays)
    ppath = parquet_path(out, region, pid)
    ppath.parent.mkdir(parents=True, exist_ok=True)
    # page CRCs: a flipped bit in a data page is an error when read, not a silently changed pose
    pq.write_table(table, ppath, row_group_size=ROW_GROUP_ROWS, compression="zstd", write_page_checksum=True)
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
