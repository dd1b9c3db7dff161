"""What a coding sheet's replay shows of an episode, as compact arrays for the page's script.

Each episode is replayed in the frame of its dominant link (the touched link
stands still while the robot moves): both hands' capsules (segment ends,
radii), the contact points on that link, how many capsules of each hand touch
the robot in each frame, and the link's surface as points coloured by body
part (:func:`link_cloud`, once per link). Two views, from 0.5 s before the
episode to 0.5 s after it (the padding the gesture model's windows get):
facing the touch (looking along the mean contact normal) and from the side.
Positions are integers in millimetres (int16), sent base64-encoded; the page
decodes them (little-endian, as every browser platform is).
"""

from __future__ import annotations

import base64

import numpy as np
import pandas as pd

from sphri.hand.kinematics import capsule_segments, quat_to_matrix

#: Seconds of motion shown before and after each episode (as the gesture model's windows pad it).
PAD_S = 0.5
#: Smallest half-width (mm) of a replay's view.
MIN_HALF_MM = 120.0


def b64(a: np.ndarray, dtype: str) -> str:
    """``a`` as little-endian ``dtype`` bytes, base64 (the page's typed arrays read them)."""
    return base64.b64encode(np.ascontiguousarray(a, dtype=np.dtype(dtype).newbyteorder("<")).tobytes()).decode()


def _mm(points_m: np.ndarray) -> np.ndarray:
    return np.clip(np.round(np.asarray(points_m, np.float64) * 1000.0), -32767, 32767).astype(np.int16)


def link_cloud(robot, link: str, spacing_mm: float = 10.0, max_points: int = 4000, seed: int = 0) -> dict:
    """The surface of ``link`` as points (mm, link frame), normals (x127, int8), body part indices and the
    points' spacing (mm; at most ``max_points``, so a large link's are farther apart than ``spacing_mm``)."""
    from sphri.geometry.samples import sample_link

    s = sample_link(robot.links[link], spacing_mm, seed)
    keep = np.arange(s.n)
    if s.n > max_points:
        keep = np.sort(np.random.default_rng(seed).choice(s.n, max_points, replace=False))
    pts, nrm = s.points_m[keep], s.normal[keep]
    lab = robot.part_labels(link, pts, nrm) if hasattr(robot, "part_labels") else np.full(len(pts), "", object)
    lab = np.where(lab == "", link, lab).astype(str)
    parts = sorted(set(lab.tolist()))
    index = {p: i for i, p in enumerate(parts)}
    return {
        "name": link,
        "parts": parts,
        "n": int(len(pts)),
        "spacing_mm": round(float(s.spacing_m) * 1000.0 * float(np.sqrt(s.n / len(pts))), 2),
        "points": b64(_mm(pts), "int16"),
        "normals": b64(np.round(nrm * 127).astype(np.int8), "int8"),
        "part": b64(np.array([index[p] for p in lab], np.uint8), "uint8"),
    }


def to_link(points: np.ndarray, link_pose: np.ndarray) -> np.ndarray:
    """World ``points`` (n, ..., 3) into the frame of a link whose world pose per frame is ``link_pose`` (n, 7)."""
    r = quat_to_matrix(link_pose[:, 3:].astype(np.float64))
    t = link_pose[:, :3].astype(np.float64)
    shape = points.shape
    flat = points.reshape(shape[0], -1, 3) - t[:, None, :]
    return np.einsum("nji,nkj->nki", r, flat).reshape(shape)


