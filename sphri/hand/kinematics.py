"""Hand kinematics: quaternions to rotations and capsule poses to segments.

Quaternions are ``(x, y, z, w)`` (Unity / scipy order), Hamilton convention,
active rotations: ``R(q) @ v`` rotates a vector from the joint's local frame
into the parent (link) frame.

Invalid quaternions (any NaN/inf component, or a norm below
:data:`MIN_QUAT_NORM`) cannot be normalized. :func:`quat_to_matrix`,
:func:`rotate_vectors` and :func:`capsule_segments` raise ``ValueError`` on
them (via :func:`validate_quaternions`, which reports how many and where);
loaders call :func:`repair_quaternions` first, which holds the last valid
rotation of the same capsule (within a trial) and counts the repairs.
"""

from __future__ import annotations

import numpy as np

from sphri.types import HandModel

#: Quaternions with a norm below this are treated as invalid (zero) rotations.
MIN_QUAT_NORM = 1e-8

#: Identity rotation in (x, y, z, w) order.
IDENTITY_QUAT = np.array([0.0, 0.0, 0.0, 1.0])


def invalid_quaternions(q: np.ndarray) -> np.ndarray:
    """(...,) bool mask of quaternions that are non-finite or (near) zero.

    ``q`` is (..., 4) in (x, y, z, w) order, any float dtype.
    """
    q = np.asarray(q)
    if q.shape[-1:] != (4,):
        raise ValueError(f"quaternions must have shape (..., 4) (x, y, z, w), got {q.shape}")
    q64 = q.astype(np.float64, copy=False)
    finite = np.isfinite(q64).all(axis=-1)
    with np.errstate(invalid="ignore", over="ignore"):
        norm = np.sqrt(np.einsum("...i,...i->...", q64, q64))
    return ~finite | ~(norm >= MIN_QUAT_NORM)


def validate_quaternions(q: np.ndarray, what: str = "quaternions") -> None:
    """Raise ``ValueError`` if any quaternion in ``q`` (..., 4) is NaN/inf or zero.

    The message gives the count and up to five offending indices (tuples into
    the leading axes of ``q``), e.g. ``(frame, capsule)`` for poses.
    """
    bad = invalid_quaternions(q)
    if bad.any():
        idx = np.argwhere(bad)
        shown = ", ".join(str(tuple(int(i) for i in row)) for row in idx[:5])
        more = f" (and {len(idx) - 5} more)" if len(idx) > 5 else ""
        raise ValueError(
            f"{what}: {len(idx)} of {bad.size} quaternions are NaN/inf or have norm < "
            f"{MIN_QUAT_NORM:g}, at indices {shown}{more}; repair them first "
            f"(sphri.hand.kinematics.repair_quaternions)"
        )


