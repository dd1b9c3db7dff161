"""The whole robot's surface for maps: samples on every link, a kernel that smooths within links, body parts.

:func:`body_surface` samples each link (:func:`sphri.surface.density.sample_link`,
link frame), labels every sample with its body part, builds each link's
geodesic kernel (:class:`~sphri.surface.density.SurfaceKernel`) and joins
them block-diagonally, so density never leaks from one link to another
(geodesic within links). For display and SWD the samples are placed at the
robot's rest pose. :func:`touched_pairs` maps contact rows (link frame) to
(frame, element) pairs of the whole surface.

:func:`reachable_elements` marks the elements a skin can cover: not turned
to the floor below a stated height (the underside of the mobile base: no hand
gets there) and not buried inside another link at the rest pose (a joint
ball half inside the upper arm, a bar's end inside the torso). The study's
areas, densities per cm^2 and budgets count the reachable elements only.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from scipy import sparse

from sphri.sessions.contact import BodyContacts
from sphri.surface.density import SurfaceKernel, SurfaceSamples, sample_link, touched_elements
from sphri.types import Link


@dataclass
class RestSurface:
    """Every link's samples, their body parts, and the robot's mesh at the rest pose (no kernel, no reachability)."""

    links: tuple[str, ...]
    local: list[SurfaceSamples]
    """Per link: its samples in the link frame."""
    offset: np.ndarray
    """(L + 1,) first element of each link in the joined samples."""
    samples: SurfaceSamples
    """All elements at the rest pose (world frame)."""
    part: np.ndarray
    """(P,) object: body part of each element (its link's name where no part holds it)."""
    link_of: np.ndarray
    """(P,) int64 link index of each element."""
    mesh: Link
    """Every link's mesh at the rest pose, joined."""
    parts: list[str]
    """The body parts (the robot's order), then the links with elements no part holds."""


@dataclass
class BodySurface(RestSurface):
    """A :class:`RestSurface` with the kernel that smooths within links and the reachability of each element."""

    kernel: SurfaceKernel
    reach: np.ndarray | None = None
    """(P,) object: '' for an element a hand can reach, else why not ('floor', 'buried'); None: not assessed."""

    @property
    def reachable(self) -> np.ndarray:
        """(P,) bool: elements a skin can cover (all when not assessed)."""
        return np.ones(self.samples.n, dtype=bool) if self.reach is None else self.reach == ""

    def part_area_m2(self, reachable: bool = False) -> dict[str, float]:
        """Area per body part (m^2); ``reachable``: only the elements a hand can reach."""
        a = self.samples.area_m2 * (self.reachable if reachable else 1.0)
        return {p: float(a[self.part == p].sum()) for p in self.parts}

    def area_table(self):
        """Per body part: area, reachable area, and the area lost to each reason (cm^2), as a DataFrame."""
        import pandas as pd

        reach = self.reach if self.reach is not None else np.full(self.samples.n, "", dtype=object)
        rows = []
        for p in self.parts:
            m = self.part == p
            a = self.samples.area_m2[m] * 1e4
            rows.append(
                dict(
                    part=p,
                    area_cm2=float(a.sum()),
                    reachable_cm2=float(a[reach[m] == ""].sum()),
                    floor_facing_cm2=float(a[reach[m] == "floor"].sum()),
                    buried_cm2=float(a[reach[m] == "buried"].sum()),
                )
            )
        return pd.DataFrame(rows)


#: Elements whose outward normal lies within ``acos(DOWN_COS)`` of straight down ...
DOWN_COS = 0.5
#: ... below this height (m, at the rest pose) face the floor out of a hand's reach.
FLOOR_HEIGHT_M = 0.3


def winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, chunk: int = 512) -> np.ndarray:
    """(P,) generalized winding number of a triangle mesh at each point (1 inside a closed mesh, 0 outside;
    fractional near holes, so it also judges the open meshes real descriptions hold)."""
    tri = vertices[faces]
    out = np.empty(len(points))
    for i in range(0, len(points), chunk):
        p = points[i : i + chunk]
        a, b, c = (tri[None, :, k, :] - p[:, None, :] for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("pfi,pfi->pf", a, b) * lc
            + np.einsum("pfi,pfi->pf", b, c) * la
            + np.einsum("pfi,pfi->pf", c, a) * lb
        )
        out[i : i + chunk] = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
    return out


