"""``data=synthetic_sessions``: a built-in synthetic scenario study (SYNTHETIC).

Participants x scenarios x repetitions sessions with the whole robot
(``robot=reachy_full``). What people do in each scenario (where they start,
which body parts they touch with which gesture, one or two hands, how fast,
how the robot moves) is read from a YAML table of assumptions
(:data:`DEFAULT_PRIORS`, ``sphri/sessions/scenario_priors.yaml``; copy and
edit it, pass ``data.priors=PATH``). Nothing in it is measured.

A session, in the world frame (the robot's base starts at the origin facing +x):

1. the touching hand(s) travel from the participant's side (at the scenario's
   starting position) to the touch for ``approach_s``; the robot runs its
   scripted motion meanwhile (``base``: drives towards the participant;
   ``arm``: the nearer arm follows a sorting trajectory);
2. the touch itself is one trial of the gesture generator
   (:class:`sphri.data.synthetic.SyntheticData`: rest, approach, contact,
   retreat) on the drawn body part's surface, in that link's frame, placed
   in the world by the link's pose (the robot stops when the touch begins,
   as in the study), time-scaled by ``duration_scale``; every frame each hand is
   moved back along its approach until it presses at most ``compliance_mm`` into
   its part's link and touches no other (:func:`settle_hands`), and in the
   gesture's contact phase a hand this left off its link is pulled back onto it
   (:func:`hold_contact`), then settled again;
4. the hands stay off the robot for ``tail_s`` (>= 2 s ends the episode).

The other hand hangs at the participant's side unless the session is two-handed
(then it touches the mirrored body part with the same gesture). Both hands use
the 19-capsule hand model. Scenario order per participant follows a cyclic
Latin square; starting positions are fixed per participant. Participant
``k``'s sessions come from the random stream ``(seed, k, scenario, repetition)``.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from sphri.data.format import participant_id
from sphri.data.gestures import Style
from sphri.data.handfk import HandRig, matrix_to_quat
from sphri.data.linkgeom import LinkSurface
from sphri.data.people import Spread
from sphri.data.synthetic import SyntheticData
from sphri.hand.kinematics import quat_to_matrix
from sphri.robots.kinematic import JointTree, WholeBodyRobot
from sphri.sessions.format import SessionDataset, make_sessions_frame
from sphri.types import GESTURES, HandModel, Link, Robot

log = logging.getLogger(__name__)

DEFAULT_PRIORS = Path(__file__).with_name("scenario_priors.yaml")
#: Starting directions in the robot's base frame at t=0 (robot faces +x, its left is +y).
DIRECTIONS = {"front": 0.0, "front_left": 45.0, "left": 90.0, "rear": 180.0, "right": -90.0, "front_right": -45.0}
MOTIONS = ("none", "base", "arm")
SCENARIO_KEYS = (
    "start_positions",
    "start_distance_m",
    "approach_s",
    "robot_motion",
    "parts",
    "gestures",
    "two_hands",
)
#: Optional per-scenario keys of the priors table (absent: the default given).
OPTIONAL_KEYS = {"duration_scale": [1.0, 1.0]}


class PriorsError(ValueError):
    """The scenario priors table is malformed; names the file and key."""


#: The joints a scenario with ``robot_motion: arm`` moves, per side (``l``/``r``): the sorting trajectory.
ARM_JOINTS = ("shoulder_pitch", "elbow_pitch")


def load_priors(
    path: str | Path, part_names: Sequence[str], joint_names: Sequence[str] | None = None
) -> dict[str, Any]:
    """Read and check the priors table against the robot's body parts (and, given ``joint_names``, the joints
    a ``robot_motion: arm`` scenario moves)."""
    path = Path(path)
    if not path.is_file():
        raise PriorsError(f"data.priors={str(path)!r}: no such file")
    try:
        table = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise PriorsError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(table, dict) or not isinstance(table.get("scenarios"), dict) or not table["scenarios"]:
        raise PriorsError(f"{path}: needs a non-empty mapping 'scenarios'")
    for key in ("tail_s", "base_speed_m_s"):
        if not isinstance(table.get(key), (int, float)) or not table[key] > 0:
            raise PriorsError(f"{path}: {key}={table.get(key)!r} is invalid: a number > 0")
    if table["tail_s"] < 2.0:
        log.warning("%s: tail_s=%s < 2 s: episodes of consecutive sessions' ends may not close", path, table["tail_s"])
    parts = set(part_names)
    given: dict[str, list[str]] = {}
    for name, s in table["scenarios"].items():
        key = f"{path}: scenarios.{name}"
        if not isinstance(s, dict):
            raise PriorsError(f"{key} must be a mapping")
        given[name] = [k for k in s if k != "prompt"]
        missing = [k for k in SCENARIO_KEYS if k not in s]
        if missing:
            raise PriorsError(f"{key} is missing {missing}")
        bad = [p for p in s["start_positions"] if p not in DIRECTIONS]
        if bad or not s["start_positions"]:
            raise PriorsError(f"{key}.start_positions: unknown {bad}; allowed: {list(DIRECTIONS)}")
        if s["robot_motion"] not in MOTIONS:
            raise PriorsError(f"{key}.robot_motion={s['robot_motion']!r}: allowed values: {list(MOTIONS)}")
        arm = [f"{side}_{j}" for side in "lr" for j in ARM_JOINTS]
        if s["robot_motion"] == "arm" and joint_names is not None and not set(arm) <= set(joint_names):
            raise PriorsError(
                f"{key}.robot_motion=arm moves the joints {arm}; the robot has {sorted(joint_names)} "
                "(robot_motion: none or base, or name the arm joints so)"
            )
        for k, default in OPTIONAL_KEYS.items():
            s.setdefault(k, list(default))
        for k in ("approach_s", "duration_scale"):
            v = s[k]
            if not (isinstance(v, list) and len(v) == 2 and 0 < v[0] <= v[1]):
                raise PriorsError(f"{key}.{k}={v!r} is invalid: [min, max] with 0 < min <= max")
        if not 0.0 <= float(s["two_hands"]) <= 1.0:
            raise PriorsError(f"{key}.two_hands={s['two_hands']!r} is invalid: a probability in [0, 1]")
        if not float(s["start_distance_m"]) > 0.3:
            raise PriorsError(f"{key}.start_distance_m={s['start_distance_m']!r} is invalid: > 0.3 m")
        for p, w in s["parts"].items():
            base = p[:-5] if p.endswith("_near") else p[:-4] if p.endswith("_far") else None
            ok = (p in parts) if base is None else (f"{base}_l" in parts and f"{base}_r" in parts)
            if not ok:
                raise PriorsError(
                    f"{key}.parts.{p}: no such body part on the robot (parts: {sorted(parts)}; "
                    "suffix _near/_far needs <part>_l and <part>_r)"
                )
            if not float(w) >= 0:
                raise PriorsError(f"{key}.parts.{p}={w!r} is invalid: a weight >= 0")
        for g, w in s["gestures"].items():
            if g not in GESTURES:
                raise PriorsError(f"{key}.gestures.{g}: unknown gesture; allowed: {list(GESTURES)}")
            if not float(w) >= 0:
                raise PriorsError(f"{key}.gestures.{g}={w!r} is invalid: a weight >= 0")
        for k in ("parts", "gestures"):
            if sum(float(w) for w in s[k].values()) <= 0:
                raise PriorsError(f"{key}.{k}: weights must not all be 0")
    table["provenance"] = check_provenance(path, table, given)
    return table


#: The fields of a scenario a provenance entry may name (``prompt`` needs none, the others one each).
PROVENANCE_FIELDS = ("prompt", *SCENARIO_KEYS, *OPTIONAL_KEYS)


def check_provenance(path: Path, table: dict[str, Any], given: dict[str, list[str]]) -> dict[str, dict[str, Any]]:
    """Every setting of the priors table (``tail_s``, ``base_speed_m_s`` and each scenario's keys in ``given``)
    with its provenance entry: ``{dotted key: entry}``. An entry names a ``source`` of the table's ``sources``,
    says ``assumption: true``, or both; ``perturb: [lo, hi]`` (0 < lo <= 1 <= hi) is the sensitivity run's
    factor range. Keys are ``tail_s``, ``scenarios.NAME.FIELD`` or ``scenarios.*.FIELD`` (an exact key wins)."""
    sources = table.get("sources") or {}
    prov = table.get("provenance")
    if not isinstance(sources, dict):
        raise PriorsError(f"{path}: sources must be a mapping of key -> citation")
    if not isinstance(prov, dict):
        raise PriorsError(
            f"{path}: needs a mapping 'provenance' saying where each setting comes from "
            "(a source of 'sources', or assumption: true)"
        )
    for k, e in prov.items():
        where = f"{path}: provenance.{k}"
        bits = str(k).split(".")
        ok = bits in (["tail_s"], ["base_speed_m_s"]) or (
            len(bits) == 3
            and bits[0] == "scenarios"
            and (bits[1] == "*" or bits[1] in table["scenarios"])
            and bits[2] in PROVENANCE_FIELDS
        )
        if not ok:
            raise PriorsError(
                f"{where}: names no setting (tail_s, base_speed_m_s, scenarios.<name or *>.<field>; "
                f"fields: {list(PROVENANCE_FIELDS)})"
            )
        if not isinstance(e, dict):
            raise PriorsError(f"{where} must be a mapping (source:, assumption:, note:, perturb:)")
        if "source" in e and e["source"] not in sources:
            raise PriorsError(f"{where}.source={e['source']!r} is not a key of sources {sorted(sources)}")
        if "assumption" in e and not isinstance(e["assumption"], bool):
            raise PriorsError(f"{where}.assumption={e['assumption']!r} is invalid: true or false")
        if "perturb" in e:
            r = e["perturb"]
            if not (isinstance(r, list) and len(r) == 2 and all(isinstance(x, (int, float)) for x in r)) or not (
                0 < r[0] <= 1 <= r[1]
            ):
                raise PriorsError(f"{where}.perturb={r!r} is invalid: [lo, hi] with 0 < lo <= 1 <= hi")
    out: dict[str, dict[str, Any]] = {}
    wanted = ["tail_s", "base_speed_m_s"] + [f"scenarios.{n}.{f}" for n, fs in given.items() for f in fs]
    for k in wanted:
        wild = f"scenarios.*.{k.split('.')[2]}" if k.startswith("scenarios.") else k
        e = prov.get(k, prov.get(wild))
        if not e or not (e.get("source") or e.get("assumption") is True):
            raise PriorsError(
                f"{path}: {k} has neither a source nor assumption: true (provenance.{k} or provenance.{wild})"
            )
        out[k] = e
    return out


def _draw(rng: np.random.Generator, weights: dict[str, float]) -> str:
    names = list(weights)
    w = np.array([float(weights[n]) for n in names])
    return names[int(rng.choice(len(names), p=w / w.sum()))]


def resolve_part(part: str, side: float, rng: np.random.Generator) -> str:
    """``shoulder_near`` -> shoulder_l / shoulder_r by the participant's side (``side`` > 0: robot's left)."""
    for suffix, near in (("_near", True), ("_far", False)):
        if part.endswith(suffix):
            left = side > 0 if abs(side) > 1e-9 else bool(rng.random() < 0.5)
            return f"{part[: -len(suffix)]}_{'l' if left == near else 'r'}"
    return part


def mirror_part(part: str) -> str:
    if part.endswith("_l"):
        return part[:-2] + "_r"
    if part.endswith("_r"):
        return part[:-2] + "_l"
    return part


#: A touch point must have this much free space (m) along its normal, out to RAY_M, from every other link.
CLEARANCE_M = 0.035
RAY_M = (0.02, 0.05, 0.08, 0.12, 0.16)


def tree_of(robot: WholeBodyRobot) -> JointTree:
    """``robot``'s kinematic tree; a robot without one cannot hold a session."""
    if robot.tree is None:
        raise ValueError(f"robot {robot.name!r} has no kinematic tree (a scenario study needs robot=reachy_full)")
    return robot.tree


