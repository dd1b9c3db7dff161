"""The contact stage's driver: dataset + robot -> sparse :class:`~sphri.types.Contacts`.

:class:`ContactStage` is the shared body of ``contact=exact`` and
``contact=spheres``. For each skin region present in ``dataset.trials`` it
takes ``robot.link_for(region)`` (links no trial uses are never touched),
checks that the prepared mesh and one chunk's queries fit the memory limit
(:func:`check_contact_memory`, estimated from the link's faces and the chunk
before anything is built), prepares the link's acceleration data once (:func:`sphri.contact.prepare_mesh`,
cached by the mesh's bytes), then walks that region's frames in chunks of
``chunk_frames``:

1. capsule segments from the poses (:func:`sphri.hand.kinematics.capsule_segments`);
2. one bounding-sphere test per frame: the sphere around all of the frame's
   capsules (grown by the largest radius) against the link's bounding
   sphere; frames that miss are dropped whole;
3. the per-capsule query (box, seed triangle, BVH, hull; see
   :mod:`sphri.contact.query`) on the capsules of the remaining frames;
4. the contact rows are kept, the rest dropped.

Rows are sorted by frame, then capsule. The output depends only on the
dataset, the hand, the robot and the component's settings (chunking and
threads change nothing).
"""

from __future__ import annotations

import logging
import sys
import time
from typing import TYPE_CHECKING

import numpy as np

from sphri.contact.mesh import MeshAccel, prepare_mesh
from sphri.types import Contacts, GestureDataset, Robot

if TYPE_CHECKING:  # the numba kernels load where contacts are computed, not when a cached run reads VERSION
    from sphri.contact.query import ContactQuery, SearchRecord

log = logging.getLogger(__name__)

#: Show a progress bar when a region has at least this many frames (and stderr is a terminal).
PROGRESS_MIN_FRAMES = 50_000
#: Say when a link's mesh preparation starts and ends from this many faces (it takes a while).
ANNOUNCE_MIN_FACES = 100_000
#: Peak bytes per mesh face of preparing a link for the queries (:func:`sphri.contact.prepare_mesh`,
#: ``inside=auto``): 76.6 MB on a 20480-face icosphere (tracemalloc; one size measured).
BYTES_PER_FACE = 3750
#: Bytes per capsule query of a chunk: the search record (73) and the capsule's segment ends (48).
BYTES_PER_QUERY = 121


class ContactMemoryError(ValueError):
    """The contact queries of a link would not fit in memory; the message gives the estimate and the settings."""


def check_contact_memory(link: str, n_faces: int, n_frames: int, chunk_frames: int, n_capsules: int) -> None:
    """Refuse a link whose prepared mesh and query chunk would pass the memory limit (:mod:`sphri.limits`),
    before anything is built: the estimate is ``faces x BYTES_PER_FACE + chunk rows x BYTES_PER_QUERY``."""
    from sphri.limits import over_limit

    rows = min(n_frames, chunk_frames) * n_capsules
    why = over_limit(
        f"the contact queries on link {link!r} ({n_faces} mesh faces, about {BYTES_PER_FACE} bytes each, and "
        f"chunks of {min(n_frames, chunk_frames)} frames x {n_capsules} capsules)",
        float(n_faces) * BYTES_PER_FACE + float(rows) * BYTES_PER_QUERY,
    )
    if why is not None:
        raise ContactMemoryError(
            f"contact: {why} (what to lower: the link's faces, with a simplified mesh, or contact.chunk_frames)"
        )


def empty_contacts(n_frames: int) -> Contacts:
    """A :class:`Contacts` with no rows."""
    z = np.zeros(0)
    z3 = np.zeros((0, 3))
    return Contacts(
        n_frames=n_frames,
        frame=np.zeros(0, dtype=np.int64),
        capsule=np.zeros(0, dtype=np.int16),
        distance_m=z.copy(),
        inside=np.zeros(0, dtype=bool),
        point_m=z3.copy(),
        segment_point_m=z3.copy(),
        triangle=np.zeros(0, dtype=np.int64),
        barycentric=z3.copy(),
        normal=z3.copy(),
        patch_radius_m=z.copy(),
        depth_m=z.copy(),
    )