def reachable_elements(
    robot,
    links: tuple[str, ...],
    points: np.ndarray,
    normals: np.ndarray,
    link_of: np.ndarray,
    floor_height_m: float = FLOOR_HEIGHT_M,
    down_cos: float = DOWN_COS,
) -> np.ndarray:
    """(P,) object: '' where a hand can reach the element (world ``points`` / ``normals`` at the rest pose),
    'buried' for one inside another link, else 'floor' for one turned to the floor below ``floor_height_m``."""
    out = np.full(len(points), "", dtype=object)
    rest = robot.rest_poses()
    order = list(robot.tree.links)
    for li, name in enumerate(links):
        link = robot.links[name]
        m = rest[order.index(name)]
        v = link.vertices @ m[:3, :3].T + m[:3, 3]
        lo, hi = v.min(axis=0) - 1e-3, v.max(axis=0) + 1e-3
        cand = np.flatnonzero((link_of != li) & (out == "") & np.all((points >= lo) & (points <= hi), axis=1))
        if cand.size:
            w = winding_numbers(points[cand], v, link.faces)
            out[cand[np.abs(w) > 0.5]] = "buried"
    out[(out == "") & (normals[:, 2] < -down_cos) & (points[:, 2] < floor_height_m)] = "floor"
    return out


def rest_surface(robot, links: tuple[str, ...], spacing_mm: float, seed: int = 0) -> RestSurface:
    """Sample each of ``links`` (``spacing_mm`` elements, link frame), label the samples with their body parts
    and place them and the meshes at the rest pose."""
    rest = robot.rest_poses()
    order = list(robot.tree.links)
    local, pts, nrm, face, area, part, link_of = [], [], [], [], [], [], []
    verts, faces, nv = [], [], 0
    for li, name in enumerate(links):
        link = robot.links[name]
        s = sample_link(link, spacing_mm, seed + li)
        local.append(s)
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
    joined = SurfaceSamples(
        robot.name,
        np.concatenate(pts),
        np.concatenate(nrm),
        np.concatenate(face),
        area_all,
        float(np.sqrt(total / offset[-1])),
    )
    part_all = np.concatenate(part)
    names = [p.name for p in robot.parts]
    names += sorted(set(part_all) - set(names))
    mesh = Link(name=robot.name, vertices=np.concatenate(verts), faces=np.concatenate(faces), watertight=False)
    return RestSurface(
        tuple(links),
        local,
        offset,
        joined,
        part_all,
        np.concatenate(link_of),
        mesh,
        [p for p in names if (part_all == p).any()],
    )


def body_surface(
    robot,
    links: tuple[str, ...],
    spacing_mm: float,
    bandwidth_mm: float,
    seed: int = 0,
    floor_height_m: float | None = FLOOR_HEIGHT_M,
    down_cos: float = DOWN_COS,
) -> BodySurface:
    """The whole surface (see the module docstring); ``floor_height_m=None`` skips the reachability test."""
    r = rest_surface(robot, links, spacing_mm, seed)
    kernels = [SurfaceKernel(s, bandwidth_mm, "geodesic") for s in r.local]
    kernel = object.__new__(SurfaceKernel)
    kernel.samples = r.samples
    kernel.bandwidth_m = float(bandwidth_mm) * 1e-3
    kernel.kernel = "geodesic"
    kernel.stretch = float(np.mean([k.stretch for k in kernels]))
    kernel.matrix = sparse.block_diag([k.matrix for k in kernels], format="csr")
    reach = None
    if floor_height_m is not None:
        reach = reachable_elements(
            robot, tuple(links), r.samples.points_m, r.samples.normal, r.link_of, floor_height_m, down_cos
        )
    rest = {f.name: getattr(r, f.name) for f in fields(r)}
    return BodySurface(**rest, kernel=kernel, reach=reach)


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