def part_link(
    robot: WholeBodyRobot, part: str, poses: np.ndarray | None = None, towards: np.ndarray | None = None
) -> Link:
    """The touchable faces of ``part`` as an open :class:`Link` in its link's frame.

    With the robot's link ``poses`` (L, 4, 4): only faces with free space along
    their normal (no other link within :data:`CLEARANCE_M` out to 16 cm: the
    hand fits there, e.g. not the inner side of an arm against the torso) and,
    with ``towards`` (3,) the participant's direction, faces not turned away
    from the participant (horizontal normal component towards them > -0.1),
    unless that leaves nothing.
    """
    spec = next(p for p in robot.parts if p.name == part)
    link = robot.links[spec.link]
    tri = link.vertices[link.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-300)
    centres = tri.mean(axis=1)
    keep = spec.contains(centres, normals)
    if not keep.any():
        raise ValueError(f"body part {part!r} selects no face of link {spec.link!r}")
    if poses is not None:
        from scipy.spatial import cKDTree

        names = list(tree_of(robot).links)
        m = poses[names.index(spec.link)]
        c_w = centres @ m[:3, :3].T + m[:3, 3]
        n_w = normals @ m[:3, :3].T
        others = []
        for i, name in enumerate(names):
            if name == spec.link:
                continue
            o = robot.links[name]
            others.append(o.vertices @ poses[i, :3, :3].T + poses[i, :3, 3])
            ot = o.vertices[o.faces].mean(axis=1)
            others.append(ot @ poses[i, :3, :3].T + poses[i, :3, 3])
        tree = cKDTree(np.concatenate(others))
        free = np.ones(len(c_w), dtype=bool)
        for t in RAY_M:
            d, _ = tree.query(c_w + t * n_w)
            free &= d > CLEARANCE_M
        if (keep & free).any():
            keep &= free
        if towards is not None:
            facing = n_w[:, :2] @ np.asarray(towards, dtype=np.float64)[:2] > -0.1
            if (keep & facing).any():
                keep &= facing
    return Link(name=part, vertices=link.vertices, faces=link.faces[keep], watertight=False)