def repair_quaternions(q: np.ndarray, starts: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Replace invalid quaternions by the nearest valid one of the same series.

    ``q`` is (F, ...) with the last axis 4 (x, y, z, w); axis 0 is time (frames)
    and every other leading index (e.g. the capsule) is its own series. Each
    invalid quaternion takes the last valid one before it; leading invalid
    ones take the first valid one after; a series with none takes the
    identity. ``starts`` (sorted frame indices, e.g. trial starts) cuts the
    time axis into independent segments, so values never cross a trial
    boundary (a start equal to F, an empty last trial, is allowed).
    Returns ``(repaired, bad)``: a unit-norm float64 copy of ``q`` and the
    (F, ...) bool mask of entries that were replaced
    (``bad.sum()`` is the repair count).
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim < 2 or q.shape[-1] != 4:
        raise ValueError(f"quaternions must have shape (F, ..., 4), got {q.shape}")
    n = q.shape[0]
    bad = invalid_quaternions(q)
    out = q.copy()
    if n == 0:
        return out, bad
    seg_start = np.zeros(n, dtype=np.int64)
    seg_end = np.full(n, n - 1, dtype=np.int64)
    if starts is not None:
        st = np.unique(np.asarray(starts, dtype=np.int64))
        if st.size and (st[0] < 0 or st[-1] > n):
            raise ValueError(f"starts must lie in [0, {n}], got {st[0]}..{st[-1]}")
        st = np.union1d(st[st < n], [0])  # an empty last trial starts at n: it cuts nothing
        owner = np.searchsorted(st, np.arange(n), side="right") - 1
        seg_start = st[owner]
        ends = np.append(st[1:] - 1, n - 1)
        seg_end = ends[owner]
    shape_rest = (n,) + (1,) * (bad.ndim - 1)
    t = np.arange(n, dtype=np.int64).reshape(shape_rest)
    ss = seg_start.reshape(shape_rest)
    se = seg_end.reshape(shape_rest)
    valid = ~bad
    # last valid index at or before t (values < seg_start mean none in this segment)
    prev = np.maximum.accumulate(np.where(valid, t, ss - 1), axis=0)
    # first valid index at or after t (values > seg_end mean none in this segment)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(valid, t, se + 1), axis=0), axis=0), axis=0)
    has_prev = prev >= ss
    has_next = nxt <= se
    src = np.where(has_prev, prev, np.where(has_next, nxt, -1))
    src_b = np.broadcast_to(src, bad.shape)
    where_bad = np.nonzero(bad)
    src_bad = src_b[where_bad]
    found = src_bad >= 0
    dst = tuple(i[found] for i in where_bad)
    out[dst] = out[(src_bad[found],) + dst[1:]]
    out[tuple(i[~found] for i in where_bad)] = IDENTITY_QUAT
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return out, bad


def _unit_quats(q: np.ndarray, what: str) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    validate_quaternions(q, what)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) float64 rotation matrices of quaternions ``q`` (..., 4) xyzw.

    Quaternions are normalized first; NaN/inf or zero ones raise ``ValueError``
    naming their indices (see :func:`validate_quaternions`).
    """
    q = _unit_quats(q, "quat_to_matrix")
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.empty(q.shape[:-1] + (3, 3), dtype=np.float64)
    m[..., 0, 0] = 1.0 - 2.0 * (yy + zz)
    m[..., 0, 1] = 2.0 * (xy - wz)
    m[..., 0, 2] = 2.0 * (xz + wy)
    m[..., 1, 0] = 2.0 * (xy + wz)
    m[..., 1, 1] = 1.0 - 2.0 * (xx + zz)
    m[..., 1, 2] = 2.0 * (yz - wx)
    m[..., 2, 0] = 2.0 * (xz - wy)
    m[..., 2, 1] = 2.0 * (yz + wx)
    m[..., 2, 2] = 1.0 - 2.0 * (xx + yy)
    return m


def _rotate_unit(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate ``v`` (..., 3) by unit quaternions ``q`` (..., 4); broadcasts."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    # t = 2 u x v ; r = v + w t + u x t  (explicit: np.cross is slow on small last axes)
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return np.stack(
        [vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz), vz + w * tz + (x * ty - y * tx)],
        axis=-1,
    )


def rotate_vectors(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., 3) float64 ``R(q) @ v`` for quaternions ``q`` (..., 4) xyzw, broadcasting.

    Same result as ``quat_to_matrix(q) @ v`` without building matrices.
    Invalid quaternions raise ``ValueError``.
    """
    q = _unit_quats(q, "rotate_vectors")
    return _rotate_unit(q, np.asarray(v, dtype=np.float64))


def capsule_segments(poses: np.ndarray, hand: HandModel) -> tuple[np.ndarray, np.ndarray]:
    """Core segments of every capsule in every frame.

    ``poses`` is (F, C, 7) float32/float64: joint position xyz (metres) and
    quaternion xyzw, C = ``hand.n_capsules``. With ``R = R(q)``, the centre
    is ``pos + R @ center_offset_m``, the axis is column ``hand.axis`` of R,
    and the endpoints are ``centre -/+ axis * segment_length_m / 2``.
    Returns ``(p0, p1)``, each (F, C, 3) float64 metres; capsule radii are
    ``hand.radius_m``. Invalid quaternions raise ``ValueError`` naming the
    (frame, capsule) indices; NaN positions pass through as NaN endpoints.
    """
    poses = np.asarray(poses)
    c = hand.n_capsules
    if poses.ndim != 3 or poses.shape[1:] != (c, 7):
        raise ValueError(
            f"poses must have shape (F, {c}, 7) (xyz + quaternion xyzw for each of the "
            f"hand's {c} capsules), got {poses.shape}"
        )
    pos = poses[..., :3].astype(np.float64)
    q = _unit_quats(poses[..., 3:], "capsule_segments: poses (frame, capsule)")
    centre = pos + _rotate_unit(q, hand.center_offset_m[None, :, :])
    basis = np.eye(3)[np.asarray(hand.axis, dtype=np.int64)]  # (C, 3)
    half = (0.5 * hand.segment_length_m)[None, :, None]
    d = _rotate_unit(q, basis[None, :, :]) * half
    return centre - d, centre + d
