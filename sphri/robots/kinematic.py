"""``KinematicRobot``: a whole robot as a kinematic tree of parametric links (``robot=reachy_full``).

Each link is a loft from dimensions (:func:`sphri.robots.parametric.loft_mesh`,
no files) in its own frame; the tree places every link frame relative to its
parent by a fixed origin (``xyz`` metres, ``rpy`` radians, URDF order: roll
about x, pitch about y, yaw about z) followed by the link's revolute joints
(``"name:axis"``, applied in order). The root's world pose is the mobile
base's planar pose (x, y, yaw). :meth:`WholeBodyRobot.link_poses` poses the
whole tree for many frames at once.

Skin *body parts* are named subsets of link surfaces: a link, optionally cut
by the outward normal's sign along a link axis (``side: +x``) and a height
band along the link's z (``z_min``, ``z_max``, metres). *Groups* name sets of
parts (``upper_torso: [torso_front_upper, torso_back_upper]``); both are YAML
and can be regrouped freely. ``Robot.regions`` maps every part (and every
group whose parts lie on one link, and every link name) to its link, so the
resolution study runs on any of them (``data.regions=[upper_arm_l]``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sphri.robots.parametric import loft_mesh
from sphri.robots.schema import check_kinematic, check_part_specs, tree_order
from sphri.robots.validate import make_link
from sphri.types import Robot

log = logging.getLogger(__name__)

AXIS_VECTORS = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


def rotation_about(axis: str, angle: np.ndarray | float) -> np.ndarray:
    """(..., 3, 3) rotations by ``angle`` (...,) radians about link axis x, y or z."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    if axis == "x":
        rows = [[one, zero, zero], [zero, c, -s], [zero, s, c]]
    elif axis == "y":
        rows = [[c, zero, s], [zero, one, zero], [-s, zero, c]]
    elif axis == "z":
        rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    else:
        raise ValueError(f"axis={axis!r} is invalid: allowed values: x, y, z")
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def axis_rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations by ``angle`` (...,) radians about the unit vector ``axis`` (3,) (Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    a = np.asarray(angle, dtype=np.float64)[..., None, None]
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(a) * kx + (1.0 - np.cos(a)) * (kx @ kx)


def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """(3, 3) URDF fixed-axis roll-pitch-yaw rotation: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = (float(v) for v in rpy)
    return rotation_about("z", y) @ rotation_about("y", p) @ rotation_about("x", r)


def joint_motion(kind: str, axis: Sequence[float], q: np.ndarray) -> np.ndarray:
    """(F, 4, 4) motions of a joint by its values ``q`` (F,): translation along ``axis`` (``prismatic``,
    metres), rotation about it (``revolute``, ``continuous``; radians), none (other kinds)."""
    m = np.tile(np.eye(4), (len(q), 1, 1))
    if kind == "prismatic":
        m[:, :3, 3] = q[:, None] * np.asarray(axis, dtype=np.float64)[None, :]
    elif kind in ("revolute", "continuous"):
        m[:, :3, :3] = axis_rotation(np.asarray(axis), q)
    return m


def mimic_value(name: str, mimic: Mapping[str, tuple[str, float, float]], own: Callable[[str], Any], depth: int = 0):
    """Joint ``name``'s value: ``own(name)``, or for a joint in ``mimic`` (joint -> (source, multiplier,
    offset)) its source's value times the multiplier plus the offset (chains followed 16 deep)."""
    if name in mimic and depth < 16:
        src, mult, off = mimic[name]
        return mult * mimic_value(src, mimic, own, depth + 1) + off
    return own(name)