def transform_poses(poses: np.ndarray, m: np.ndarray) -> np.ndarray:
    """(T, C, 7) poses in a link frame -> world by the (4, 4) link pose ``m``."""
    out = np.empty_like(poses, dtype=np.float64)
    out[..., :3] = poses[..., :3] @ m[:3, :3].T + m[:3, 3]
    out[..., 3:] = matrix_to_quat(m[:3, :3] @ quat_to_matrix(poses[..., 3:]))
    return out


def pose7(m: np.ndarray) -> np.ndarray:
    """(..., 4, 4) transforms -> (..., 7) position + quaternion xyzw."""
    return np.concatenate([m[..., :3, 3], matrix_to_quat(m[..., :3, :3])], axis=-1)


#: Rounds of :func:`settle_hands` (each moves every offending hand once, by its deepest excess).
SETTLE_ROUNDS = 24
#: Smallest cosine between a surface normal and the approach that :func:`settle_hands` divides an excess by.
SETTLE_MIN_COS = 0.25
#: Clearance (m) a hand moved off a link it must not touch keeps from it.
SETTLE_CLEARANCE_M = 1e-3


def one_session(hand_poses: np.ndarray, link_poses7: np.ndarray, hand: HandModel, links, name: str) -> SessionDataset:
    """One session of poses as a :class:`SessionDataset` (participant P01, 30 Hz): hand poses (F, 2, C, 7) and link
    poses (F, L, 7), world frame, ``links`` the link names; what the contact query of a few frames reads."""
    return SessionDataset(
        name=name,
        synthetic=True,
        hand=hand,
        sessions=make_sessions_frame(
            [
                dict(
                    participant="P01",
                    scenario="-",
                    repetition=1,
                    order=0,
                    start_position="-",
                    start=0,
                    n_frames=len(hand_poses),
                )
            ]
        ),
        hand_poses=np.asarray(hand_poses, dtype=np.float32),
        links=tuple(links),
        link_poses=np.asarray(link_poses7, dtype=np.float32),
        frame_rate_hz=30.0,
    )


