"""Contact of both hands with every link of a moving robot, in one pass.

For each chunk of frames: both hands' capsule segments in the world
(:func:`sphri.hand.kinematics.capsule_segments`); one bounding sphere per
(frame, hand) around its 2C segment ends grown by the largest capsule radius;
per link, the link's bounding sphere (from the prepared mesh, placed by that
frame's link pose) against those hand spheres. Only the (frame, hand, link)
triples that pass are transformed into the link's frame and handed to the
configured contact component's exact query (``contact=exact``: capsule vs
mesh; :meth:`sphri.contact.stage.ContactStage._chunk`). So the cost grows with
the links a hand is actually near, not with the link count;
``cull=False`` tests every triple (for the benchmark).

Rows are in the touched link's frame, so maps on the robot's surface do not
move with the robot.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sphri.contact.mesh import prepare_mesh
from sphri.contact.query import SearchRecord
from sphri.hand.kinematics import capsule_segments, quat_to_matrix
from sphri.sessions.format import SessionDataset
from sphri.types import Robot


@dataclass
class BodyContacts:
    """Sparse contacts of a :class:`SessionDataset` with a whole robot, sorted by frame, hand, link, capsule."""

    n_frames: int
    links: tuple[str, ...]
    frame: np.ndarray
    """(K,) int64 global frame."""
    hand: np.ndarray
    """(K,) int8 hand index (0 left, 1 right)."""
    link: np.ndarray
    """(K,) int16 index into ``links``."""
    capsule: np.ndarray
    """(K,) int16 capsule index."""
    point_m: np.ndarray
    """(K, 3) closest surface point, link frame (m)."""
    normal: np.ndarray
    """(K, 3) outward normal, link frame."""
    patch_radius_m: np.ndarray
    depth_m: np.ndarray
    stats: dict = field(default_factory=dict)
    """Culling counts: triples (frame, hand, link) in total and those passed to the exact query."""

    @property
    def n_contacts(self) -> int:
        return int(self.frame.size)

    def take(self, rows: np.ndarray) -> BodyContacts:
        return BodyContacts(
            self.n_frames, self.links, **{k: getattr(self, k)[rows] for k in ROW_FIELDS}, stats=dict(self.stats)
        )


#: The per-row fields of :class:`BodyContacts`, in order.
ROW_FIELDS = ("frame", "hand", "link", "capsule", "point_m", "normal", "patch_radius_m", "depth_m")
#: The integer types its index fields are stored as.
ROW_TYPES = {"frame": np.int64, "hand": np.int8, "link": np.int16, "capsule": np.int16}


@dataclass
class _Links:
    """The links' prepared meshes and bounding spheres, and the hand's capsule radii grown by the margin."""

    meshes: list
    centres: np.ndarray
    """(L, 3) bounding sphere centres, link frame (m)."""
    radii: np.ndarray
    """(L,) bounding sphere radii (m)."""
    capsule_radius: np.ndarray
    """(C,) capsule radii plus the contact margin (m)."""


@dataclass
class _Pass:
    """What the chunks found so far: contact rows per (chunk, link), the reused search buffer, culling counts."""

    record: SearchRecord
    parts: list[dict] = field(default_factory=list)
    tested: int = 0
    passed: int = 0


def body_contacts(
    ds: SessionDataset, robot: Robot, contact, chunk_frames: int = 4000, cull: bool = True
) -> BodyContacts:
    """Contacts of both hands with every link of ``ds.links`` (see module); ``contact`` is a contact component."""
    missing = [ln for ln in ds.links if ln not in robot.links]
    if missing:
        raise ValueError(f"sessions {ds.name!r} pose links {missing} that robot {robot.name!r} lacks")
    links = _prepare_links(ds, robot, contact)
    acc = _Pass(SearchRecord.empty(0))
    for s in range(0, ds.n_frames, chunk_frames):
        _chunk_contacts(ds, links, contact, np.arange(s, min(s + chunk_frames, ds.n_frames)), chunk_frames, cull, acc)
    return _assemble(ds, acc)


def _prepare_links(ds: SessionDataset, robot: Robot, contact) -> _Links:
    """Each link of ``ds.links`` prepared for ``contact``'s exact query, with its bounding sphere."""
    radius = np.asarray(ds.hand.radius_m, dtype=np.float64) + float(getattr(contact, "margin_m", 0.0))
    inside = "none" if getattr(contact, "spheres", 0) else getattr(contact, "inside", "auto")
    meshes = [prepare_mesh(robot.links[ln].vertices, robot.links[ln].faces, inside=inside) for ln in ds.links]
    centres = np.stack([m.shift for m in meshes])  # (L, 3) link frame
    radii = np.array([m.sphere_radius for m in meshes])
    return _Links(meshes, centres, radii, radius)


