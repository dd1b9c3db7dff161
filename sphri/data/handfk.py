"""A kinematic right hand for the synthetic generator: joint angles -> capsule poses.

Hand frame (metres): origin at the wrist joint, +x towards the fingers, +z
out of the back of the hand (the palm faces -z), +y towards the thumb. Each
of the five chains (thumb, index, middle, ring, pinky) has 4 angles in
radians: abduction (about the chain base's z) and three flexions (about each
bone's local y; positive bends towards the palm). The four palm capsules
(``wrist1``..``wrist4``) are fixed to the hand frame.

Bones are as long as the capsules' core segments (``HandModel.segment_length_m``)
times the participant's hand scale; each capsule is centred on its bone, so
the poses follow the hand model's own convention (centre = ``pos + R @
center_offset``, axis = local ``axis``) whatever its offsets and axes are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from sphri.types import HandModel

#: Chain order of the finger-angle arrays (T, 5, 4).
CHAINS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "pinky")

#: Capsule names the generator drives: chain bones and palm capsules.
PALM_CAPSULES: tuple[str, ...] = ("wrist1", "wrist2", "wrist3", "wrist4")

# Nominal hand (scale 1), metres in the hand frame.
_MCP = np.array(
    [
        [0.030, 0.022, -0.006],  # thumb CMC
        [0.088, 0.024, -0.008],  # index MCP
        [0.091, 0.005, -0.008],  # middle MCP
        [0.086, -0.013, -0.008],  # ring MCP
        [0.078, -0.030, -0.010],  # pinky MCP
    ]
)
_MIDDLE1_SEGMENT_M = 0.06527488 - 2 * 0.01117394  # the study's middle1 capsule core segment
_SPLAY = np.array([0.0, 0.10, 0.0, -0.10, -0.20])  # base yaw of the finger chains (rad)
_THUMB_DIR = np.array([0.65, 0.70, -0.25])  # thumb metacarpal at rest
_THUMB_FLEX_TO = np.array([0.35, -0.55, -0.75])  # where thumb flexion points (across the palm)
_PALM_START = np.array([[0.030, 0.016, 0.0], [0.030, 0.002, 0.0], [0.030, -0.012, 0.0], [0.035, -0.025, 0.0]])
_PALM_TOWARD = np.array(
    [[0.085, 0.022, -0.004], [0.088, 0.004, -0.004], [0.083, -0.013, -0.004], [0.075, -0.030, -0.004]]
)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _chain_bases() -> np.ndarray:
    """(5, 3, 3) base frames (columns x, y, z) of the chains in the hand frame."""
    bases = np.empty((5, 3, 3))
    u = _unit(_THUMB_DIR)
    a = _unit(np.cross(u, _unit(_THUMB_FLEX_TO)))
    bases[0] = np.stack([u, a, np.cross(u, a)], axis=1)
    for k in range(1, 5):
        s = _SPLAY[k]
        bases[k] = np.array([[np.cos(s), -np.sin(s), 0.0], [np.sin(s), np.cos(s), 0.0], [0.0, 0.0, 1.0]])
    return bases


_BASES = _chain_bases()


def rotvec_to_matrix(w: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of rotation vectors ``w`` (..., 3) radians (Rodrigues)."""
    w = np.asarray(w, dtype=np.float64)
    th = np.linalg.norm(w, axis=-1)
    safe = np.where(th > 1e-12, th, 1.0)
    k = w / safe[..., None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = np.zeros_like(kx)
    K = np.stack([np.stack([zero, -kz, ky], -1), np.stack([kz, zero, -kx], -1), np.stack([-ky, kx, zero], -1)], -2)
    s = np.sin(th)[..., None, None]
    c = (1.0 - np.cos(th))[..., None, None]
    return np.eye(3) + s * K + c * (K @ K)


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (x, y, z, w), w >= 0, of rotation matrices (..., 3, 3).

    Shepperd's method: each matrix uses the formula whose pivot (w, x, y or
    z) is largest, so it is accurate everywhere.
    """
    m = np.asarray(m, dtype=np.float64)
    shape = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    m00, m11, m22 = m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]
    piv = np.stack([m00 + m11 + m22, m00 - m11 - m22, m11 - m00 - m22, m22 - m00 - m11], axis=-1)
    pick = np.argmax(piv, axis=-1)
    q = np.empty((m.shape[0], 4))
    for k in range(4):
        sel = np.flatnonzero(pick == k)
        if sel.size == 0:
            continue
        a = m[sel]
        r = np.sqrt(1.0 + piv[sel, k])
        s = 0.5 / r
        d21, d02, d10 = a[:, 2, 1] - a[:, 1, 2], a[:, 0, 2] - a[:, 2, 0], a[:, 1, 0] - a[:, 0, 1]
        s01, s02, s12 = a[:, 0, 1] + a[:, 1, 0], a[:, 0, 2] + a[:, 2, 0], a[:, 1, 2] + a[:, 2, 1]
        if k == 0:
            q[sel] = np.stack([d21 * s, d02 * s, d10 * s, 0.5 * r], axis=-1)
        elif k == 1:
            q[sel] = np.stack([0.5 * r, s01 * s, s02 * s, d21 * s], axis=-1)
        elif k == 2:
            q[sel] = np.stack([s01 * s, 0.5 * r, s12 * s, d02 * s], axis=-1)
        else:
            q[sel] = np.stack([s02 * s, s12 * s, 0.5 * r, d10 * s], axis=-1)
    q *= np.where(q[:, 3:] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q.reshape(shape + (4,))


@njit(cache=True)
def _chain_kernel(fingers, bases, mcp, lengths, slots, start, frame):  # pragma: no cover - compiled
    """Finger chains: start (T, C, 3) and frame (T, C, 3, 3) of the 15 chain bones, in place."""
    for t in range(fingers.shape[0]):
        for k in range(5):
            a = fingers[t, k, 0]
            ca, sa = np.cos(a), np.sin(a)
            cum = 0.0
            jx, jy, jz = mcp[k, 0], mcp[k, 1], mcp[k, 2]
            for b in range(3):
                cum += fingers[t, k, 1 + b]
                cc, sc = np.cos(cum), np.sin(cum)
                # M = Rz(a) Ry(cum)
                m00, m01, m02 = ca * cc, -sa, ca * sc
                m10, m11, m12 = sa * cc, ca, sa * sc
                m20, m21, m22 = -sc, 0.0, cc
                s = slots[k, b]
                for i in range(3):
                    b0, b1, b2 = bases[k, i, 0], bases[k, i, 1], bases[k, i, 2]
                    frame[t, s, i, 0] = b0 * m00 + b1 * m10 + b2 * m20
                    frame[t, s, i, 1] = b0 * m01 + b1 * m11 + b2 * m21
                    frame[t, s, i, 2] = b0 * m02 + b1 * m12 + b2 * m22
                start[t, s, 0] = jx
                start[t, s, 1] = jy
                start[t, s, 2] = jz
                ln = lengths[k, b]
                jx += ln * frame[t, s, 0, 0]
                jy += ln * frame[t, s, 1, 0]
                jz += ln * frame[t, s, 2, 0]


@njit(cache=True)
def _pose_kernel(start, frame, length, rot, pos, perm, offset, out):  # pragma: no cover - compiled
    """Joint poses (T, C, 7): capsule centred on its bone, joint frame = rot @ frame @ perm, quaternion xyzw."""
    r = np.empty((3, 3))
    f = np.empty((3, 3))
    for t in range(start.shape[0]):
        for c in range(start.shape[1]):
            for i in range(3):
                for j in range(3):
                    f[i, j] = (
                        rot[t, i, 0] * frame[t, c, 0, j]
                        + rot[t, i, 1] * frame[t, c, 1, j]
                        + rot[t, i, 2] * frame[t, c, 2, j]
                    )
            for i in range(3):
                for j in range(3):
                    r[i, j] = f[i, 0] * perm[c, 0, j] + f[i, 1] * perm[c, 1, j] + f[i, 2] * perm[c, 2, j]
            h = 0.5 * length[c]
            m0 = start[t, c, 0] + h * frame[t, c, 0, 0]
            m1 = start[t, c, 1] + h * frame[t, c, 1, 0]
            m2 = start[t, c, 2] + h * frame[t, c, 2, 0]
            for i in range(3):
                centre = rot[t, i, 0] * m0 + rot[t, i, 1] * m1 + rot[t, i, 2] * m2
                out[t, c, i] = (
                    pos[t, i] + centre - (r[i, 0] * offset[c, 0] + r[i, 1] * offset[c, 1] + r[i, 2] * offset[c, 2])
                )
            # Shepperd: the largest of w, x, y, z as pivot
            tr = r[0, 0] + r[1, 1] + r[2, 2]
            if tr >= r[0, 0] and tr >= r[1, 1] and tr >= r[2, 2]:
                q = np.sqrt(1.0 + tr)
                s = 0.5 / q
                qx, qy, qz, qw = (r[2, 1] - r[1, 2]) * s, (r[0, 2] - r[2, 0]) * s, (r[1, 0] - r[0, 1]) * s, 0.5 * q
            elif r[0, 0] >= r[1, 1] and r[0, 0] >= r[2, 2]:
                q = np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
                s = 0.5 / q
                qx, qy, qz, qw = 0.5 * q, (r[0, 1] + r[1, 0]) * s, (r[0, 2] + r[2, 0]) * s, (r[2, 1] - r[1, 2]) * s
            elif r[1, 1] >= r[2, 2]:
                q = np.sqrt(1.0 - r[0, 0] + r[1, 1] - r[2, 2])
                s = 0.5 / q
                qx, qy, qz, qw = (r[0, 1] + r[1, 0]) * s, 0.5 * q, (r[1, 2] + r[2, 1]) * s, (r[0, 2] - r[2, 0]) * s
            else:
                q = np.sqrt(1.0 - r[0, 0] - r[1, 1] + r[2, 2])
                s = 0.5 / q
                qx, qy, qz, qw = (r[0, 2] + r[2, 0]) * s, (r[1, 2] + r[2, 1]) * s, 0.5 * q, (r[1, 0] - r[0, 1]) * s
            n = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
            if qw < 0:
                n = -n
            out[t, c, 3] = qx / n
            out[t, c, 4] = qy / n
            out[t, c, 5] = qz / n
            out[t, c, 6] = qw / n


@dataclass(frozen=True)
class HandRig:
    """Which pose slot each generator bone fills, and the bone lengths of a hand model.

    ``chain_slot`` (5, 3): capsule index of each chain bone; ``palm_slot`` (4,).
    """

    hand: HandModel
    chain_slot: np.ndarray
    palm_slot: np.ndarray
    axis_perm: np.ndarray
    """(C, 3, 3) rotation taking the bone frame (x along the bone) to the joint frame (capsule axis along the bone)."""
    palm_scale: float = 1.0
    """Size of this hand model relative to the study's (middle1 segment length ratio): scales the palm layout."""

    @classmethod
    def from_hand(cls, hand: HandModel) -> HandRig:
        index = {n: i for i, n in enumerate(hand.names)}
        need = [f"{c}{k}" for c in CHAINS for k in (1, 2, 3)] + list(PALM_CAPSULES)
        missing = [n for n in need if n not in index]
        if missing:
            raise ValueError(
                f"the synthetic hand needs capsules {need}; the hand model lacks {missing} (it has {list(hand.names)})"
            )
        extra = [n for n in hand.names if n not in need]
        if extra:
            raise ValueError(f"the synthetic hand cannot drive capsules {extra}; it knows {need}")
        chain_slot = np.array([[index[f"{c}{k}"] for k in (1, 2, 3)] for c in CHAINS])
        palm_slot = np.array([index[n] for n in PALM_CAPSULES])
        # Q maps local e_axis to e_0 (cyclic permutations, det +1): R_joint = R_bone @ Q.
        perms = {
            0: np.eye(3),
            1: np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], float),
            2: np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], float),
        }
        axis_perm = np.stack([perms[int(a)] for a in hand.axis])
        palm_scale = float(hand.segment_length_m[index["middle1"]] / _MIDDLE1_SEGMENT_M)
        if not 0.2 < palm_scale < 5.0:
            raise ValueError(
                f"hand capsule middle1 has a {hand.segment_length_m[index['middle1']]:.4f} m segment; "
                f"the synthetic hand expects about {_MIDDLE1_SEGMENT_M:.4f} m"
            )
        return cls(hand=hand, chain_slot=chain_slot, palm_slot=palm_slot, axis_perm=axis_perm, palm_scale=palm_scale)

    def bones(self, fingers: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bone frames in the hand frame for finger angles ``fingers`` (T, 5, 4).

        Returns ``start`` (T, C, 3) bone start points, ``frame`` (T, C, 3, 3)
        bone frames (column 0 along the bone) and ``length`` (C,), all in
        capsule (pose-column) order.
        """
        fingers = np.asarray(fingers, dtype=np.float64)
        t = fingers.shape[0]
        c = self.hand.n_capsules
        seg = self.hand.segment_length_m
        lc, lp = seg[self.chain_slot] * scale, seg[self.palm_slot] * scale  # chain (5, 3), palm (4,) bones (m)
        start = np.empty((t, c, 3))
        frame = np.empty((t, c, 3, 3))
        length = np.empty(c)
        # flexions share the bone's y axis, so bone b's frame is B Rz(abd) Ry(theta_1 + ... + theta_b)
        _chain_kernel(fingers, _BASES, _MCP * scale * self.palm_scale, lc, self.chain_slot, start, frame)
        for b in range(3):
            length[self.chain_slot[:, b]] = lc[:, b]
        d = _unit(_PALM_TOWARD - _PALM_START)
        z = np.array([0.0, 0.0, 1.0])
        y = _unit(np.cross(z, d))
        pf = np.stack([d, y, np.cross(d, y)], axis=-1)  # (4, 3, 3)
        start[:, self.palm_slot] = _PALM_START * scale * self.palm_scale
        frame[:, self.palm_slot] = pf
        length[self.palm_slot] = lp
        return start, frame, length

    def poses(self, fingers: np.ndarray, rot: np.ndarray, pos: np.ndarray, scale: float) -> np.ndarray:
        """(T, C, 7) float64 joint poses (xyz metres + quaternion xyzw) in the link frame.

        ``rot`` (T, 3, 3) and ``pos`` (T, 3) place the hand frame (its wrist
        joint) in the link frame; ``fingers`` (T, 5, 4) are the chain angles.
        """
        return self.poses_from_bones(*self.bones(fingers, scale), rot, pos)

    def poses_from_bones(
        self, start: np.ndarray, frame: np.ndarray, length: np.ndarray, rot: np.ndarray, pos: np.ndarray
    ) -> np.ndarray:
        """:meth:`poses` from :meth:`bones` output (``length`` (C,))."""
        t, c = start.shape[:2]
        out = np.empty((t, c, 7))
        _pose_kernel(
            np.ascontiguousarray(start, dtype=np.float64),
            np.ascontiguousarray(frame, dtype=np.float64),
            np.asarray(length, dtype=np.float64),
            np.ascontiguousarray(rot, dtype=np.float64),
            np.ascontiguousarray(pos, dtype=np.float64),
            self.axis_perm,
            self.hand.center_offset_m,
            out,
        )
        return out


#: Effector kinds, in the order of :func:`effectors_from_bones`' output.
EFFECTORS: tuple[str, ...] = ("palm", "index_tip", "pad", "fingers", "fist")


def effectors_from_bones(
    rig: HandRig, start: np.ndarray, frame: np.ndarray, length: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points of the hand that touch, in the hand frame, for every kind in :data:`EFFECTORS`.

    ``palm``: centre of the palm's skin; ``index_tip``: tip of the index
    finger; ``pad``: pad of the index fingertip; ``fingers``: pads of the
    middle phalanges of index to ring; ``fist``: knuckles of a fist. Input:
    :meth:`HandRig.bones` output. Returns ``point`` (T, E, 3) metres,
    ``normal`` (T, E, 3) (outward normal of the touching skin, which is turned
    against the link's surface normal) and ``forward`` (T, E, 3) (a unit hand
    direction orthogonal to ``normal`` that orients the hand around it).
    """
    r = rig.hand.radius_m
    t = start.shape[0]
    pts, nrm, fwd = [], [], []
    # palm
    ps = rig.palm_slot
    mid = start[:, ps] + 0.5 * length[ps][None, :, None] * frame[:, ps][..., 0]
    pts.append(mid.mean(axis=1) - np.array([0.0, 0.0, r[ps].max()]))
    nrm.append(np.broadcast_to([0.0, 0.0, -1.0], (t, 3)))
    fwd.append(np.broadcast_to([1.0, 0.0, 0.0], (t, 3)))
    # index tip
    s = rig.chain_slot[1, 2]
    d = frame[:, s, :, 0]
    pts.append(start[:, s] + (length[s] + r[s]) * d)
    nrm.append(d)
    fwd.append(frame[:, s, :, 2])
    # index pad
    pts.append(start[:, s] + 0.6 * length[s] * d - r[s] * frame[:, s, :, 2])
    nrm.append(-frame[:, s, :, 2])
    fwd.append(d)
    # middle phalanges of index, middle, ring
    s3 = rig.chain_slot[1:4, 1]
    mid = start[:, s3] + 0.5 * length[s3][None, :, None] * frame[:, s3][..., 0]
    down = -frame[:, s3][..., 2]
    pts.append((mid + r[s3][None, :, None] * down).mean(axis=1))
    nrm.append(_unit(down.mean(axis=1)))
    fwd.append(_unit(frame[:, s3][..., 0].mean(axis=1)))
    # fist knuckles: ends of the proximal phalanges, dorsal side
    s3 = rig.chain_slot[1:4, 0]
    up = frame[:, s3][..., 2]
    end = start[:, s3] + length[s3][None, :, None] * frame[:, s3][..., 0]
    pts.append((end + r[s3][None, :, None] * up).mean(axis=1))
    nrm.append(_unit(up.mean(axis=1)))
    fwd.append(np.broadcast_to([0.0, 0.0, 1.0], (t, 3)))
    point = np.stack(pts, axis=1)
    normal = np.stack(nrm, axis=1)
    return point, normal, orthogonal_forward(np.stack(fwd, axis=1), normal)


def orthogonal_forward(forward: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(T, 3) unit ``forward`` made orthogonal to ``normal``; the hand's y axis where they are parallel."""
    f = forward - (forward * normal).sum(-1, keepdims=True) * normal
    n = np.linalg.norm(f, axis=-1, keepdims=True)
    alt = np.array([0.0, 1.0, 0.0]) - normal[..., 1:2] * normal
    f = np.where(n > 1e-6, f, alt)
    return _unit(f)