def settle_hands(
    hand_poses: np.ndarray,
    link_poses: np.ndarray,
    robot: WholeBodyRobot,
    hand: HandModel,
    own_link: tuple[int, int],
    compliance_m: float,
    away: np.ndarray,
    phase: np.ndarray | None = None,
) -> tuple[np.ndarray, int]:
    """Hands that stop at the skin: ``hand_poses`` (F, 2, C, 7) world, ``link_poses`` (F, L, 4, 4) world.

    Per frame and hand, the contact rows with every link (:func:`sphri.sessions.contact.body_contacts`, exact
    capsule vs mesh) give a depth (m) and the surface's outward normal; the allowed depth is ``compliance_m`` on
    the hand's own link (``own_link[h]``, index into ``tree_of(robot).links``; -1: none) and none elsewhere;
    with ``phase`` (F, 2) bool (the frames of each hand's planned contact phase) only inside that phase: before
    and after it the hand keeps clear of its own link too (a hand on its way to a touch does not touch yet,
    whichever capsule comes first; the gesture generator plans the phase by its effector point, and a finger-pad
    rub's other finger capsules reach the surface about 7 frames before and after it,
    ``outputs/bench/rub_overrun.json``). The
    whole hand is moved back along its approach (``away[h]``, unit vector towards the participant) until its
    row with the largest excess would leave the surface along that row's outward normal (excess over the
    cosine between normal and approach, at least :data:`SETTLE_MIN_COS`; :data:`SETTLE_CLEARANCE_M` off
    other links); :data:`SETTLE_ROUNDS` times at most. Returns the poses and the number
    of (frame, hand) pairs moved."""
    from sphri.contact.exact import ExactContact
    from sphri.sessions.contact import body_contacts

    out = np.array(hand_poses, dtype=np.float64)
    n = len(out)
    links = tuple(tree_of(robot).links)
    rot = link_poses[..., :3, :3]
    lk7 = pose7(link_poses)
    contact = ExactContact()
    own = np.asarray(own_link)
    moved = np.zeros((n, 2), dtype=bool)
    for _ in range(SETTLE_ROUNDS):
        bc = body_contacts(one_session(out, lk7, hand, links, "settle"), robot, contact)
        if bc.n_contacts == 0:
            break
        mine = bc.link == own[bc.hand]
        if phase is not None:
            mine &= phase[bc.frame, bc.hand]
        excess = bc.depth_m - np.where(mine, compliance_m, -SETTLE_CLEARANCE_M)
        bad = excess > 0
        if not bad.any():
            break
        f, h, e = bc.frame[bad], bc.hand[bad].astype(np.int64), excess[bad]
        nrm = np.einsum("kij,kj->ki", rot[f, bc.link[bad]], bc.normal[bad])
        e = e / np.maximum(np.abs((nrm * away[h]).sum(axis=1)), SETTLE_MIN_COS)
        unit = f * 2 + h
        order = np.lexsort((-e, unit))
        first = order[np.r_[True, unit[order][1:] != unit[order][:-1]]]
        out[f[first], h[first], :, :3] += ((e[first] + 1e-4)[:, None] * away[h[first]])[:, None, :]
        moved[f[first], h[first]] = True
    return out, int(moved.sum())


#: Depth (m) into its own link a hand pulled back onto the surface during a contact phase presses (within the
#: compliance; :func:`hold_contact`).
HOLD_DEPTH_M = 2e-3
#: Largest gap (m) :func:`hold_contact` closes: a hand farther off its link in a contact phase is left where it is.
HOLD_MAX_GAP_M = 0.15
#: Rounds of :func:`hold_contact` (each pulls every hand still off its link once, by its smallest gap).
HOLD_ROUNDS = 6


