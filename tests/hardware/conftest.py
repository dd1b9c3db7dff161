"""Fixtures of the hardware tests: small geometries, hand models and contacts."""

from __future__ import annotations

import os

import numpy as np
import pytest

from sphri.types import Contacts, HandModel, TaxelGeometry


def grid_geometry(h: int, w: int, length_m: float = 0.24, radius_m: float = 0.04) -> TaxelGeometry:
    """A cylinder-like H x W grid (u along the link, v around it, v wraps)."""
    u = (np.arange(h) + 0.5) / h
    v = (np.arange(w) + 0.5) / w
    uu, vv = np.meshgrid(u, v, indexing="ij")
    ang = 2 * np.pi * vv.ravel()
    pos = np.stack([radius_m * np.cos(ang), radius_m * np.sin(ang), uu.ravel() * length_m], axis=1)
    return TaxelGeometry(
        grid_shape=(h, w),
        uv=np.stack([uu.ravel(), vv.ravel()], axis=1),
        position_m=pos,
        wrap_v=True,
        metres_per_u=length_m,
        metres_per_v=2 * np.pi * radius_m,
    )


@pytest.fixture
def make_geometry():
    return grid_geometry


@pytest.fixture
def hand() -> HandModel:
    """A 19-capsule hand like the Quest's: 4 palm, 3 per finger."""
    fingers = ("palm",) * 4 + ("thumb",) * 3 + ("index",) * 3 + ("middle",) * 3 + ("ring",) * 3 + ("pinky",) * 3
    c = len(fingers)
    return HandModel(
        names=tuple(f"{f}{i}" for i, f in enumerate(fingers)),
        fingers=fingers,
        radius_m=np.full(c, 0.01),
        height_m=np.full(c, 0.04),
        axis=np.zeros(c, dtype=np.int64),
        center_offset_m=np.zeros((c, 3)),
    )


def make_contacts(n_frames: int, rows: list[tuple[int, int, float]]) -> Contacts:
    """Contacts from (frame, capsule, depth_m) rows (sorted here); other fields are filler."""
    rows = sorted(rows)
    k = len(rows)
    fr = np.array([r[0] for r in rows], dtype=np.int64)
    cap = np.array([r[1] for r in rows], dtype=np.int16)
    depth = np.array([r[2] for r in rows], dtype=np.float64)
    z3 = np.zeros((k, 3))
    return Contacts(
        n_frames=n_frames,
        frame=fr,
        capsule=cap,
        distance_m=np.zeros(k),
        inside=np.zeros(k, bool),
        point_m=z3,
        segment_point_m=z3,
        triangle=np.zeros(k, np.int64),
        barycentric=z3,
        normal=z3,
        patch_radius_m=np.full(k, 0.01),
        depth_m=depth,
    )


@pytest.fixture
def contacts_from_rows():
    return make_contacts


def _real_port(device: str, example: str) -> str:
    """The port of a real ``device`` from ``SPHRI_<DEVICE>_PORT``; without one the test is skipped."""
    var = f"SPHRI_{device.upper()}_PORT"
    port = os.environ.get(var)
    if not port:
        pytest.skip(f"no real {device}: set {var}={example} (or a pyserial URL) to run")
    return port


@pytest.fixture
def skin_port() -> str:
    return _real_port("skin", "/dev/ttyACM0")


@pytest.fixture
def glove_port() -> str:
    return _real_port("glove", "/dev/rfcomm0")


def _frames_on_disk(partial) -> int:
    """Complete frames a recorder's ``.partial`` file holds so far (0 while its header is being written)."""
    from sphri.hardware.recording import PARTIAL_MAGIC, RecordingError, load_recording

    if not partial.exists() or partial.stat().st_size <= len(PARTIAL_MAGIC) + 4:
        return 0
    try:
        return load_recording(partial).n_frames
    except RecordingError:  # header still being written
        return 0


@pytest.fixture
def frames_on_disk():
    return _frames_on_disk
