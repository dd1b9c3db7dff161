"""From a log's rows to frames: one hand, time order, no duplicates, complete frames, metres; resampling.

A frame is the rows sharing one ``time``. Each check refuses with one :class:`LogError` line naming the
file, the line and the field; :func:`resample` interpolates the frames onto a fixed rate and says what
it did (frames interpolated across tracking gaps, frames fewer by downsampling).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation, Slerp

from sphri.data.recording_schema import GAP_FACTOR, HANDS
from sphri.data.schema import POSITION_UNITS
from sphri.data.vr_gesture import HAND_SCALE_RANGE, hand_model_size_m
from sphri.recordings.logs import LogError
from sphri.types import HandModel

#: Plausible median time between a log's frames (s): 10 kHz to 0.5 Hz.
MIN_STEP_S, MAX_STEP_S = 1e-4, 2.0


@dataclass
class Frames:
    """A log's frames: ``values`` (F, K, D) of ``ids`` (K) at ``time_s`` (F,), ``line`` (F,) each frame's first line."""

    time_s: np.ndarray
    values: np.ndarray
    ids: tuple[str, ...]
    line: np.ndarray


def check_hand(path: object, df: pd.DataFrame, expected: str) -> None:
    """Refuse an unknown hand, a log mixing hands, or one whose hand is not ``expected``."""
    if "hand" not in df:
        return
    hand = df["hand"].str.lower().to_numpy()
    lines = df["line"].to_numpy()
    unknown = ~np.isin(hand, HANDS)
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise LogError(f"{path}: line {lines[i]}: field hand={df['hand'].iat[i]!r} is not a hand: left or right")
    other = np.flatnonzero(hand != hand[0])
    if other.size:
        i = int(other[0])
        raise LogError(
            f"{path}: line {lines[i]}: field hand={hand[i]!r} after rows of hand {hand[0]!r}: mixed hands, "
            f"where one trial is one hand (hand={expected}); split the log by hand"
        )
    if hand[0] != expected:
        raise LogError(
            f"{path}: line {lines[0]}: field hand={hand[0]!r}, but hand={expected} is expected "
            f"(give hand={hand[0]} to import this hand)"
        )


def to_frames(
    path: object, df: pd.DataFrame, key: str, ids: Sequence[str], values: Sequence[str], required: Sequence[str]
) -> Frames:
    """Group ``df``'s rows into frames by ``time``. ``key`` is the column naming the row's joint or capsule
    (already one of ``ids``), ``values`` the columns kept; every id of ``required`` must be in every frame.
    Refuses time going back, a (time, id) given twice, and a frame missing an id."""
    t = df["time"].to_numpy()
    lines = df["line"].to_numpy()
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise LogError(
            f"{path}: line {lines[i]}: field time={t[i]:.9g} goes back (line {lines[i - 1]} has {t[i - 1]:.9g}): "
            "time must not decrease"
        )
    dup = df.duplicated(["time", key], keep="first").to_numpy()
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        same = np.flatnonzero((t == t[i]) & (df[key].to_numpy() == df[key].iat[i]))
        raise LogError(
            f"{path}: line {lines[i]}: field {key}={df[key].iat[i]!r} at time={t[i]:.9g} repeats line "
            f"{lines[same[0]]}: duplicate frame ({int(dup.sum())} duplicated row(s))"
        )
    times, first, frame = np.unique(t, return_index=True, return_inverse=True)
    if len(times) > 1:
        step = float(np.median(np.diff(times)))
        if not MIN_STEP_S <= step <= MAX_STEP_S:
            raise LogError(
                f"{path}: line {lines[first[1]]}: field time: frames lie {step:.4g} apart (median), where seconds "
                f"give {MIN_STEP_S:g} to {MAX_STEP_S:g}: wrong time unit (milliseconds? nanoseconds?); give seconds"
            )
    index = {n: k for k, n in enumerate(ids)}
    k = np.array([index[v] for v in df[key]], dtype=np.int64)
    arr = np.full((len(times), len(ids), len(values)), np.nan)
    arr[frame, k] = df[list(values)].to_numpy(np.float64)
    present = np.zeros((len(times), len(ids)), bool)
    present[frame, k] = True
    need = [index[n] for n in required]
    miss = ~present[:, need]
    if miss.any():
        f = int(np.flatnonzero(miss.any(axis=1))[0])
        names = [required[int(j)] for j in np.flatnonzero(miss[f])]
        raise LogError(
            f"{path}: line {lines[first[f]]}: the frame at time={times[f]:.9g} misses {key}(s) {names[:6]}"
            f"{' ...' if len(names) > 6 else ''} ({int(miss.any(axis=1).sum())} of {len(times)} frame(s) miss one)"
        )
    return Frames(times, arr, tuple(ids), lines[first])


def check_metres(path: object, frames: Frames, columns: str, points: np.ndarray, hand: HandModel) -> None:
    """Refuse positions that cannot be metres: ``points`` (F, N, 3) of a hand must span about a hand
    (:data:`sphri.data.vr_gesture.HAND_SCALE_RANGE` of its capsule model's size), median over frames."""
    span = np.linalg.norm(points - points.mean(axis=1, keepdims=True), axis=2).max(axis=1)
    med = float(np.median(span))
    size = hand_model_size_m(hand)
    ratio = med / size
    if HAND_SCALE_RANGE[0] <= ratio <= HAND_SCALE_RANGE[1]:
        return
    guess = min(POSITION_UNITS, key=lambda u: abs(np.log10(max(ratio, 1e-12) * POSITION_UNITS[u] / 0.5)))
    f = int(np.argmin(np.abs(span - med)))
    raise LogError(
        f"{path}: line {frames.line[f]}: fields {columns}: the hand spans {med:.4g} (median over frames) where "
        f"a hand in metres spans about {0.5 * size:.2g}: wrong units, the positions look like {guess}; "
        "give metres"
    )


def resample(frames: Frames, rate_hz: float, quat: slice | None = None) -> tuple[Frames, dict]:
    """``frames`` interpolated at ``rate_hz`` from their first time on: linear, and spherical (slerp) for the
    quaternion components ``quat`` of the last axis. Returns the frames and a report: source frames, their
    median rate, output frames, tracking gaps (intervals over :data:`GAP_FACTOR` median intervals) and the
    output frames interpolated across them, and how many frames fewer downsampling made."""
    t, v = frames.time_s, frames.values
    n = len(t)
    if n == 1:
        out_t, out, gaps, in_gap = t.copy(), v.copy(), np.zeros(0, bool), 0
    else:
        count = int(np.floor((t[-1] - t[0]) * rate_hz + 1e-6)) + 1
        out_t = t[0] + np.arange(count) / rate_hz
        i = np.clip(np.searchsorted(t, out_t, side="right") - 1, 0, n - 2)
        w = ((out_t - t[i]) / (t[i + 1] - t[i]))[:, None, None]
        out = (1 - w) * v[i] + w * v[i + 1]
        if quat is not None:
            for k in range(v.shape[1]):
                rot = Rotation.from_quat(v[:, k, quat])
                out[:, k, quat] = Slerp(t, rot)(np.clip(out_t, t[0], t[-1])).as_quat()
        dt = np.diff(t)
        gaps = dt > GAP_FACTOR * np.median(dt)
        inside = (out_t[:, None] > t[:-1][gaps][None, :]) & (out_t[:, None] < t[1:][gaps][None, :])
        in_gap = int(inside.any(axis=1).sum())
    src_rate = float(1.0 / np.median(np.diff(t))) if n > 1 else float("nan")
    report = {
        "source_frames": int(n),
        "source_rate_hz": round(src_rate, 3),
        "frames": int(len(out_t)),
        "rate_hz": float(rate_hz),
        "gaps": int(gaps.sum()),
        "interpolated_frames": in_gap,
        "dropped_frames": max(0, int(n) - int(len(out_t))),
    }
    line = frames.line[np.clip(np.searchsorted(t, out_t, side="right") - 1, 0, n - 1)]
    return Frames(out_t, out, frames.ids, line), report


def describe(report: dict) -> str:
    """One sentence of a :func:`resample` report."""
    return (
        f"{report['source_frames']} source frames (median {report['source_rate_hz']:g} Hz) resampled to "
        f"{report['frames']} frames at {report['rate_hz']:g} Hz: {report['interpolated_frames']} frame(s) "
        f"interpolated across {report['gaps']} tracking gap(s), {report['dropped_frames']} source frame(s) "
        "dropped by downsampling"
    )


def parse_link_pose(text: str) -> tuple[Rotation, np.ndarray]:
    """``"x,y,z,qx,qy,qz,qw"``: the robot link's pose in the log's frame (metres; a unit quaternion, Hamilton,
    (x, y, z, w)) -> its rotation and translation. Raises ``ValueError`` with what is wrong."""
    parts = [s.strip() for s in text.split(",")]
    if len(parts) != 7:
        raise ValueError(f"must be 7 numbers x,y,z,qx,qy,qz,qw (metres, a unit quaternion), got {len(parts)}")
    try:
        v = np.array([float(s) for s in parts])
    except ValueError:
        raise ValueError("must be 7 numbers x,y,z,qx,qy,qz,qw (metres, a unit quaternion)") from None
    if not np.isfinite(v).all():
        raise ValueError("must be 7 finite numbers")
    norm = float(np.linalg.norm(v[3:]))
    if abs(norm - 1.0) > 1e-3:
        raise ValueError(f"its quaternion (qx, qy, qz, qw) has norm {norm:.4g}, not 1")
    return Rotation.from_quat(v[3:]), v[:3]


def to_link_frame(frames: Frames, link_pose: str, points: tuple[slice, ...], quat: slice | None = None) -> Frames:
    """``frames`` with positions and orientations logged in another frame (the room's, a tracker's) taken into
    the robot link's frame, where the link's pose in the log's frame is ``link_pose`` (:func:`parse_link_pose`):
    ``p_link = R^T (p - t)`` for each point column block in ``points``, ``q_link = q_R^-1 q`` for ``quat``.
    The link is taken as still for the whole log."""
    rot, trans = parse_link_pose(link_pose)
    inv = rot.inv()
    v = frames.values.copy()
    f, k = v.shape[:2]
    for block in points:
        v[..., block] = inv.apply((v[..., block] - trans).reshape(-1, 3)).reshape(f, k, 3)
    if quat is not None:
        v[..., quat] = (inv * Rotation.from_quat(v[..., quat].reshape(-1, 4))).as_quat().reshape(f, k, 4)
    return replace(frames, values=v)