def own_link_gap(
    hand_poses: np.ndarray, link_poses: np.ndarray, robot: WholeBodyRobot, hand: HandModel, link: int, margin_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """(gap m (F,), outward normal (F, 3) world) of hand poses (F, C, 7) world to link ``link`` (index into
    ``tree_of(robot).links``) at its poses ``link_poses`` (F, 4, 4): the least over the capsules of (distance of the
    capsule's segment to the link's surface - its radius), negative when pressing in (exact capsule-vs-mesh
    query, :func:`sphri.contact.query.capsule_mesh_query`), with that capsule's normal; ``inf`` beyond
    ``margin_m``."""
    from sphri.contact.query import capsule_mesh_query
    from sphri.hand.kinematics import capsule_segments

    n, c = hand_poses.shape[:2]
    if n == 0:
        return np.zeros(0), np.zeros((0, 3))
    lk = robot.links[tuple(tree_of(robot).links)[link]]
    p0, p1 = capsule_segments(hand_poses, hand)  # (F, C, 3) world
    rot, tr = link_poses[:, None, :3, :3], link_poses[:, None, :3, 3]
    a = np.einsum("fcji,fcj->fci", rot, p0 - tr).reshape(-1, 3)  # R^T (p - t): the link's frame
    b = np.einsum("fcji,fcj->fci", rot, p1 - tr).reshape(-1, 3)
    radius = np.tile(np.asarray(hand.radius_m, dtype=np.float64), n)
    q = capsule_mesh_query(lk.vertices, lk.faces, a, b, radius, margin=margin_m)
    gap = -np.asarray(q.depth, dtype=np.float64).reshape(n, c)
    gap[~np.isfinite(gap) | (np.asarray(q.triangle).reshape(n, c) < 0)] = np.inf
    best = gap.argmin(axis=1)
    rows = np.arange(n)
    nrm = np.asarray(q.normal).reshape(n, c, 3)[rows, best]
    return gap[rows, best], np.einsum("fij,fj->fi", link_poses[:, :3, :3], nrm)


def hold_contact(
    hand_poses: np.ndarray,
    link_poses: np.ndarray,
    robot: WholeBodyRobot,
    hand: HandModel,
    own_link: tuple[int, int],
    phase: np.ndarray,
    away: np.ndarray,
    compliance_m: float,
) -> tuple[np.ndarray, int]:
    """Held contact follows the surface: ``hand_poses`` (F, 2, C, 7) world, ``link_poses`` (F, L, 4, 4) world.

    In the frames of a hand's contact phase (``phase`` (F, 2) bool: the gesture trial's touches) where the hand
    does not touch its own link (``own_link[h]``; -1: none) but comes within :data:`HOLD_MAX_GAP_M` of it, the
    whole hand is moved towards the robot along its approach (``-away[h]``, the reverse of :func:`settle_hands`)
    until its nearest capsule presses :data:`HOLD_DEPTH_M` in (gap over the cosine between that capsule's normal and
    the approach, at least :data:`SETTLE_MIN_COS`); :data:`HOLD_ROUNDS` times at most. A frame whose deepest capsule would then
    press more than ``compliance_m`` into the link keeps its pose before the pull. Only positions change (no time
    stretch: the gesture keeps its timing). Other links are not checked: run :func:`settle_hands` after it.
    Returns the poses and the number of (frame, hand) pairs moved.

    Why along the approach and not along the surface normal at the closest point: the pull and
    :func:`settle_hands`' push then act on one line per hand, so neither drifts the hand sideways over the
    surface (where on the part the gesture touches, and its slide, stay the generator's), and settling again
    takes back exactly a pull that ran the hand into another link."""
    out = np.array(hand_poses, dtype=np.float64)
    moved = np.zeros(phase.shape, dtype=bool)
    for h in (0, 1):
        if own_link[h] < 0:
            continue
        frames = np.flatnonzero(phase[:, h])
        before = out[:, h, :, :3].copy()
        pulled = np.zeros(len(out), dtype=bool)
        for r in range(HOLD_ROUNDS + 1):
            if frames.size == 0:
                break
            gap, nrm = own_link_gap(
                out[frames, h], link_poses[frames, own_link[h]], robot, hand, own_link[h], HOLD_MAX_GAP_M
            )
            back = frames[(gap < -compliance_m) | (gap > HOLD_MAX_GAP_M)]
            out[back, h, :, :3] = before[back]  # pulled too deep (or not reached): back to where it was
            pulled[back] = False
            off = (gap > 0) & (gap <= HOLD_MAX_GAP_M)
            frames, gap, nrm = frames[off], gap[off], nrm[off]
            if frames.size == 0 or r == HOLD_ROUNDS:
                break
            step = (gap + HOLD_DEPTH_M) / np.maximum(np.abs(nrm @ away[h]), SETTLE_MIN_COS)
            out[frames, h, :, :3] -= (step[:, None] * away[h][None, :])[:, None, :]
            pulled[frames] = True
        out[frames, h, :, :3] = before[frames]  # still off its link after the last round: as it was
        pulled[frames] = False
        moved[:, h] = pulled
    return out, int(moved.sum())


class SyntheticSessions:
    """``data=synthetic_sessions`` (see module). ``load(hand, robot)`` -> :class:`SessionDataset`."""

    VERSION = "6"

    def __init__(
        self,
        seed: int = 0,
        participants: int | None = 12,
        repetitions: int | None = 3,
        scenarios: Sequence[str] | None = None,
        priors: str | None = None,
        frame_rate_hz: float = 30.0,
        variability: float = 1.0,
        compliance_mm: float = 5.0,
        **_: Any,
    ):
        self.seed = int(seed)
        self.participants = 12 if participants is None else int(participants)
        self.repetitions = 3 if repetitions is None else int(repetitions)
        self.scenarios = None if scenarios is None else [str(s) for s in scenarios]
        self.priors = str(priors) if priors else str(DEFAULT_PRIORS)
        self.frame_rate_hz = float(frame_rate_hz)
        self.variability = float(variability)
        self.spread = Spread(variability=self.variability)
        self.compliance_mm = float(compliance_mm)

    def load(self, hand: HandModel, robot: Robot) -> SessionDataset:
        if not isinstance(robot, WholeBodyRobot) or robot.tree is None:
            raise ValueError(
                f"data=synthetic_sessions needs a whole robot with a kinematic tree (robot=reachy_full); "
                f"robot {robot.name!r} has none"
            )
        table = load_priors(self.priors, [p.name for p in robot.parts], list(robot.tree.joint_names))
        names = list(table["scenarios"])
        if self.scenarios is not None:
            bad = [s for s in self.scenarios if s not in names]
            if bad:
                raise ValueError(f"data.scenarios: unknown {bad}; the priors table has {names}")
            names = [s for s in names if s in self.scenarios]
        rig = HandRig.from_hand(hand)
        surfaces: dict[str, LinkSurface] = {}
        records, truth, hands, lposes = [], [], [], []
        start = 0
        n_s = len(names)
        for k in range(1, self.participants + 1):
            style = Style.draw(np.random.default_rng([self.seed, k, 0]), self.spread)
            pid = participant_id(k)
            for rep in range(1, self.repetitions + 1):
                for pos in range(n_s):
                    si = (k - 1 + pos) % n_s  # cyclic Latin square over participants
                    scen = names[si]
                    rng = np.random.default_rng([self.seed, k, si + 1, rep])
                    h, lk, info = self._session(rng, style, rig, robot, surfaces, table, scen, k)
                    records.append(
                        dict(
                            participant=pid,
                            scenario=scen,
                            repetition=rep,
                            order=(rep - 1) * n_s + pos,
                            start_position=info.pop("start_position"),
                            start=start,
                            n_frames=len(h),
                        )
                    )
                    truth.append(dict(participant=pid, scenario=scen, repetition=rep, **info))
                    hands.append(h)
                    lposes.append(lk)
                    start += len(h)
        return SessionDataset(
            name="synthetic_sessions",
            synthetic=True,
            hand=hand,
            sessions=make_sessions_frame(records),
            hand_poses=np.concatenate(hands).astype(np.float32),
            links=tuple(tree_of(robot).links),
            link_poses=np.concatenate(lposes).astype(np.float32),
            frame_rate_hz=self.frame_rate_hz,
            robot=robot.name,
            truth=pd.DataFrame(truth),
        )

    def trial_generator(self, part: str, gesture: str) -> SyntheticData:
        """The gesture generator of one touch: one participant, one trial of ``gesture`` on ``part``, this
        generator's seed, frame rate and variability."""
        return SyntheticData(
            seed=self.seed,
            participants=1,
            repetitions=1,
            regions=[part],
            gestures=[gesture],
            frame_rate_hz=self.frame_rate_hz,
            variability=self.variability,
        )

    # ------------------------------------------------------------------ internals
    def _touch(
        self,
        rng,
        style,
        rig,
        robot,
        surfaces,
        part: str,
        gesture: str,
        poses: np.ndarray,
        position: str,
        towards: np.ndarray,
        static: bool,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One gesture-generator trial on ``part``: poses (T, C, 7) in the part's link frame and (T,) bool, the
        frames of its contact phase."""
        key = (part, position)
        surf = surfaces.get(key) if static else None
        if surf is None:
            surf = LinkSurface(part_link(robot, part, poses, towards), n_samples=6000)
            if static:
                surfaces[key] = surf
        gen = self.trial_generator(part, gesture)
        _, out, _, phase = gen._participant_region_phases(rng, style, rig, surf, part)
        return out.astype(np.float64), phase

    def _session(self, rng, style, rig, robot, surfaces, table, scen: str, k: int):
        """Participant ``k``'s session of scenario ``scen``: (hand poses (T, 2, C, 7), link poses (T, L, 7), both
        world frame, float32; the generator's draws). Draws from ``rng`` in a fixed order: the session's choices
        (:func:`_draw_session`), the robot's arm motion, then each touch."""
        s = table["scenarios"][scen]
        fps = self.frame_rate_hz
        dr = _draw_session(rng, s, k)
        n_app = max(int(round(dr.approach_s * fps)), 2)
        t = np.arange(n_app) / fps  # s, the approach
        poses_app = _robot_motion(rng, robot, s, float(table["base_speed_m_s"]), dr, t)
        final = poses_app[-1]  # the robot stops when the touch begins
        parts = [dr.part] + ([mirror_part(dr.part)] if dr.two_hands else [])
        touches, phases, lengths = self._touches(rng, style, rig, robot, surfaces, s, dr, parts, final)
        n_touch = len(touches[0])
        n_tail = int(round(float(table["tail_s"]) * fps))
        idle = _idle_hands(dr.direction, float(s["start_distance_m"]))
        out = _hand_paths(rig.hand.n_capsules, touches, idle, t, n_tail)
        lk = np.concatenate([poses_app, np.repeat(final[None], n_touch + n_tail, axis=0)])
        # hands stop at the skin: up to compliance_mm into the link each touches, backing off towards the participant
        li = {n: i for i, n in enumerate(tree_of(robot).links)}
        own = [li[next(x for x in robot.parts if x.name == p).link] for p in parts]
        own_link = (own[1] if dr.two_hands else -1, own[0])
        away = np.stack([idle[h] - out[n_app, h, :, :3].mean(axis=0) for h in (0, 1)])
        norm = np.linalg.norm(away, axis=1, keepdims=True)
        away = np.where(norm > 1e-9, away / np.maximum(norm, 1e-9), dr.direction[None, :])
        phase = np.zeros(out.shape[:2], dtype=bool)
        phase[n_app : n_app + n_touch, 1] = phases[0]
        if dr.two_hands:
            phase[n_app : n_app + n_touch, 0] = phases[1]
        comp = self.compliance_mm * 1e-3
        out, moved = settle_hands(out, lk, robot, rig.hand, own_link, comp, away, phase=phase)
        # held contact follows the surface: in its contact phase a hand that settling moved off its own link is
        # pulled back onto it (within the compliance); settling again clears other links it then touches
        out, held = hold_contact(out, lk, robot, rig.hand, own_link, phase, away, comp)
        if held:
            out, _ = settle_hands(out, lk, robot, rig.hand, own_link, comp, away, phase=phase)
        info = dict(
            start_position=dr.position,
            gesture=dr.gesture,
            part=dr.part,
            two_hands=dr.two_hands,
            second_part=parts[1] if dr.two_hands else "",
            approach_s=dr.approach_s,
            duration_scale=dr.scale,
            touch_start_frame=n_app,
            touch_frames=n_touch,
            **_plan_of(phases[0], lengths[0]),
            settled_frames=moved,
            held_frames=held,
        )
        return out.astype(np.float32), pose7(lk).astype(np.float32), info

    def _touches(self, rng, style, rig, robot, surfaces, s, dr: _SessionDraw, parts: list[str], final: np.ndarray):
        """Per touched part (the drawn one, then its mirror when two-handed): the gesture trial (T, C, 7) time-scaled
        by the session's ``duration_scale``, placed in the world by the link poses ``final`` (L, 4, 4); padded
        to one length by holding the last frame; per part (T,) bool, the frames of the trial's contact phase
        (none in the padding); and per part the trial's own length (frames, before the padding)."""
        li = {n: i for i, n in enumerate(tree_of(robot).links)}
        touches, phases = [], []
        for p in parts:
            spec = next(x for x in robot.parts if x.name == p)
            local, phase = self._touch(
                rng,
                style,
                rig,
                robot,
                surfaces,
                p,
                dr.gesture,
                final,
                dr.position,
                dr.direction,
                static=s["robot_motion"] == "none",
            )
            scale = dr.scale
            idx = np.round(np.arange(int(round(len(local) * scale))) / scale).astype(int).clip(0, len(local) - 1)
            touches.append(transform_poses(local[idx], final[li[spec.link]]))
            phases.append(phase[idx])
        n_touch = max(len(x) for x in touches)
        padded = [np.concatenate([x, np.repeat(x[-1:], n_touch - len(x), axis=0)]) for x in touches]
        phases = [np.r_[x, np.zeros(n_touch - len(x), dtype=bool)] for x in phases]
        return padded, phases, [len(x) for x in touches]


def _plan_of(phase: np.ndarray, n_trial: int) -> dict[str, int]:
    """The truth table's record of the drawing hand's trial: its own length (frames) and the first and last frame
    of its planned contact phase ``phase`` (T,) bool within the touch (-1 when the plan has none)."""
    on = np.flatnonzero(phase)
    first, last = (int(on[0]), int(on[-1])) if on.size else (-1, -1)
    return dict(trial_frames=int(n_trial), plan_first_frame=first, plan_last_frame=last)


@dataclass
class _SessionDraw:
    """What a session's random stream chose first (:func:`_draw_session`)."""

    position: str
    """Starting position (a key of :data:`DIRECTIONS`)."""
    direction: np.ndarray
    """(3,) unit vector from the robot's base to the starting position, world frame."""
    side: float
    """The direction's y (rounded): > 0 the robot's left, < 0 its right."""
    gesture: str
    part: str
    two_hands: bool
    approach_s: float
    """Approach duration (s)."""
    scale: float
    """Time scale of the touch (``duration_scale``)."""


def _draw_session(rng: np.random.Generator, s: dict, k: int) -> _SessionDraw:
    """Participant ``k``'s starting position (fixed per participant) and the session's draws from ``rng``, in
    this order: gesture, body part (its side), one or two hands, approach duration, time scale; ``s`` is the
    scenario's row of the priors table."""
    position = s["start_positions"][(k - 1) % len(s["start_positions"])]
    ang = np.radians(DIRECTIONS[position])
    d = np.array([np.cos(ang), np.sin(ang), 0.0])
    side = float(np.round(d[1], 6))
    gesture = _draw(rng, s["gestures"])
    part = resolve_part(_draw(rng, s["parts"]), side, rng)
    two = bool(rng.random() < float(s["two_hands"]))
    approach = float(rng.uniform(*s["approach_s"]))
    scale = float(rng.uniform(*s["duration_scale"]))
    return _SessionDraw(position, d, side, gesture, part, two, approach, scale)


def _robot_motion(
    rng: np.random.Generator, robot: WholeBodyRobot, s: dict, base_speed_m_s: float, dr: _SessionDraw, t: np.ndarray
) -> np.ndarray:
    """(n_app, L, 4, 4) link poses during the approach at times ``t`` (s): the scenario's scripted motion (``base``:
    drives towards the participant at ``base_speed_m_s``; ``arm``: the nearer arm, drawn from ``rng`` when the
    participant stands straight ahead, follows a sorting trajectory with a drawn phase; ``none``: still)."""
    n_app = t.size
    base = np.zeros((n_app, 3))
    joints: dict[str, np.ndarray] = {}
    if s["robot_motion"] == "base":
        base[:, :2] = (base_speed_m_s * t)[:, None] * dr.direction[None, :2]
    elif s["robot_motion"] == "arm":
        arm = "l" if dr.side > 0 or (dr.side == 0 and rng.random() < 0.5) else "r"
        phase = rng.uniform(0, 2 * np.pi)
        joints[f"{arm}_shoulder_pitch"] = -0.5 - 0.35 * np.sin(2 * np.pi * t / 3.0 + phase)
        joints[f"{arm}_elbow_pitch"] = -0.9 + 0.3 * np.sin(2 * np.pi * t / 3.0 + phase)
    return robot.link_poses(base, joints)


def _idle_hands(d: np.ndarray, dist: float) -> dict[int, np.ndarray]:
    """Where each hand (0 left, 1 right) hangs at the participant's side (world, m): the participant stands
    ``dist`` m from the robot's base along ``d``."""
    body = d * dist
    lateral = np.array([-d[1], d[0], 0.0])  # the participant's right is -lateral seen facing the robot
    return {0: body - 0.22 * lateral + [0, 0, 0.85], 1: body + 0.22 * lateral + [0, 0, 0.85]}


def _hand_paths(
    n_capsules: int, touches: list[np.ndarray], idle: dict[int, np.ndarray], t: np.ndarray, n_tail: int
) -> np.ndarray:
    """(T, 2, C, 7) both hands over the session (world): hand 1 (right) moves from its ``idle`` point to the first
    touch during the approach (times ``t``, s; minimum-jerk), touches, then holds its last pose for ``n_tail``
    frames; hand 0 (left) does the same with the second touch, or hangs idle in a one-handed session."""
    n_app = t.size
    two = len(touches) > 1
    n_touch = len(touches[0])
    out = np.empty((n_app + n_touch + n_tail, 2, n_capsules, 7))
    for h in (0, 1):
        tr = touches[0] if h == 1 else (touches[1] if two else None)
        shape = tr[0] if tr is not None else touches[0][0]
        centre = shape[:, :3].mean(axis=0)
        if tr is None:
            out[:, h] = shape
            out[:, h, :, :3] += idle[h] - centre
            continue
        w = np.clip(t / t[-1], 0, 1) if n_app > 1 else np.ones(1)
        w = w**3 * (10 - 15 * w + 6 * w**2)
        app = np.repeat(shape[None], n_app, axis=0)
        app[..., :3] += ((1 - w)[:, None] * (idle[h] - centre)[None, :])[:, None, :]
        out[:n_app, h] = app
        out[n_app : n_app + n_touch, h] = tr
        out[n_app + n_touch :, h] = tr[-1]
    return out
