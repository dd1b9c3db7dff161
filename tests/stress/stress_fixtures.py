"""Degenerate links, hands and datasets shared by the stress tests (plain functions, no pytest).

Links (metres, link frame): the built-in Reachy arm, a nearly spherical
icosphere, a thin disc (a very short link), the arm re-triangulated with
zero-area and sliver triangles, and the arm 1000 m from the origin.

:func:`degenerate_dataset` poses a three-capsule hand (a finger capsule, a
zero-length palm sphere and a long thumb) in the configurations that stress
the chain: capsules exactly tangent to faces, touching vertices and edges,
wholly inside, across the cylinder's angular seam, on an end cap's centre
(on the axis), lying through the whole link, plus a trial with no contact and
an empty trial (0 frames).
"""

from __future__ import annotations

from dataclasses import fields, is_dataclass
from functools import cache
from typing import Any

import numpy as np
import trimesh
from omegaconf import OmegaConf
from scipy.spatial.transform import Rotation

from sphri.config import CONF_DIR
from sphri.data.format import make_trials_frame
from sphri.robots.parametric import ParametricRobot
from sphri.surface.cylinder import CylinderSurface
from sphri.surface.meshutil import face_areas, face_normals, link_from_trimesh, sample_surface
from sphri.types import GESTURES, Contacts, GestureDataset, HandModel, Link, Robot

#: Offset of the ``far`` link from the origin (metres).
FAR_OFFSET_M = np.array([1000.0, -1000.0, 1000.0])

#: Names of the degenerate links, in the order tests parametrize over them.
LINK_NAMES = ("arm", "sphere", "disc", "slivers", "far")

#: Frames per trial of :func:`degenerate_dataset`.
TRIAL_FRAMES = 6

#: The configurations of :func:`degenerate_dataset`, one trial each per participant, in trial order.
CONFIGS = ("tangent", "vertex_edge", "inside", "seam", "cap_centre", "through", "no_contact", "mixed", "empty")


@cache
def reachy_arm() -> Link:
    """The built-in Reachy arm (``conf/robot/reachy.yaml``, closed loft, 24 cm along z)."""
    spec = OmegaConf.to_container(OmegaConf.load(CONF_DIR / "robot" / "reachy.yaml"), resolve=True)
    robot = ParametricRobot(name=spec["name"], links=spec["links"], regions=spec["regions"]).build()
    return robot.link_for("arm")


def with_slivers(link: Link, seed: int = 0) -> Link:
    """``link`` re-triangulated: every third face split at a point on (or 1e-9 m off) an edge.

    The surface is unchanged; the mesh gains zero-area triangles (the point
    exactly on the edge) and slivers (1 nm off it).
    """
    rng = np.random.default_rng(seed)
    v = [np.asarray(link.vertices, dtype=np.float64)]
    faces = []
    n_v = len(v[0])
    for j, (a, b, c) in enumerate(np.asarray(link.faces)):
        if j % 3:
            faces.append((a, b, c))
            continue
        pa, pb, pc = v[0][[a, b, c]]
        t = rng.uniform(0.2, 0.8)
        p = pa + t * (pb - pa)
        if j % 2:  # a sliver: 1 nm towards the opposite vertex
            d = pc - p
            p = p + 1e-9 * d / np.linalg.norm(d)
        v.append(p[None])
        faces += [(a, b, n_v), (b, c, n_v), (c, a, n_v)]
        n_v += 1
    return Link(
        name=f"{link.name}_slivers",
        vertices=np.concatenate(v),
        faces=np.asarray(faces, dtype=np.int64),
        watertight=link.watertight,
        notes=("re-triangulated with zero-area and sliver faces",),
    )


def translated(link: Link, offset: np.ndarray, name: str | None = None) -> Link:
    """``link`` moved by ``offset`` (3,) metres."""
    return Link(
        name=name or f"{link.name}_moved",
        vertices=np.asarray(link.vertices, dtype=np.float64) + np.asarray(offset, dtype=np.float64),
        faces=np.asarray(link.faces, dtype=np.int64),
        watertight=link.watertight,
    )