@dataclass(frozen=True)
class BodyPart:
    """A named piece of a link's surface."""

    name: str
    link: str
    side: str | None = None
    """Keep surface points whose outward normal has this sign along this link axis (``+x``), or all."""
    z_min: float | None = None
    """Keep points at link-frame z >= z_min (metres)."""
    z_max: float | None = None
    """Keep points at link-frame z < z_max (metres)."""
    min_cos: float = 0.0
    """With ``side``: keep points whose unit normal's component along the side exceeds this
    (0: any point facing that way; 0.5: within 60 degrees of it, e.g. a top face)."""
    mountable: bool = True
    """False for a surface no skin can be fixed to: a joint's rotating shell (the scenario study leaves it out of
    the ranking, the placement and the skin design)."""

    def contains(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """(P,) bool for (P, 3) link-frame points with outward normals."""
        ok = np.ones(len(points), dtype=bool)
        if self.side is not None:
            v = normals @ AXIS_VECTORS[self.side[1]]
            if self.min_cos > 0:
                ok &= v > self.min_cos if self.side[0] == "+" else v < -self.min_cos
            else:
                ok &= v > 0 if self.side[0] == "+" else v <= 0
        if self.z_min is not None:
            ok &= points[:, 2] >= self.z_min
        if self.z_max is not None:
            ok &= points[:, 2] < self.z_max
        return ok


@dataclass(frozen=True)
class JointStep:
    """One movable joint on the way from a link's parent to the link (URDF trees, :mod:`sphri.robots.urdf_tree`).

    The joint moves (``revolute``: rotation about ``axis``; ``prismatic``:
    translation along it), then the fixed transform ``after`` follows (the
    next joint's origin on the path, identity for the last one). A ``mimic``
    joint follows ``(source joint, multiplier, offset)`` and is not a joint
    of its own in :attr:`JointTree.joint_names`.
    """

    name: str
    kind: str
    axis: tuple[float, float, float]
    after: np.ndarray
    mimic: tuple[str, float, float] | None = None


@dataclass(frozen=True)
class JointTree:
    """The kinematic tree in topological order (parents before children)."""

    links: tuple[str, ...]
    parent: tuple[int, ...]
    """Index of each link's parent in ``links``, -1 for the root."""
    origin: np.ndarray
    """(L, 4, 4) fixed transform parent frame -> joint frame."""
    joints: tuple[tuple[tuple[str, str], ...], ...]
    """Per link: (joint name, axis) applied in order after ``origin``."""
    steps: tuple[tuple[JointStep, ...], ...] | None = None
    """Per link, instead of ``joints``: general joints (any axis, prismatic, mimic) with fixed
    transforms between them (trees read from a URDF); None for the parametric trees."""

    @property
    def joint_names(self) -> list[str]:
        if self.steps is not None:
            return [s.name for ss in self.steps for s in ss if s.mimic is None]
        return [j for js in self.joints for j, _ in js]

    @property
    def mimic(self) -> dict[str, tuple[str, float, float]]:
        """Mimic joint -> (source joint, multiplier, offset)."""
        return {s.name: s.mimic for ss in (self.steps or ()) for s in ss if s.mimic is not None}


@dataclass(frozen=True)
class WholeBodyRobot(Robot):
    """A :class:`Robot` that also knows its kinematic tree, body parts and part groups."""

    tree: JointTree | None = None
    parts: tuple[BodyPart, ...] = ()
    groups: dict[str, tuple[str, ...]] = field(default_factory=dict)
    rest: dict[str, float] = field(default_factory=dict)
    """Joint angles (radians) of the rest pose; others 0."""
    skipped: tuple[tuple[str, str], ...] = ()
    """(link, reason) of every link of the robot's description that has no surface here (URDF robots)."""

    def link_poses(self, base: np.ndarray, joints: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """(F, L, 4, 4) world transforms of every link (``tree.links`` order).

        ``base`` (F, 3): the mobile base's x, y (metres) and yaw (radians);
        ``joints``: joint name -> (F,) angles (missing joints take the rest pose).
        """
        tree = self.tree
        if tree is None:
            raise ValueError(f"robot {self.name!r} has no kinematic tree: it cannot pose its links")
        base = np.atleast_2d(np.asarray(base, dtype=np.float64))
        if base.ndim != 2 or base.shape[1] != 3:
            raise ValueError(f"base must be (F, 3) x, y, yaw, got {base.shape}")
        f = base.shape[0]
        joints = dict(joints or {})
        unknown = sorted(set(joints) - set(tree.joint_names))
        if unknown:
            raise ValueError(f"robot {self.name!r} has no joint(s) {unknown}; joints: {tree.joint_names}")
        root = np.tile(np.eye(4), (f, 1, 1))
        root[:, :3, :3] = rotation_about("z", base[:, 2])
        root[:, 0, 3], root[:, 1, 3] = base[:, 0], base[:, 1]
        out = np.empty((f, len(tree.links), 4, 4))
        mimic = tree.mimic

        def given(name: str) -> np.ndarray:
            return np.broadcast_to(np.asarray(joints.get(name, self.rest.get(name, 0.0)), dtype=np.float64), (f,))

        for i, _name in enumerate(tree.links):
            m = (root if tree.parent[i] < 0 else out[:, tree.parent[i]]) @ tree.origin[i]
            for step in tree.steps[i] if tree.steps is not None else ():
                m = m @ joint_motion(step.kind, step.axis, mimic_value(step.name, mimic, given)) @ step.after
            for jname, axis in tree.joints[i]:
                rot = np.tile(np.eye(4), (f, 1, 1))
                rot[:, :3, :3] = rotation_about(axis, given(jname))
                m = m @ rot
            out[:, i] = m
        return out

    def rest_poses(self) -> np.ndarray:
        """(L, 4, 4) link transforms of the rest pose at the world origin."""
        return self.link_poses(np.zeros((1, 3)))[0]

    def part_labels(self, link: str, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """(P,) object array: the first body part of ``link`` holding each point ('' if none)."""
        out = np.full(len(points), "", dtype=object)
        for part in self.parts:
            if part.link != link:
                continue
            free = out == ""
            hit = free & part.contains(points, normals)
            out[hit] = part.name
        return out


class KinematicRobot:
    """A whole robot from dimensions (``robot=reachy_full``): links, tree, parts, groups (see module)."""

    VERSION = "1"

    def __init__(
        self,
        name: str,
        links: Mapping[str, Any],
        parts: Mapping[str, Any],
        groups: Mapping[str, Any] | None = None,
        rest: Mapping[str, float] | None = None,
    ):
        self.name = str(name)
        spec = check_kinematic(links, parts, groups, rest)  # the schema's checks (sphri.robots.schema)
        self.specs = spec.links
        self.parts = [BodyPart(**p) for p in spec.parts]
        self.groups = spec.groups
        self.rest = spec.rest
        self.tree = build_tree(self.specs)

    def build(self) -> WholeBodyRobot:
        links = {}
        for name, spec in self.specs.items():
            v, f = loft_mesh(**spec["shape"])
            links[name] = make_link(name, v, f, units="m", source=f"kinematic {self.name}")
        return WholeBodyRobot(
            name=self.name,
            links=links,
            regions=part_regions(links, self.parts, self.groups),
            tree=self.tree,
            parts=tuple(self.parts),
            groups={k: tuple(v) for k, v in self.groups.items()},
            rest=dict(self.rest),
        )


def build_tree(specs: Mapping[str, dict]) -> JointTree:
    """Topologically ordered :class:`JointTree` of checked tree links (:func:`sphri.robots.schema.check_tree_link`;
    the order and its checks: :func:`sphri.robots.schema.tree_order`)."""
    order = tree_order(specs)
    origin = np.tile(np.eye(4), (len(order), 1, 1))
    for i, n in enumerate(order):
        origin[i, :3, :3] = rpy_matrix(specs[n]["rpy"])
        origin[i, :3, 3] = specs[n]["xyz"]
    return JointTree(
        links=tuple(order),
        parent=tuple(-1 if specs[n]["parent"] is None else order.index(specs[n]["parent"]) for n in order),
        origin=origin,
        joints=tuple(tuple(specs[n]["joints"]) for n in order),
    )


def part_regions(
    links: Mapping[str, Any], parts: Sequence[BodyPart], groups: Mapping[str, Sequence[str]]
) -> dict[str, str]:
    """Region name -> link: every link its own, each body part its link, and each group whose parts all lie
    on one link that link."""
    regions = {n: n for n in links}
    for p in parts:
        regions[p.name] = p.link
    by_part = {p.name: p.link for p in parts}
    for g, members in groups.items():
        owners = {by_part[x] for x in members}
        if len(owners) == 1:
            regions[g] = owners.pop()
    return regions


def check_parts(parts: Any, specs: Mapping[str, Any]) -> list[BodyPart]:
    """``robot.parts`` as :class:`BodyPart` (checks: :func:`sphri.robots.schema.check_part_specs`)."""
    return [BodyPart(**p) for p in check_part_specs(parts, specs)]