def _check_dataset(dataset: GestureDataset) -> None:
    poses = dataset.poses
    c = dataset.hand.n_capsules
    if poses.ndim != 3 or poses.shape[1:] != (c, 7):
        raise ValueError(
            f"dataset {dataset.name!r}: poses must have shape (F, {c}, 7) for a hand of {c} capsules, got {poses.shape}"
        )
    if c > np.iinfo(np.int16).max:
        raise ValueError(f"dataset {dataset.name!r}: {c} capsules do not fit Contacts.capsule (int16)")
    for col in ("region", "start", "n_frames"):
        if col not in dataset.trials.columns:
            raise ValueError(f"dataset {dataset.name!r}: trials lack the column {col!r}")
    start = dataset.trials["start"].to_numpy(dtype=np.int64)
    count = dataset.trials["n_frames"].to_numpy(dtype=np.int64)
    bad = (start < 0) | (count < 0) | (start + count > poses.shape[0])
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"dataset {dataset.name!r}: trial row {i} spans frames {start[i]}..{start[i] + count[i]} "
            f"outside the {poses.shape[0]} pose rows"
        )
    r = np.asarray(dataset.hand.radius_m, dtype=np.float64)
    if not (np.isfinite(r).all() and (r >= 0).all()):
        raise ValueError(f"hand radius_m must be finite and >= 0, got {r}")


def region_frames(dataset: GestureDataset, region: str) -> np.ndarray:
    """(M,) int64 global frames of the trials in ``region``, ascending and unique."""
    t = dataset.trials
    sel = (t["region"].astype(str) == region).to_numpy()
    start = t["start"].to_numpy(dtype=np.int64)[sel]
    count = t["n_frames"].to_numpy(dtype=np.int64)[sel]
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    # concatenated ranges start[i] .. start[i] + count[i] without a Python loop
    offsets = np.cumsum(count) - count
    frames = np.repeat(start - offsets, count) + np.arange(total, dtype=np.int64)
    if frames.size > 1 and not (np.diff(frames) > 0).all():
        frames = np.unique(frames)
    return frames


def frames_near_link(p0: np.ndarray, p1: np.ndarray, reach_m: float, mesh: MeshAccel) -> np.ndarray:
    """(F,) bool: frames whose capsules' bounding sphere can reach the link's.

    ``p0``/``p1`` are (F, C, 3) world segment ends; ``reach_m`` the largest
    capsule radius (margin included). The hand's sphere is centred on the box
    of its 2C segment ends; the link's on its bounding-box centre.
    """
    out = np.empty(p0.shape[0], dtype=np.bool_)
    if p0.shape[0]:
        from sphri.contact import _kernels

        c = mesh.shift
        _kernels.frames_near(
            np.ascontiguousarray(p0, dtype=np.float64),
            np.ascontiguousarray(p1, dtype=np.float64),
            float(reach_m),
            float(c[0]),
            float(c[1]),
            float(c[2]),
            float(mesh.sphere_radius),
            out,
        )
    return out