def view_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, v): screen axes of the view facing along ``-normal`` (v as close to the link's +z as it can be)."""
    n = normal / max(float(np.linalg.norm(normal)), 1e-12)
    up = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
    v = up - n * (up @ n)
    v /= np.linalg.norm(v)
    return np.cross(v, n), v


def episode_replay(e, ds, bc, link_index: int, replay_hz: float) -> dict:
    """The replay of episode ``e`` (a row of the coded episodes) on its dominant link (``ds.links[link_index]``)."""
    rate = float(ds.frame_rate_hz)
    s0 = int(ds.sessions["start"].iat[int(e.session)])
    s1 = s0 + int(ds.sessions["n_frames"].iat[int(e.session)])
    pad = int(round(PAD_S * rate))
    a, b = max(s0, int(e.start_frame) - pad), min(s1, int(e.end_frame) + pad + 1)
    stride = max(1, int(round(rate / replay_hz)))
    frames = np.arange(a, b, stride)
    n, c = frames.size, ds.hand.n_capsules
    lp = ds.link_poses[frames, link_index]
    p0, p1 = capsule_segments(ds.hand_poses[frames].reshape(n * 2, c, 7), ds.hand)
    ends = np.stack([p0.reshape(n, 2, c, 3), p1.reshape(n, 2, c, 3)], axis=3)  # (n, hand, capsule, end, 3)
    ends = to_link(ends, lp)
    rows = np.flatnonzero((bc.frame >= a) & (bc.frame < b))
    on = rows[np.isin(bc.frame[rows], frames)]
    count = np.zeros((n, 2), np.uint8)
    pos = np.searchsorted(frames, bc.frame[on])
    keys = np.unique(np.c_[pos, bc.hand[on].astype(np.int64), bc.capsule[on].astype(np.int64)], axis=0)
    np.add.at(count, (keys[:, 0], keys[:, 1]), 1)
    mine = on[bc.link[on] == link_index]
    touch = rows[(bc.link[rows] == link_index) & (bc.hand[rows] == int(e.dominant_hand))]
    normal = bc.normal[touch].mean(axis=0) if touch.size else np.array([0.0, 0.0, 1.0])
    centre = bc.point_m[touch].mean(axis=0) if touch.size else ends[:, int(e.dominant_hand)].reshape(-1, 3).mean(0)
    u, v = view_basis(normal)
    n_hat = np.cross(u, v)
    near = ends[:, int(e.dominant_hand)].reshape(-1, 3) - centre
    reach = np.abs(np.c_[near @ u, near @ v, near @ n_hat]).max() * 1000.0 if near.size else 0.0
    return {
        "n": int(n),
        "stride": stride,
        "first_frame": int(a - s0),
        "episode": [int(np.searchsorted(frames, int(e.start_frame))), int(np.searchsorted(frames, int(e.end_frame)))],
        "caps": b64(_mm(ends), "int16"),
        "count": b64(count, "uint8"),
        "dot_frame": b64(np.searchsorted(frames, bc.frame[mine]).astype(np.uint16), "uint16"),
        "dots": b64(_mm(bc.point_m[mine]), "int16"),
        "centre": [round(float(x) * 1000.0, 1) for x in centre],
        "u": [round(float(x), 5) for x in u],
        "v": [round(float(x), 5) for x in v],
        "n_hat": [round(float(x), 5) for x in n_hat],
        "half_mm": round(max(MIN_HALF_MM, 1.1 * reach), 1),
    }


def replay_data(coded: pd.DataFrame, ds, bc, robot, replay_hz: float) -> dict:
    """Everything the sheet's script draws: the hand's capsule radii (mm), each touched link's surface once,
    and one replay per coded episode (in the order of ``coded``)."""
    links = list(dict.fromkeys(str(x) for x in coded["dominant_link"]))
    li = {name: i for i, name in enumerate(ds.links)}
    episodes = []
    for e in coded.itertuples(index=False):
        r = episode_replay(e, ds, bc, li[str(e.dominant_link)], replay_hz)
        r["link"] = links.index(str(e.dominant_link))
        r["hand"] = int(e.dominant_hand)
        episodes.append(r)
    return {
        "rate_hz": float(ds.frame_rate_hz),
        "radius_mm": [round(float(x) * 1000.0, 2) for x in ds.hand.radius_m],
        "links": [link_cloud(robot, name) for name in links],
        "episodes": episodes,
    }