def _chunk_contacts(
    ds: SessionDataset, links: _Links, contact, fr: np.ndarray, chunk_frames: int, cull: bool, acc: _Pass
) -> None:
    """The contacts of frames ``fr`` with every link, added to ``acc``: per link, the (frame, hand) units whose
    bounding spheres meet the link's (all with ``cull=False``) go to ``contact``'s exact query in the link's
    frame."""
    hand = ds.hand
    c = hand.n_capsules
    reach = float(links.capsule_radius.max())
    n = fr.size
    p0, p1 = capsule_segments(ds.hand_poses[fr].reshape(n * 2, c, 7), hand)  # (n*2, C, 3) world
    ends = np.concatenate([p0, p1], axis=1)
    lo, hi = ends.min(axis=1), ends.max(axis=1)
    hc = 0.5 * (lo + hi)  # (n*2, 3)
    hr = np.sqrt(((ends - hc[:, None]) ** 2).sum(axis=2)).max(axis=1) + reach
    lp = ds.link_poses[fr].astype(np.float64)  # (n, L, 7)
    rot = quat_to_matrix(lp[..., 3:])  # (n, L, 3, 3)
    trans = lp[..., :3]
    cw = np.einsum("nlij,lj->nli", rot, links.centres) + trans  # link spheres' centres, world
    for li in range(len(ds.links)):
        acc.tested += 2 * n
        if cull:
            d = np.linalg.norm(hc.reshape(n, 2, 3) - cw[:, li, None, :], axis=2)
            units = np.flatnonzero((d <= hr.reshape(n, 2) + links.radii[li]).ravel())  # frame*2 + hand
        else:
            units = np.arange(2 * n)
        if units.size == 0:
            continue
        acc.passed += units.size
        f_local = units // 2
        r_t = rot[f_local, li]  # (m, 3, 3) link -> world
        t_t = trans[f_local, li]
        a = np.einsum("mji,mcj->mci", r_t, p0[units] - t_t[:, None, :])  # R^T (p - t)
        b = np.einsum("mji,mcj->mci", r_t, p1[units] - t_t[:, None, :])
        need = units.size * c
        if acc.record.d2.size < need:
            acc.record = SearchRecord.empty(max(need, min(2 * chunk_frames, 2 * ds.n_frames) * c))
        for part in contact._chunk(links.meshes[li], a, b, units, links.capsule_radius, acc.record):
            u = part.pop("frame")
            part["frame"] = fr[u // 2]
            part["hand"] = (u % 2).astype(np.int8)
            part["link"] = np.full(u.size, li, dtype=np.int16)
            acc.parts.append(part)


def _assemble(ds: SessionDataset, acc: _Pass) -> BodyContacts:
    """The rows of ``acc`` in one :class:`BodyContacts`, sorted by frame, hand, link, capsule."""
    if acc.parts:
        cat = {k: np.concatenate([p[k] for p in acc.parts]) for k in ROW_FIELDS}
    else:  # no contact: no rows
        cat = {k: np.zeros((0, 3) if k in ("point_m", "normal") else 0) for k in ROW_FIELDS}
    order = np.lexsort((cat["capsule"], cat["link"], cat["hand"], cat["frame"]))
    rows = {k: cat[k][order].astype(ROW_TYPES[k]) if k in ROW_TYPES else cat[k][order] for k in ROW_FIELDS}
    return BodyContacts(ds.n_frames, tuple(ds.links), **rows, stats={"triples": acc.tested, "tested": acc.passed})