class ContactStage:
    """Shared driver of the contact components (see the module docstring).

    Subclasses set :attr:`spheres` (0 = exact capsules, k > 0 = k spheres)
    and :attr:`inside`.
    """

    VERSION = "1"
    spheres: int = 0
    inside: str = "auto"
    margin_m: float = 0.0
    chunk_frames: int = 20000

    def _segments(self, dataset: GestureDataset, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        from sphri.hand.kinematics import capsule_segments

        try:
            p0, p1 = capsule_segments(dataset.poses[frames], dataset.hand)
        except ValueError as exc:
            raise ValueError(
                f"contact: dataset {dataset.name!r}, global frames {int(frames[0])}..{int(frames[-1])} "
                f"(indices below count from {int(frames[0])}): {exc}"
            ) from None
        ok = np.isfinite(p0).all(axis=2) & np.isfinite(p1).all(axis=2)
        if not ok.all():
            bad = np.argwhere(~ok)
            shown = ", ".join(f"(frame {int(frames[i])}, capsule {int(c)})" for i, c in bad[:5])
            raise ValueError(
                f"contact: dataset {dataset.name!r} has {len(bad)} capsule poses with NaN/inf positions, "
                f"e.g. {shown}; repair them on load"
            )
        return p0, p1

    def compute(self, dataset: GestureDataset, robot: Robot) -> Contacts:
        """Sparse contacts of every trial against ``robot.link_for(trial.region)``."""
        from sphri.contact.query import SearchRecord

        _check_dataset(dataset)
        n_frames = dataset.n_frames
        c = dataset.hand.n_capsules
        radius = np.asarray(dataset.hand.radius_m, dtype=np.float64) + float(self.margin_m)
        reach = float(radius.max()) if radius.size else 0.0
        parts: list[dict[str, np.ndarray]] = []
        regions = sorted(set(dataset.trials["region"].astype(str)))
        record = SearchRecord.empty(0)
        for region in regions:
            frames = region_frames(dataset, region)
            if frames.size == 0 or c == 0:
                continue
            link = robot.link_for(region)
            n_faces = int(len(link.faces))
            check_contact_memory(link.name, n_faces, int(frames.size), int(self.chunk_frames), c)
            loud = n_faces >= ANNOUNCE_MIN_FACES
            if loud:
                log.info(
                    "contact: preparing link %r (%d faces) for the queries of %d frames",
                    link.name,
                    n_faces,
                    frames.size,
                )
            started = time.perf_counter()
            mesh = prepare_mesh(link.vertices, link.faces, inside="none" if self.spheres else self.inside)
            if loud:
                log.info("contact: link %r prepared in %.1f s", link.name, time.perf_counter() - started)
            bar = _progress(frames.size, f"contact {region} ({link.name})")
            try:
                for s in range(0, frames.size, self.chunk_frames):
                    fr = frames[s : s + self.chunk_frames]
                    p0, p1 = self._segments(dataset, fr)
                    near = frames_near_link(p0, p1, reach, mesh)
                    if near.any():
                        n = int(near.sum()) * c
                        if record.d2.size < n:  # one buffer for all chunks (fresh pages are slow to touch)
                            record = SearchRecord.empty(min(frames.size, self.chunk_frames) * c)
                        parts += self._chunk(mesh, p0[near], p1[near], fr[near], radius, record)
                    if bar is not None:
                        bar.update(fr.size)
            finally:
                if bar is not None:
                    bar.close()
        if not parts:
            return empty_contacts(n_frames)
        cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        order = np.lexsort((cat["capsule"], cat["frame"]))
        return Contacts(n_frames=n_frames, **{k: v[order] for k, v in cat.items()})

    def _chunk(
        self,
        mesh: MeshAccel,
        p0: np.ndarray,
        p1: np.ndarray,
        frames: np.ndarray,
        radius: np.ndarray,
        record: SearchRecord,
    ) -> list[dict[str, np.ndarray]]:
        """Contact rows of the capsules of ``frames`` ((F, C, 3) segment ends)."""
        from sphri.contact.query import finish, search

        c = radius.size
        a = np.ascontiguousarray(p0.reshape(-1, 3))
        b = np.ascontiguousarray(p1.reshape(-1, 3))
        r = np.tile(radius, frames.size)
        rec = search(mesh, a, b, r, 0.0, spheres=self.spheres, record=record)
        rows = np.flatnonzero(rec.in_contact(r))
        if rows.size == 0:
            return []
        q = finish(mesh, a[rows], b[rows], r[rows], rec.take(rows))
        return [_rows(q, rows, frames, c)]


def _rows(q: ContactQuery, rows: np.ndarray, frames: np.ndarray, c: int) -> dict[str, np.ndarray]:
    """Contacts columns of the query rows ``rows`` (``q`` holds exactly those rows)."""
    return {
        "frame": frames[rows // c],
        "capsule": (rows % c).astype(np.int16),
        "distance_m": q.distance,
        "inside": q.inside,
        "point_m": q.point,
        "segment_point_m": q.segment_point,
        "triangle": q.triangle,
        "barycentric": q.barycentric,
        "normal": q.normal,
        "patch_radius_m": q.patch_radius,
        "depth_m": q.depth,
    }


def _progress(total: int, desc: str):
    if total < PROGRESS_MIN_FRAMES or not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="frame", leave=False)