@cache
def make_link(name: str) -> Link:
    """One of :data:`LINK_NAMES` (cached; Links are frozen)."""
    if name == "arm":
        return reachy_arm()
    if name == "sphere":
        return link_from_trimesh(trimesh.creation.icosphere(subdivisions=2, radius=0.05), "sphere")
    if name == "disc":
        return link_from_trimesh(trimesh.creation.cylinder(radius=0.05, height=0.004, sections=64), "disc")
    if name == "slivers":
        return with_slivers(reachy_arm())
    if name == "far":
        return translated(reachy_arm(), FAR_OFFSET_M, "arm_far")
    raise KeyError(f"unknown stress link {name!r}; known: {LINK_NAMES}")


def stress_hand() -> HandModel:
    """Three capsules: a finger (r 8 mm), a zero-length palm sphere (r 20 mm), a long thumb (r 10 mm, 28 cm core)."""
    return HandModel(
        names=("index1", "palm", "thumb1"),
        fingers=("index", "palm", "thumb"),
        radius_m=np.array([0.008, 0.020, 0.010]),
        height_m=np.array([0.040, 0.040, 0.300]),
        axis=np.array([0, 0, 2], dtype=np.int64),
        center_offset_m=np.zeros((3, 3)),
    )


def quat_from_to(axis_index: int, direction: np.ndarray) -> np.ndarray:
    """(4,) xyzw quaternion turning the local axis ``axis_index`` onto ``direction``."""
    e = np.eye(3)[axis_index]
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    rot, _ = Rotation.align_vectors(d[None], e[None])
    return rot.as_quat()


def vertex_normals(link: Link) -> np.ndarray:
    """(V, 3) area-weighted unit vertex normals (zero where no face has area)."""
    f = np.asarray(link.faces)
    fn = face_normals(link) * face_areas(link)[:, None]
    vn = np.zeros((len(link.vertices), 3))
    for k in range(3):
        np.add.at(vn, f[:, k], fn)
    n = np.linalg.norm(vn, axis=1, keepdims=True)
    return np.divide(vn, n, out=np.zeros_like(vn), where=n > 0)


