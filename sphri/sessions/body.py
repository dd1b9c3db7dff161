"""The whole robot's surface for maps: samples on every link, a kernel that smooths within links, body parts.

:func:`body_surface` samples each link (:func:`sphri.surface.density.sample_link`,
link frame), labels every sample with its body part, builds each link's
geodesic kernel (:class:`~sphri.surface.density.SurfaceKernel`) and joins
them block-diagonally, so density never leaks from one link to another
(geodesic within links). For display and SWD the samples are placed at the
robot's rest pose. :func:`touched_pairs` maps contact rows (link frame) to
(frame, element) pairs of the whole surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from sphri.surface.density import SurfaceKernel, SurfaceSamples, sample_link, touched_elements
from sphri.sessions.contact import BodyContacts
from sphri.types import Link


@dataclass
class BodySurface:
    links: tuple[str, ...]
    local: list[SurfaceSamples]
    """Per link: its samples in the link frame."""
    offset: np.ndarray
    """(L + 1,) first element of each link in the joined samples."""
    samples: SurfaceSamples
    """All elements at the rest pose (world frame)."""
    kernel: SurfaceKernel
    part: np.ndarray
    """(P,) object: body part of each element."""
    link_of: np.ndarray
    """(P,) int64 link index of each element."""
    mesh: Link
    """Every link's mesh at the rest pose, joined (for display)."""
    parts: list[str]

    def part_area_m2(self) -> dict[str, float]:
        return {p: float(self.samples.area_m2[self.part == p].sum()) for p in self.parts}


def body_surface(robot, links: tuple[str, ...], spacing_mm: float, bandwidth_mm: float, seed: int = 0) -> BodySurface:
    rest = robot.rest_poses()
    order = list(robot.tree.links)
    local, kernels, pts, nrm, face, area, part, link_of = [], [], [], [], [], [], [], []
    verts, faces, nv = [], [], 0
    for li, name in enumerate(links):
        link = robot.links[name]
        s = sample_link(link, spacing_mm, seed + li)
        local.append(s)
        kernels.append(SurfaceKernel(s, bandwidth_mm, "geodesic"))
        m = rest[order.index(name)]
        pts.append(s.points_m @ m[:3, :3].T + m[:3, 3])
        nrm.append(s.normal @ m[:3, :3].T)
        face.append(s.face)
        area.append(s.area_m2)
        lab = robot.part_labels(name, s.points_m, s.normal)
        part.append(np.where(lab == "", name, lab))
        link_of.append(np.full(s.n, li, dtype=np.int64))
        verts.append(link.vertices @ m[:3, :3].T + m[:3, 3])
        faces.append(link.faces + nv)
        nv += len(link.vertices)
    offset = np.r_[0, np.cumsum([s.n for s in local])].astype(np.int64)
    area_all = np.concatenate(area)
    total = float(area_all.sum())
    joined = SurfaceSamples(robot.name, np.concatenate(pts), np.concatenate(nrm), np.concatenate(face), area_all,
                            float(np.sqrt(total / offset[-1])))
    kernel = object.__new__(SurfaceKernel)
    kernel.samples = joined
    kernel.bandwidth_m = float(bandwidth_mm) * 1e-3
    kernel.kernel = "geodesic"
    kernel.stretch = float(np.mean([k.stretch for k in kernels]))
    kernel.matrix = sparse.block_diag([k.matrix for k in kernels], format="csr")
    part_all = np.concatenate(part)
    names = [p.name for p in robot.parts]
    names += sorted(set(part_all) - set(names))
    mesh = Link(name=robot.name, vertices=np.concatenate(verts), faces=np.concatenate(faces), watertight=False)
    return BodySurface(tuple(links), local, offset, joined, kernel, part_all, np.concatenate(link_of), mesh,
                       [p for p in names if (part_all == p).any()])


def touched_pairs(body: BodySurface, bc: BodyContacts, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique (frame, element) pairs of contact ``rows``, sorted by frame then element."""
    fs, es = [], []
    for li in range(len(body.links)):
        r = rows[bc.link[rows] == li]
        if r.size == 0:
            continue
        f, e = touched_elements(body.local[li], bc.frame[r], bc.point_m[r], bc.normal[r], bc.patch_radius_m[r], "patch")
        fs.append(f)
        es.append(e + body.offset[li])
    if not fs:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    n = int(body.offset[-1])
    key = np.unique(np.concatenate(fs) * n + np.concatenate(es))
    return key // n, key % n
