"""``encoder=proximity``: a taxel is active when a capsule surface is within range.

Works on any layout, including 3-D-only ones. Choice about what is sensed:
``Contacts`` carries, per (frame, capsule) row, only the capsule's closest
segment point and its depth, so each capsule is approximated by the sphere of
its radius at ``segment_point_m`` (radius recovered from ``depth_m`` and
``distance_m``), and only capsules that the contact stage reported are sensed.
The sensing range is therefore bounded by what the contact stage detects: to
sense capsules hovering near the skin, give the contact stage a margin of at
least ``sensing_distance_m`` (any rows it reports, touching or not, are used).

``intensity: binary`` gives uint8 0/1; ``depth`` gives a float32 pressure
proxy ``clip((sensing - d) / (sensing + depth_scale), 0, 1)`` where d is the
signed distance from the taxel to the capsule surface (negative = pressed in),
the maximum over capsules. Taxels whose normal faces away from the contact
normal do not sense it (no sensing through the link).
"""

from __future__ import annotations

import numpy as np

from sphri.config import Configured
from sphri.encode.common import capsule_radius, check_frame_index, make_frames, select_rows
from sphri.encode.schema import ProximityEncoderSchema
from sphri.encode.spatial import VoxelHash, proximity_kernel, voxel_size
from sphri.layout.common import nn_spacing
from sphri.types import Contacts, Frames, Layout, Link, SurfaceMap


class ProximityEncoder(Configured):
    """``encoder=proximity``: taxels within ``sensing_distance_m`` of a capsule surface."""

    VERSION = "1"

    SCHEMA = ProximityEncoderSchema
    sensing_distance_m: float  # these three set from SCHEMA by Configured
    intensity: str
    depth_scale_m: float

    def encode(
        self, contacts: Contacts, link: Link, surface: SurfaceMap, layout: Layout, frame_index: np.ndarray
    ) -> Frames:
        """Readings (M, N): uint8 (binary) or float32 (depth) for the frames in ``frame_index``."""
        who = "encoder=proximity"
        fi = check_frame_index(contacts, frame_index, who)
        rows, start = select_rows(contacts, fi)
        binary = self.intensity == "binary"
        m, n = len(fi), layout.n_taxels
        out_u8 = np.zeros((m, n) if binary else (0, 0), dtype=np.uint8)
        out_f32 = np.zeros((0, 0) if binary else (m, n), dtype=np.float32)
        out = out_u8 if binary else out_f32
        if rows.size == 0 or n == 0:
            return make_frames(out, layout, surface)
        sphere = np.asarray(contacts.segment_point_m, dtype=np.float64)[rows]
        radius = capsule_radius(contacts, rows)
        normal = np.asarray(contacts.normal, dtype=np.float64)[rows]
        for name, a in (("segment_point_m", sphere), ("depth_m/distance_m", radius), ("normal", normal)):
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{who}: contacts.{name} holds NaN or inf in the requested frames")
        spacing = float(np.median(nn_spacing(layout.position_m))) if n > 1 else 0.01
        vh = VoxelHash(layout.position_m, voxel_size(layout.position_m, spacing))
        proximity_kernel(
            start,
            np.ascontiguousarray(sphere),
            np.ascontiguousarray(radius),
            np.ascontiguousarray(normal),
            np.ascontiguousarray(layout.position_m, dtype=np.float64),
            np.ascontiguousarray(layout.normal, dtype=np.float64),
            float(self.sensing_distance_m),
            float(self.depth_scale_m),
            vh.origin,
            vh.cell_m,
            vh.dims,
            vh.start,
            vh.order,
            binary,
            out_u8,
            out_f32,
            int(min(max(1, m // 256), 64)),
        )
        return make_frames(out, layout, surface)
