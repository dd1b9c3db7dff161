"""Synthetic :class:`~sphri.types.Contacts` with realistic statistics (tests, bench).

Per contact frame a hand centre is drawn on the surface and 3-8 capsules
touch within a few centimetres of it (finger-sized radii, penetration up to a
centimetre), as in the VR study where the hand could sink into the hull.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sphri.geometry.link import face_normals, sample_surface
from sphri.types import Contacts, Link


def make_contacts(
    frame: np.ndarray,
    point_m: np.ndarray,
    normal: np.ndarray,
    patch_radius_m: np.ndarray,
    n_frames: int,
    capsule: np.ndarray | None = None,
    capsule_radius_m: np.ndarray | float = 0.008,
    triangle: np.ndarray | None = None,
) -> Contacts:
    """Contacts from hand-made rows (sorted by frame then capsule here).

    The capsule sphere is placed along the normal so that its circle on the
    plane has ``patch_radius_m`` (centre outside the solid).
    """
    frame = np.asarray(frame, dtype=np.int64)
    k = frame.size
    point_m = np.asarray(point_m, dtype=np.float64).reshape(k, 3)
    normal = np.asarray(normal, dtype=np.float64).reshape(k, 3)
    normal = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    patch = np.asarray(patch_radius_m, dtype=np.float64).reshape(k)
    rc = np.broadcast_to(np.asarray(capsule_radius_m, dtype=np.float64), (k,)).copy()
    rc = np.maximum(rc, patch)
    height = np.sqrt(np.maximum(rc**2 - patch**2, 0.0))  # centre above the plane
    cap = np.arange(k) % 19 if capsule is None else np.asarray(capsule)
    order = np.lexsort((cap, frame))
    tri = np.zeros(k, dtype=np.int64) if triangle is None else np.asarray(triangle, dtype=np.int64)
    seg = point_m + normal * height[:, None]
    return Contacts(
        n_frames=int(n_frames),
        frame=frame[order],
        capsule=cap[order].astype(np.int16),
        distance_m=height[order],
        inside=np.zeros(k, dtype=bool),
        point_m=point_m[order],
        segment_point_m=seg[order],
        triangle=tri[order],
        barycentric=np.full((k, 3), 1.0 / 3.0),
        normal=normal[order],
        patch_radius_m=patch[order],
        depth_m=(rc - height)[order],
    )


def synthetic_contacts(
    link: Link,
    n_frames: int,
    contact_fraction: float = 0.6,
    per_frame: tuple[int, int] = (3, 8),
    spread_m: float = 0.03,
    seed: int = 0,
) -> Contacts:
    """Random hand contacts on ``link`` for ``n_frames`` frames (see module docstring)."""
    rng = np.random.default_rng(seed)
    active = np.flatnonzero(rng.random(n_frames) < contact_fraction)
    counts = rng.integers(per_frame[0], per_frame[1] + 1, size=active.size)
    k = int(counts.sum())
    frame = np.repeat(active, counts)
    hand, _ = sample_surface(link, max(active.size, 1), seed + 1)
    centre = np.repeat(hand[: active.size], counts, axis=0)
    # contact points: the surface sample nearest to a jittered hand centre
    pool, pool_tri = sample_surface(link, 200_000, seed + 2)
    _, near = cKDTree(pool).query(centre + rng.normal(scale=spread_m / 2, size=(k, 3)))
    pts, tri = pool[near], pool_tri[near]
    normal = face_normals(link)[tri]
    capsule_r = rng.uniform(0.006, 0.011, k)  # finger phalanx to palm capsule radii (m)
    depth = rng.uniform(0.0005, 0.012, k)  # penetration (m); deeper than 2 r = wholly inside
    height = capsule_r - depth  # signed height of the sphere centre above the plane
    patch = np.where(np.abs(height) < capsule_r, np.sqrt(np.maximum(capsule_r**2 - height**2, 0.0)), capsule_r)
    capsule = np.concatenate([rng.choice(19, size=c, replace=False) for c in counts]) if k else np.zeros(0, int)
    order = np.lexsort((capsule, frame))
    inside = height < 0
    return Contacts(
        n_frames=int(n_frames),
        frame=frame[order].astype(np.int64),
        capsule=capsule[order].astype(np.int16),
        distance_m=np.abs(height)[order],
        inside=inside[order],
        point_m=pts[order],
        segment_point_m=(pts + normal * height[:, None])[order],
        triangle=tri[order],
        barycentric=np.full((k, 3), 1.0 / 3.0),
        normal=normal[order],
        patch_radius_m=patch[order],
        depth_m=depth[order],
    )