def degenerate_dataset(link: Link, participants: int = 2, seed: int = 0) -> GestureDataset:
    """Trials of :func:`stress_hand` in the degenerate configurations of the module docstring.

    Every configuration is one trial of :data:`TRIAL_FRAMES` frames per
    participant (participants alternate, gestures cycle through
    :data:`~sphri.types.GESTURES`); unused capsules are parked 1 m away.
    Poses are float32 like every dataset's.
    """
    rng = np.random.default_rng(seed)
    hand = stress_hand()
    v = np.asarray(link.vertices, dtype=np.float64)
    f = np.asarray(link.faces, dtype=np.int64)
    fa = face_areas(link)
    fn = face_normals(link)
    vn = vertex_normals(link)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    good_faces = np.flatnonzero(fa > 1e-3 * fa.max())
    used_v = np.unique(f[good_faces])
    cyl = CylinderSurface().fit(link).params
    axis, ref, origin = cyl["axis"], cyl["ref"], cyl["origin"]
    r0, r1, r2 = hand.radius_m
    park = centre + np.array([1.0, 1.0, 1.0])
    ident = np.array([0.0, 0.0, 0.0, 1.0])

    def frame(**caps: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        row = np.zeros((3, 7))
        for i, name in enumerate(hand.names):
            pos, q = caps.get(name, (park + 0.1 * i, ident))
            row[i, :3], row[i, 3:] = pos, q
        return row

    def face_point(j: int) -> np.ndarray:
        w = rng.dirichlet(np.ones(3)) * 0.6 + 0.4 / 3
        return w @ v[f[j]]

    def tangent_dir(n: np.ndarray) -> np.ndarray:
        t = np.cross(n, [1.0, 0.0, 0.0])
        if np.linalg.norm(t) < 0.1:
            t = np.cross(n, [0.0, 1.0, 0.0])
        return t / np.linalg.norm(t)

    configs: dict[str, list[np.ndarray]] = {}
    rows = []
    for _ in range(TRIAL_FRAMES):  # finger lying on a face, palm sphere resting on another: exactly tangent
        j, k = rng.choice(good_faces, 2)
        p, n = face_point(j), fn[j]
        q_, m = face_point(k), fn[k]
        rows.append(frame(index1=(p + r0 * n, quat_from_to(0, tangent_dir(n))), palm=(q_ + r1 * m, ident)))
    configs["tangent"] = rows
    rows = []
    for _ in range(TRIAL_FRAMES):  # finger end on a vertex, pointing out; palm sphere on an edge
        i = int(rng.choice(used_v))
        d = vn[i] if np.linalg.norm(vn[i]) > 0 else np.array([0.0, 0.0, 1.0])
        j = int(rng.choice(good_faces))
        a, b = v[f[j, 0]], v[f[j, 1]]
        rows.append(
            frame(
                index1=(v[i] + 0.5 * hand.segment_length_m[0] * d, quat_from_to(0, d)),
                palm=(0.5 * (a + b) + 0.5 * r1 * fn[j], ident),
            )
        )
    configs["vertex_edge"] = rows
    configs["inside"] = [frame(palm=(centre + rng.normal(scale=1e-4, size=3), ident)) for _ in range(TRIAL_FRAMES)]
    rows = []
    for _ in range(
        TRIAL_FRAMES
    ):  # finger across the angular seam (v = 0), pressed 80 % of its radius into the cylinder
        t = rng.uniform(cyl["u_min"] * 0.5, cyl["u_max"] * 0.5)
        p = origin + t * axis + (cyl["radius"] + 0.2 * r0) * ref
        rows.append(frame(index1=(p, quat_from_to(0, np.cross(axis, ref)))))
    configs["seam"] = rows
    rows = []
    for s in range(TRIAL_FRAMES):  # palm sphere on an end cap's centre (on the axis): the chart's pole
        end = cyl["u_max"] if s % 2 == 0 else cyl["u_min"]
        sign = 1.0 if s % 2 == 0 else -1.0
        rows.append(frame(palm=(origin + end * axis + sign * 0.5 * r1 * axis, ident)))
    configs["cap_centre"] = rows
    configs["through"] = [
        frame(thumb1=(origin + rng.normal(scale=1e-3, size=3), quat_from_to(2, axis))) for _ in range(TRIAL_FRAMES)
    ]
    configs["no_contact"] = [frame() for _ in range(TRIAL_FRAMES)]
    rows = []
    for _ in range(TRIAL_FRAMES):  # everything at once near random surface points, random orientations
        j, k, m = rng.choice(good_faces, 3)
        caps = {}
        for name, jj, r in (("index1", j, r0), ("palm", k, r1), ("thumb1", m, r2)):
            h = rng.uniform(-0.5, 1.0) * r
            caps[name] = (face_point(jj) + h * fn[jj], Rotation.random(random_state=rng.integers(2**31)).as_quat())
        rows.append(frame(**caps))
    configs["mixed"] = rows
    configs["empty"] = []
    assert tuple(configs) == CONFIGS

    records, poses = [], []
    start = 0
    ordinal = 0
    for p in range(participants):
        for g, (_name, rows) in enumerate(configs.items()):
            ordinal += 1
            gesture = GESTURES[g % len(GESTURES)]
            records.append(
                {
                    "participant": f"participant_{p + 1:02d}",
                    "region": "arm",
                    "trial_ordinal": ordinal,
                    "trial_id": f"{ordinal:04d}_{gesture}",
                    "gesture": gesture,
                    "start": start,
                    "n_frames": len(rows),
                }
            )
            poses += rows
            start += len(rows)
    return GestureDataset(
        name=f"stress_{link.name}",
        synthetic=True,
        hand=hand,
        trials=make_trials_frame(records),
        poses=np.asarray(poses, dtype=np.float32).reshape(-1, 3, 7),
        frame_rate_hz=30.0,
    )


def near_surface_dataset(
    link: Link, n_frames: int, seed: int, participants: int = 2, spheres: bool = False
) -> GestureDataset:
    """:func:`stress_hand` capsules near random surface points of ``link``, random orientations.

    Each capsule's centre sits at ``h`` from a surface point along its face
    normal, ``h`` uniform in [-0.5, 1.5] radii (so about half touch), one
    trial of ``n_frames`` frames per participant. float32 poses.
    ``spheres``: zero-length capsules (no segment crosses the surface twice).
    """
    rng = np.random.default_rng(seed)
    hand = stress_hand()
    if spheres:
        hand = HandModel(hand.names, hand.fingers, hand.radius_m, 2 * hand.radius_m, hand.axis, hand.center_offset_m)
    pts, face = sample_surface(link, n_frames * participants * 3, seed)
    nrm = face_normals(link)[face]
    h = rng.uniform(-0.5, 1.5, len(pts)) * np.tile(hand.radius_m, n_frames * participants)
    pos = pts + h[:, None] * nrm
    quat = Rotation.random(len(pts), random_state=int(rng.integers(2**31))).as_quat()
    poses = np.concatenate([pos, quat], axis=1).reshape(-1, 3, 7).astype(np.float32)
    records = [
        {
            "participant": f"participant_{p + 1:02d}",
            "region": "arm",
            "trial_ordinal": p + 1,
            "trial_id": f"{p + 1:04d}_{GESTURES[p % len(GESTURES)]}",
            "gesture": GESTURES[p % len(GESTURES)],
            "start": p * n_frames,
            "n_frames": n_frames,
        }
        for p in range(participants)
    ]
    return GestureDataset(f"near_{link.name}", True, hand, make_trials_frame(records), poses, 30.0)


@cache
def degenerate_for(name: str) -> GestureDataset:
    """:func:`degenerate_dataset` of :func:`make_link` ``(name)``, built once (do not mutate it)."""
    return degenerate_dataset(make_link(name))


def robot_of(link: Link) -> Robot:
    """A one-link robot whose ``arm`` region is ``link``."""
    return Robot(name="stress", links={link.name: link}, regions={"arm": link.name})


def transform_dataset(ds: GestureDataset, rot: Rotation, shift: np.ndarray, scale: float = 1.0) -> GestureDataset:
    """Poses moved by ``x -> scale * (rot x) + shift`` (quaternions rotated), hand scaled by ``scale``.

    Computed in float64 from the float32 poses and stored as float32 again.
    """
    p = ds.poses.astype(np.float64)
    pos = scale * rot.apply(p[..., :3].reshape(-1, 3)) + shift
    quat = (rot * Rotation.from_quat(p[..., 3:].reshape(-1, 4))).as_quat()
    poses = np.concatenate([pos, quat], axis=1).reshape(p.shape).astype(np.float32)
    h = ds.hand
    hand = HandModel(h.names, h.fingers, h.radius_m * scale, h.height_m * scale, h.axis, h.center_offset_m * scale)
    return GestureDataset(ds.name, ds.synthetic, hand, ds.trials.copy(), poses, ds.frame_rate_hz, dict(ds.repairs))


def transform_link(link: Link, rot: Rotation, shift: np.ndarray, scale: float = 1.0) -> Link:
    """``link`` moved by ``x -> scale * (rot x) + shift``."""
    return Link(
        link.name,
        scale * rot.apply(np.asarray(link.vertices, dtype=np.float64)) + shift,
        np.asarray(link.faces),
        link.watertight,
        link.notes,
    )


def nonfinite_fields(obj: Any, prefix: str = "") -> list[str]:
    """Names of the float array fields of a dataclass (or dict) holding NaN or inf."""
    bad = []
    items = (
        ((fl.name, getattr(obj, fl.name)) for fl in fields(obj))
        if is_dataclass(obj)
        else (obj.items() if isinstance(obj, dict) else ())
    )
    for name, val in items:
        if isinstance(val, np.ndarray) and np.issubdtype(val.dtype, np.floating):
            if not np.all(np.isfinite(val)):
                bad.append(f"{prefix}{name}")
        elif isinstance(val, float) and not np.isfinite(val):
            bad.append(f"{prefix}{name}")
        elif isinstance(val, dict) or (is_dataclass(val) and not isinstance(val, type)):
            bad += nonfinite_fields(val, f"{prefix}{name}.")
    return bad


def compare_contacts(
    a: Contacts, b: Contacts, rot: Rotation, shift: np.ndarray, scale: float, tol: float, radius_m: np.ndarray
) -> list[str]:
    """Differences between ``b`` and ``a`` mapped through ``x -> scale * (rot x) + shift``.

    ``tol`` (metres, in ``b``'s units) absorbs the float32 rounding of the
    poses. Rows present on one side only must be within ``tol`` of tangency;
    matching rows must agree in distance, depth, inside flag, patch radius
    (squared, inside a triangle and away from the switch to the full radius
    at depth = 2 r), closest point and, inside a triangle, its normal. ``radius_m`` (C,) are ``b``'s
    capsule radii.
    """
    problems = []
    ka = a.frame.astype(np.int64) * 65536 + a.capsule
    kb = b.frame.astype(np.int64) * 65536 + b.capsule
    only_a = ~np.isin(ka, kb)
    only_b = ~np.isin(kb, ka)
    if np.any(scale * a.depth_m[only_a] > tol):
        problems.append(f"rows lost: depths {scale * a.depth_m[only_a][scale * a.depth_m[only_a] > tol][:5]}")
    if np.any(b.depth_m[only_b] > tol):
        problems.append(f"rows gained: depths {b.depth_m[only_b][b.depth_m[only_b] > tol][:5]}")
    ia = np.flatnonzero(~only_a)
    ib = np.flatnonzero(~only_b)
    if not np.array_equal(ka[ia], kb[ib]):
        return problems + ["row order differs"]
    r = radius_m[b.capsule[ib]]
    da, db = scale * a.distance_m[ia], b.distance_m[ib]
    depth_a, depth_b = scale * a.depth_m[ia], b.depth_m[ib]
    if np.any(np.abs(depth_a - depth_b) > 2 * tol):
        problems.append(f"depth differs by up to {np.abs(depth_a - depth_b).max():.3g} m")
    near_surface = (da < tol) | (db < tol)
    same_side = a.inside[ia] == b.inside[ib]
    if np.any(~same_side & ~near_surface):
        problems.append("inside flag differs away from the surface")
    ok = same_side & ~near_surface
    if np.any(np.abs(da - db)[ok] > tol):
        problems.append(f"distance differs by up to {np.abs(da - db)[ok].max():.3g} m")
    # a segment through the surface (distance 0) may cross it more than once: its closest
    # point, triangle and patch are then not unique, so compare them only away from the surface;
    # on an edge or vertex either triangle holds the point, and the patch lies in that one's plane
    interior = (a.barycentric[ia].min(axis=1) > 1e-3) & (b.barycentric[ib].min(axis=1) > 1e-3) & ok
    switch = a.inside[ia] & (np.abs(depth_b - 2 * r) < 4 * tol)
    pa2, pb2 = (scale * a.patch_radius_m[ia]) ** 2, b.patch_radius_m[ib] ** 2
    bad = (np.abs(pa2 - pb2) > 4 * r * tol) & ~switch & interior
    if bad.any():
        problems.append(f"patch radius^2 differs by up to {np.abs(pa2 - pb2)[bad].max():.3g} m^2")
    pa = scale * rot.apply(a.point_m[ia]) + shift
    gap = np.linalg.norm(pa - b.point_m[ib], axis=1)[ok]
    if np.any(gap > 20 * tol):
        problems.append(f"closest point moved by up to {gap.max():.3g} m")
    na = rot.apply(a.normal[ia])
    if np.any(np.abs(na - b.normal[ib])[interior] > 1e-6):
        problems.append("normals differ inside triangles")
    return problems
