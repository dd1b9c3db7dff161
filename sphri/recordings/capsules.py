"""Capsule poses from tracked joints or logged capsule segments, and the OpenXR joint log of capsule poses.

sphri stores a capsule as its joint's pose (position, quaternion xyzw) plus the hand model's radius,
height, axis and centre offset (:func:`sphri.hand.kinematics.capsule_segments`). Here the other way:

- :func:`openxr_poses`: from the 26 ``XR_EXT_hand_tracking`` joints. A finger capsule
  (:data:`sphri.data.recording_schema.OPENXR_CAPSULES`) is centred on the bone between two
  consecutive joints and points along it; its size is the hand model's. A palm capsule starts at its
  metacarpal joint and points along the joint's forward axis (OpenXR's -Z). The capsule frame's roll
  about its axis follows the first joint's orientation.
- :func:`segment_poses`: from logged capsule segments (p0, p1): centred on the segment, along it.
- :func:`export_openxr`: capsule poses as an OpenXR joint log, placing the joints where consecutive
  capsules' bones meet; importing that log gives back the same capsule segments.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from sphri.data.recording_schema import OPENXR_CAPSULES, OPENXR_JOINTS, documented_capsules
from sphri.hand.capsules import finger_of
from sphri.hand.kinematics import capsule_segments, quat_to_matrix
from sphri.types import HandModel

#: Rotation taking the capsule's local frame to the OpenXR joint frame's: ``R_capsule = R_joint @ Q``,
#: with ``Q @ e_axis = -e_z`` (the joint's forward axis), one per capsule axis 0/1/2 (X/Y/Z).
JOINT_TO_CAPSULE = np.array(
    [
        [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]],
        [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
        [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
    ]
)
#: Shortest bone (m) a capsule can point along.
MIN_BONE_M = 1e-6

#: Joint chains: (capsule names, joint names), a chain's k-th capsule on the bone from joint k to k + 1.
CHAINS: tuple[tuple[tuple[str, ...], tuple[str, ...]], ...] = tuple(
    (
        tuple(f"{c}{k}" for k in (1, 2, 3)),
        tuple(OPENXR_CAPSULES[f"{c}{k}"][0] for k in (1, 2, 3)) + (OPENXR_CAPSULES[f"{c}3"][1],),
    )
    for c in ("thumb", "index", "middle", "ring", "pinky")
)
PALM = ("wrist1", "wrist2", "wrist3", "wrist4")


def documented_hand(scale: float = 1.0) -> HandModel:
    """The documented hand model (``conf/hand/quest_capsules.yaml``, the study's 19 capsules) times ``scale``."""
    from sphri.hand.capsules import HandCapsules

    return HandCapsules(capsules=documented_capsules(), scale=scale).build()


def _align(rot: np.ndarray, axis: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``rot`` (N, 3, 3) turned by the shortest arc that takes its column ``axis`` (N,) onto ``d`` (N, 3, unit)."""
    a = rot[np.arange(len(rot)), :, axis]
    v = np.cross(a, d)
    s = np.linalg.norm(v, axis=1)
    c = np.einsum("ij,ij->i", a, d)
    angle = np.arctan2(s, c)
    with np.errstate(invalid="ignore", divide="ignore"):
        k = np.where(s[:, None] > 1e-12, v / s[:, None], 0.0)
    flip = (s <= 1e-12) & (c < 0)  # opposite: half a turn about any axis normal to a
    if flip.any():
        helper = np.where(np.abs(a[flip, 0:1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        k[flip] = np.cross(a[flip], helper)
        k[flip] /= np.linalg.norm(k[flip], axis=1, keepdims=True)
        angle[flip] = np.pi
    fix = Rotation.from_rotvec(k * angle[:, None]).as_matrix()
    return fix @ rot


def _pose(centre: np.ndarray, rot: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """(N, 7) poses of capsules with centre (N, 3), frame (N, 3, 3) and centre offset (N, 3)."""
    pos = centre - np.einsum("nij,nj->ni", rot, offset)
    return np.concatenate([pos, Rotation.from_matrix(rot).as_quat()], axis=1)


def openxr_poses(joints: np.ndarray, hand: HandModel) -> np.ndarray:
    """(F, C, 7) capsule poses of ``hand`` from joints (F, 26, 7) in :data:`OPENXR_JOINTS` order
    (position m, quaternion xyzw); see the module docstring. Bones must not be shorter than
    :data:`MIN_BONE_M` (checked by the importer)."""
    f = joints.shape[0]
    c = hand.n_capsules
    index = {n: i for i, n in enumerate(OPENXR_JOINTS)}
    out = np.empty((f, c, 7))
    for ci, name in enumerate(hand.names):
        bone = OPENXR_CAPSULES[name]
        a = joints[:, index[bone[0]]]
        axis = int(hand.axis[ci])
        rot = quat_to_matrix(a[:, 3:]) @ JOINT_TO_CAPSULE[axis]
        if len(bone) == 2:
            b = joints[:, index[bone[1]], :3]
            d = b - a[:, :3]
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            rot = _align(rot, np.full(f, axis), d)
            centre = 0.5 * (a[:, :3] + b)
        else:
            centre = a[:, :3] + rot[:, :, axis] * (0.5 * hand.segment_length_m[ci])
        out[:, ci] = _pose(centre, rot, np.broadcast_to(hand.center_offset_m[ci], (f, 3)))
    return out


def segment_poses(p0: np.ndarray, p1: np.ndarray, hand: HandModel) -> np.ndarray:
    """(F, C, 7) poses putting each capsule of ``hand`` centred on the segment p0 -> p1 (F, C, 3), along it."""
    f, c = p0.shape[:2]
    d = (p1 - p0).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    axis = np.tile(np.asarray(hand.axis, np.int64), f)
    rot = _align(np.broadcast_to(np.eye(3), (f * c, 3, 3)).copy(), axis, d)
    centre = (0.5 * (p0 + p1)).reshape(-1, 3)
    offset = np.broadcast_to(hand.center_offset_m, (f, c, 3)).reshape(-1, 3)
    return _pose(centre, rot, offset).reshape(f, c, 7)


def hand_from_segments(names: tuple[str, ...], p0: np.ndarray, p1: np.ndarray, radius: np.ndarray) -> HandModel:
    """A hand model of capsules ``names`` sized by logged segments (F, C, 3) and radii (F, C): each capsule's
    median core length and radius, its core starting at the joint (axis X, centre offset half the core)."""
    core = np.median(np.linalg.norm(p1 - p0, axis=2), axis=0)
    r = np.median(radius, axis=0)
    return HandModel(
        names=tuple(names),
        fingers=tuple(finger_of(n) or "palm" for n in names),
        radius_m=r.astype(np.float64),
        height_m=(core + 2 * r).astype(np.float64),
        axis=np.zeros(len(names), np.int64),
        center_offset_m=np.stack([0.5 * core, np.zeros_like(core), np.zeros_like(core)], axis=1),
    )


def openxr_joints(poses: np.ndarray, hand: HandModel) -> np.ndarray:
    """(F, 26, 7) OpenXR joints (position m, quaternion xyzw) of capsule poses (F, C, 7) of ``hand``.

    In each chain the bones are as long as the capsules' cores times one factor per frame, fitted by least
    squares so that consecutive bones meet; the joint between two bones is the mean of their ends. A
    metacarpal joint sits at the start of its palm capsule's core. ``palm`` (the palm capsules' mean
    centre) and ``wrist`` (3 cm behind the metacarpal joints' mean) are placed for completeness: no capsule
    is made from them."""
    f = poses.shape[0]
    index = {n: i for i, n in enumerate(hand.names)}
    p0, p1 = capsule_segments(poses, hand)
    centre, seg = 0.5 * (p0 + p1), hand.segment_length_m
    d = (p1 - p0) / np.maximum(seg, MIN_BONE_M)[None, :, None]
    quat = poses[..., 3:].astype(np.float64)
    rot = quat_to_matrix(quat) @ np.transpose(JOINT_TO_CAPSULE[np.asarray(hand.axis)], (0, 2, 1))[None]
    jq = Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_quat().reshape(f, -1, 4)
    out = np.zeros((f, len(OPENXR_JOINTS), 7))
    jidx = {n: i for i, n in enumerate(OPENXR_JOINTS)}
    for caps, joints in CHAINS:
        k = [index[c] for c in caps]
        dc = centre[:, k[:-1]] - centre[:, k[1:]]
        v = 0.5 * (d[:, k[:-1]] * seg[k[:-1], None] + d[:, k[1:]] * seg[k[1:], None])
        s = -np.einsum("fbi,fbi->f", dc, v) / np.einsum("fbi,fbi->f", v, v)
        half = 0.5 * s[:, None, None] * seg[k][None, :, None] * d[:, k]
        start, end = centre[:, k] - half, centre[:, k] + half
        pts = [start[:, 0], 0.5 * (end[:, 0] + start[:, 1]), 0.5 * (end[:, 1] + start[:, 2]), end[:, 2]]
        for j, (name, p) in enumerate(zip(joints, pts)):
            out[:, jidx[name], :3] = p
            out[:, jidx[name], 3:] = jq[:, k[min(j, 2)]]
    for cap, bone in ((c, OPENXR_CAPSULES[c][0]) for c in PALM):
        out[:, jidx[bone], :3] = p0[:, index[cap]]
        out[:, jidx[bone], 3:] = jq[:, index[cap]]
    meta = [jidx[OPENXR_CAPSULES[c][0]] for c in PALM]
    forward = d[:, index["wrist2"]]
    out[:, jidx["palm"], :3] = centre[:, [index[c] for c in PALM]].mean(axis=1)
    out[:, jidx["wrist"], :3] = out[:, meta, :3].mean(axis=1) - 0.03 * forward
    for name in ("palm", "wrist"):
        out[:, jidx[name], 3:] = jq[:, index["wrist2"]]
    return out


def export_openxr(
    poses: np.ndarray, hand: HandModel, time_s: np.ndarray, path: str | Path, hand_label: str = "right"
) -> Path:
    """Write capsule poses (F, C, 7) of ``hand`` at ``time_s`` (F,) as an OpenXR joint log (CSV,
    :data:`sphri.data.recording_schema.OPENXR_LOG`), joints by :func:`openxr_joints`. ``hand`` must have
    the 19 capsules of :data:`OPENXR_CAPSULES`."""
    missing = [n for n in OPENXR_CAPSULES if n not in hand.names]
    if missing:
        raise ValueError(f"export_openxr needs the capsules {list(OPENXR_CAPSULES)}; the hand lacks {missing}")
    joints = openxr_joints(np.asarray(poses, dtype=np.float64), hand)
    path = Path(path)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time", "hand", "joint", "px", "py", "pz", "qx", "qy", "qz", "qw"])
        for t, frame in zip(np.asarray(time_s, dtype=np.float64), joints):
            for name, v in zip(OPENXR_JOINTS, frame):
                w.writerow([repr(float(t)), hand_label, name, *(f"{x:.9g}" for x in v)])
    return path
