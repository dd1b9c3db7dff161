"""Hand-made studies for the coverage tests: a cylinder link and contacts placed on purpose.

A plain module (not conftest) so tests can import it by a unique name."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import trimesh

from sphri.types import TRIAL_COLUMNS, Contacts, GestureDataset, HandModel, Link

RADIUS = 0.04
HEIGHT = 0.24

#: gesture -> (angle around z in radians, height z in metres, spread m, capsules per frame)
TARGETS = {
    "poke": (0.0, 0.08, 0.004, 1),  # +x side, upper part, small
    "stroke": (np.pi, -0.02, 0.03, 2),  # -x side, middle, long strokes
    "grab": (None, -0.09, 0.01, 4),  # all around the lower part
}


def cylinder_link(radius: float = RADIUS, height: float = HEIGHT, sections: int = 48) -> Link:
    m = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    return Link("cyl", np.asarray(m.vertices, float), np.asarray(m.faces, np.int64), True)


def plate_link(thickness: float = 0.002, size: float = 0.1) -> Link:
    m = trimesh.creation.box(extents=(size, size, thickness))
    m = m.subdivide().subdivide().subdivide()
    return Link("plate", np.asarray(m.vertices, float), np.asarray(m.faces, np.int64), True)


def hand_stub() -> HandModel:
    return HandModel(("palm",), ("palm",), np.array([0.01]), np.array([0.03]), np.array([1]), np.zeros((1, 3)))


def make_contacts(
    link: Link, frame: np.ndarray, points: np.ndarray, radius: float | np.ndarray, n_frames: int
) -> Contacts:
    mesh = trimesh.Trimesh(link.vertices, link.faces, process=False)
    cp, _, tri = trimesh.proximity.closest_point(mesh, points)
    order = np.argsort(frame, kind="stable")
    frame, cp, tri = frame[order], cp[order], tri[order]
    k = frame.size
    normal = np.asarray(mesh.face_normals)[tri]
    r = np.broadcast_to(np.asarray(radius, float), (k,))[order] if np.ndim(radius) else np.full(k, float(radius))
    return Contacts(
        n_frames=n_frames,
        frame=frame.astype(np.int64),
        capsule=np.zeros(k, np.int16),
        distance_m=np.zeros(k),
        inside=np.zeros(k, bool),
        point_m=cp,
        segment_point_m=cp + 0.005 * normal,
        triangle=tri.astype(np.int64),
        barycentric=np.full((k, 3), 1 / 3),
        normal=normal,
        patch_radius_m=r,
        depth_m=np.full(k, 0.002),
    )


@dataclass
class Study:
    link: Link
    dataset: GestureDataset
    contacts: Contacts


def make_study(
    participants: int = 6,
    repetitions: int = 4,
    seed: int = 0,
    targets=None,
    frames_per_trial: int = 24,
    contact_frames: int = 12,
) -> Study:
    """Trials of each target gesture by each participant; contacts on the cylinder."""
    targets = targets or TARGETS
    rng = np.random.default_rng(seed)
    link = cylinder_link()
    rows, fr, pts = [], [], []
    start = 0
    for p in range(participants):
        ordinal = 0
        offset = rng.normal(0, 0.004, 2)  # a participant's own aim (m)
        for _rep in range(repetitions):
            for g, (ang, z, spread, caps) in targets.items():
                ordinal += 1
                rows.append((f"participant_{p:02d}", "arm", ordinal, f"{ordinal:04d}_{g}", g, start, frames_per_trial))
                first = start + int(rng.integers(2, frames_per_trial - contact_frames))
                for f in range(first, first + contact_frames):
                    for _ in range(caps):
                        a = (
                            rng.uniform(0, 2 * np.pi)
                            if ang is None
                            else ang + offset[0] / RADIUS + rng.normal(0, spread / RADIUS)
                        )
                        h = z + offset[1] + rng.normal(0, spread if ang is not None else 0.006)
                        h = float(np.clip(h, -HEIGHT / 2 + 0.005, HEIGHT / 2 - 0.005))
                        fr.append(f)
                        pts.append([RADIUS * np.cos(a), RADIUS * np.sin(a), h])
                start += frames_per_trial
    trials = pd.DataFrame(rows, columns=list(TRIAL_COLUMNS))
    n_frames = start
    ds = GestureDataset("handmade", True, hand_stub(), trials, np.zeros((n_frames, 1, 7), np.float32), 30.0)
    contacts = make_contacts(link, np.asarray(fr, np.int64), np.asarray(pts, float), 0.008, n_frames)
    return Study(link, ds, contacts)
