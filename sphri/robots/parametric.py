"""``ParametricRobot``: built-in morphologies made from dimensions in the YAML.

Each link is a loft of superellipse cross-sections along its long axis
(:func:`loft_mesh`), closed with flat end caps and wound outward; the
profile's stations taper the ends. ``robot=reachy`` mirrors the real study's
collision hulls (frames and sizes), ``nao_child`` and ``service_bot`` give
other proportions.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sphri.robots.schema import check_parametric_link, check_regions, loft_spec
from sphri.robots.validate import make_link, signed_volume
from sphri.types import Robot

log = logging.getLogger(__name__)

#: Cross-section axes (a, b) for each long axis, in x, y, z order.
_CROSS = {"x": (1, 2), "y": (0, 2), "z": (0, 1)}
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def superellipse(n: int, a: float, b: float, exponent: float) -> np.ndarray:
    """(n, 2) points on ``|x/a|^p + |y/b|^p = 1`` counter-clockwise from (a, 0).

    With n a multiple of 4 the points include (+-a, 0) and (0, +-b) exactly.
    """
    i = np.arange(n)
    theta = i * (2.0 * np.pi / n)
    c, s = np.cos(theta), np.sin(theta)
    quarter = (4 * i) % n == 0  # exactly on an axis: avoid cos(pi/2) = 6e-17
    q = (4 * i[quarter]) // n
    c[quarter] = np.array([1.0, 0.0, -1.0, 0.0])[q]
    s[quarter] = np.array([0.0, 1.0, 0.0, -1.0])[q]
    e = 2.0 / exponent
    return np.stack([a * np.sign(c) * np.abs(c) ** e, b * np.sign(s) * np.abs(s) ** e], axis=1)


def loft_mesh(
    size_m: Sequence[float],
    center_m: Sequence[float],
    axis: str,
    profile: Sequence[Sequence[float]],
    exponent: float,
    n_around: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Closed, outward-wound loft of superellipse sections.

    ``size_m`` (x, y, z) bounding box and ``center_m`` its centre (metres);
    ``axis`` the long axis; ``profile`` rows ``[t, scale_a, scale_b]`` (t in
    [0, 1] along the axis, scales of the half-extents). Returns vertices
    (S * n_around + 2, 3) float64 and faces (2 * n_around * S, 3) int64.
    """
    size = np.asarray(size_m, dtype=np.float64)
    centre = np.asarray(center_m, dtype=np.float64)
    prof = np.asarray(profile, dtype=np.float64)
    ax = _AXIS_INDEX[axis]
    ia, ib = _CROSS[axis]
    n, s_count = int(n_around), len(prof)
    rings = []
    for t, sa, sb in prof:
        pts = np.zeros((n, 3))
        pts[:, [ia, ib]] = superellipse(n, 0.5 * size[ia] * sa, 0.5 * size[ib] * sb, exponent)
        pts[:, ax] = (t - 0.5) * size[ax]
        rings.append(pts)
    caps = np.zeros((2, 3))
    caps[0, ax], caps[1, ax] = -0.5 * size[ax], 0.5 * size[ax]
    vertices = np.concatenate(rings + [caps]) + centre
    j = np.arange(n)
    jn = (j + 1) % n
    blocks: list[np.ndarray] = []
    for s in range(s_count - 1):
        a0, a1, b0, b1 = s * n + j, s * n + jn, (s + 1) * n + j, (s + 1) * n + jn
        blocks += [np.stack([a0, a1, b1], 1), np.stack([a0, b1, b0], 1)]
    bottom, top = s_count * n, s_count * n + 1
    last = (s_count - 1) * n
    blocks += [np.stack([np.full(n, bottom), jn, j], 1), np.stack([np.full(n, top), last + j, last + jn], 1)]
    faces = np.concatenate(blocks).astype(np.int64)
    if signed_volume(vertices, faces) < 0:  # the (a, b, axis) frame is left-handed for axis y
        faces = faces[:, ::-1].copy()
    return vertices, faces


class ParametricRobot:
    """A built-in morphology from dimensions (``robot=reachy``, ``nao_child``, ``service_bot``).

    ``links``: link name -> spec (``size_m``, ``center_m``, ``axis``,
    ``profile``, ``exponent``, ``n_around``; see
    :class:`sphri.robots.schema.ParametricLinkSpec`); ``regions``: skin
    region -> link name.
    """

    VERSION = "1"

    def __init__(self, name: str, links: Mapping[str, Any], regions: Mapping[str, str]):
        self.name = str(name)
        self.links = {str(k): loft_spec(v, f"robot.links.{k}") for k, v in links.items()}
        self.regions = {str(k): str(v) for k, v in regions.items()}
        for link, spec in self.links.items():
            check_parametric_link(spec, f"robot.links.{link}")
        check_regions(self.regions, list(self.links))

    def build(self) -> Robot:
        """The :class:`Robot`: one closed loft mesh per link (metres, link frame)."""
        links = {}
        for name, spec in self.links.items():
            v, f = loft_mesh(**spec)
            links[name] = make_link(name, v, f, units="m", source=f"parametric {self.name}")
            log.debug("robot %s: link %s: %d vertices, %d faces", self.name, name, len(v), len(f))
        return Robot(name=self.name, links=links, regions=dict(self.regions))
