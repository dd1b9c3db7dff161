"""Shared by the encoders: wrapping values as the output type, contact row selection, checks.

The output type, :class:`~sphri.types.SkinFrames` (Frames plus the taxel geometry), lives with the
other data types (:mod:`sphri.types`).
"""

from __future__ import annotations

import numpy as np

from sphri.types import Contacts, Layout, SkinFrames, SurfaceMap, TaxelGeometry


def make_frames(values: np.ndarray, layout: Layout, surface: SurfaceMap) -> SkinFrames:
    """Wrap encoded ``values (M, N)`` with the layout's grid shape and geometry."""
    return SkinFrames(values=values, grid_shape=layout.grid_shape, geometry=TaxelGeometry.from_layout(layout, surface))


def check_frame_index(contacts: Contacts, frame_index: np.ndarray, who: str) -> np.ndarray:
    """Validate ``frame_index (M,)`` against ``contacts``; returns it as int64."""
    fi = np.asarray(frame_index)
    if fi.ndim != 1:
        raise ValueError(f"{who}: frame_index must be (M,), got shape {fi.shape}")
    if fi.size and not np.issubdtype(fi.dtype, np.integer):
        raise ValueError(f"{who}: frame_index must hold integers, got dtype {fi.dtype}")
    fi = fi.astype(np.int64, copy=False)
    if fi.size and (fi.min() < 0 or fi.max() >= contacts.n_frames):
        raise ValueError(
            f"{who}: frame_index values must lie in [0, {contacts.n_frames}) (contacts.n_frames); "
            f"got [{fi.min()}, {fi.max()}]"
        )
    fr = np.asarray(contacts.frame)
    if fr.size > 1 and np.any(np.diff(fr) < 0):
        raise ValueError(f"{who}: contacts.frame must be sorted (rows sorted by frame, then capsule)")
    return fi


def select_rows(contacts: Contacts, frame_index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contact rows of the requested frames, compacted.

    Returns ``rows (K,)`` int64 indices into the contact arrays (frame m's
    rows are ``rows[start[m]:start[m+1]]``) and ``start (M+1,)`` int64.
    """
    fr = np.asarray(contacts.frame)
    lo = np.searchsorted(fr, frame_index, side="left")
    hi = np.searchsorted(fr, frame_index, side="right")
    counts = hi - lo
    start = np.zeros(len(frame_index) + 1, dtype=np.int64)
    np.cumsum(counts, out=start[1:])
    k = int(start[-1])
    # rows = concat(arange(lo[m], hi[m])) without a Python loop
    rows = np.arange(k, dtype=np.int64) - np.repeat(start[:-1] - lo, counts)
    return rows, start


def tangent_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two (K, 3) unit vectors spanning the plane perpendicular to each (K, 3) normal."""
    n = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    helper = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(n, e1)


def capsule_radius(contacts: Contacts, rows: np.ndarray) -> np.ndarray:
    """(K,) capsule radius (metres) of contact rows, from depth and distance.

    ``depth = radius - distance`` outside the solid, ``radius + distance`` inside.
    """
    depth = np.asarray(contacts.depth_m)[rows]
    dist = np.asarray(contacts.distance_m)[rows]
    inside = np.asarray(contacts.inside)[rows]
    return np.maximum(np.where(inside, depth - dist, depth + dist), 0.0)
