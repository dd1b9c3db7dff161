"""Chart functions of a :class:`~sphri.types.SurfaceMap`: 3-D points <-> (u, v).

All functions are vectorized over K points (float64 metres, link frame):

- :func:`to_uv` ``(K, 3) -> (K, 2)`` chart coordinates in [0, 1]^2;
- :func:`jacobian` ``(K, 3) -> (K, 2, 3)`` d(u, v)/d(x, y, z) in 1/metres;
- :func:`from_uv` ``(K, 2) -> (K, 3)`` points on the fitted primitive
  (optionally with its outward normals and a validity mask).

Each surface kind is one :class:`Chart` class registered under its
``SurfaceMap.kind`` (:func:`register_chart`); :func:`chart_of` finds it, and
every caller (layouts, encoders, coverage maps, placement) asks the chart
instead of testing the kind. Kinds: ``cylinder`` (u along the axis, v the
angle, wraps) and ``box`` (the oriented bounding box unfolded into a net: a
band of four faces around the long axis, wrapping in v, and the two end caps
attached above and below one band face); ``mesh`` has no 2-D chart (its
``to_uv``/``jacobian``/``from_uv`` raise). A new surface is one module: its
fit (a component returning a ``SurfaceMap`` of a new kind) and its chart
class, registered there.
"""

from __future__ import annotations

from typing import ClassVar, Protocol

import numpy as np

from sphri.types import SurfaceMap

TWO_PI = 2.0 * np.pi


def _require_chart(surface: SurfaceMap) -> None:
    if not surface.has_uv:
        raise ValueError(
            f"surface kind {surface.kind!r} has no 2-D chart (to_uv/jacobian/from_uv need "
            "surface=cylinder or surface=box)"
        )


def _points(points: np.ndarray, name: str = "points") -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name} must be (K, 3) metres, got shape {p.shape}")
    return p


# --------------------------------------------------------------------------- cylinder


def _cyl_local(surface: SurfaceMap, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pr = surface.params
    d = p - pr["origin"]
    return d @ pr["axis"], d @ pr["ref"], d @ pr["binormal"]


class CylinderChart:
    """``surface=cylinder``: u along the axis (the paper's h), v the angle around it (a), wrapping."""

    every_cell_valid: ClassVar[bool] = True

    def to_uv(self, surface: SurfaceMap, p: np.ndarray) -> np.ndarray:
        pr = surface.params
        t, x, y = _cyl_local(surface, p)
        length = pr["u_max"] - pr["u_min"]
        u = np.clip((t - pr["u_min"]) / length, 0.0, 1.0)
        v = np.mod(np.arctan2(y, x) / TWO_PI, 1.0)
        v[v >= 1.0] = 0.0
        return np.stack([u, v], axis=1)

    def jacobian(self, surface: SurfaceMap, p: np.ndarray) -> np.ndarray:
        pr = surface.params
        _, x, y = _cyl_local(surface, p)
        length = pr["u_max"] - pr["u_min"]
        rho2 = np.maximum(x * x + y * y, (1e-3 * pr["radius"]) ** 2)
        j = np.empty((p.shape[0], 2, 3))
        j[:, 0, :] = pr["axis"] / length
        j[:, 1, :] = (x[:, None] * pr["binormal"] - y[:, None] * pr["ref"]) / (TWO_PI * rho2[:, None])
        return j

    def from_uv(self, surface: SurfaceMap, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pr = surface.params
        t = pr["u_min"] + uv[:, 0] * (pr["u_max"] - pr["u_min"])
        a = TWO_PI * uv[:, 1]
        radial = np.cos(a)[:, None] * pr["ref"] + np.sin(a)[:, None] * pr["binormal"]
        pts = pr["origin"] + t[:, None] * pr["axis"] + pr["radius"] * radial
        return pts, radial, np.ones(uv.shape[0], dtype=bool)

    def primitive_distance(self, surface, p):
        """Distance to the closed finite cylinder (lateral surface and the two end discs)."""
        pr = surface.params
        t, x, y = _cyl_local(surface, p)
        rho = np.hypot(x, y)
        r = pr["radius"]
        lo, hi = pr["u_min"], pr["u_max"]
        dt_out = np.maximum(np.maximum(lo - t, t - hi), 0.0)
        inside_slab = dt_out == 0
        return np.where(
            inside_slab,
            np.where(rho <= r, np.minimum(r - rho, np.minimum(t - lo, hi - t)), rho - r),
            np.where(rho <= r, dt_out, np.hypot(dt_out, rho - r)),
        )

    def long_axis_length_m(self, surface):
        return float(surface.metres_per_u)

    def describe_uv(self, u, v, around):
        angle = "all around" if around else f"a {360 * v[0]:.0f}-{360 * v[1]:.0f} deg"
        return f"h {u[0]:.2f}-{u[1]:.2f}, {angle}"


# --------------------------------------------------------------------------- box
# Faces: 0 = +a0 (top cap), 1 = -a0 (bottom cap), 2 = +a1, 3 = -a1, 4 = +a2, 5 = -a2.
# Band (around a0, v increasing): +a1, +a2, -a1, -a2; caps hang off the +a2 face.

_BOX_DU = np.array(  # du/dq in local (a0, a1, a2) coordinates, times U
    [[0, 0, -1], [0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0], [1, 0, 0]], dtype=np.float64
)
_BOX_DV = np.array(  # dv/dq times P
    [[0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, -1, 0], [0, 1, 0]], dtype=np.float64
)


def box_face(surface: SurfaceMap, points: np.ndarray) -> np.ndarray:
    """(K,) int64 box face (0..5, see module) each point projects onto."""
    pr = surface.params
    q = (_points(points) - pr["centre"]) @ pr["rotation"].T
    s = np.abs(q) / (0.5 * pr["extents"])
    axis = np.argmax(s, axis=1)
    neg = q[np.arange(q.shape[0]), axis] < 0
    return (2 * axis + neg).astype(np.int64)


class BoxChart:
    """``surface=box``: the oriented box unfolded into a net (a band around the long axis and two caps)."""

    every_cell_valid: ClassVar[bool] = False

    def to_uv(self, surface: SurfaceMap, p: np.ndarray) -> np.ndarray:
        pr = surface.params
        e0, e1, e2 = pr["extents"]
        big_u, per = pr["U"], pr["P"]
        q = (p - pr["centre"]) @ pr["rotation"].T
        face = box_face(surface, p)
        x = np.clip(q[:, 0], -e0 / 2, e0 / 2)
        y = np.clip(q[:, 1], -e1 / 2, e1 / 2)
        z = np.clip(q[:, 2], -e2 / 2, e2 / 2)
        um = e2 + x + e0 / 2
        s = np.empty_like(um)
        f = face
        s[f == 2] = (z + e2 / 2)[f == 2]
        s[f == 4] = (e2 + e1 / 2 - y)[f == 4]
        s[f == 3] = (e2 + e1 + e2 / 2 - z)[f == 3]
        s[f == 5] = (2 * e2 + e1 + y + e1 / 2)[f == 5]
        cap = (f == 0) | (f == 1)
        s[cap] = (e2 + e1 / 2 - y)[cap]
        um[f == 0] = (e2 + e0 + e2 / 2 - z)[f == 0]
        um[f == 1] = (z + e2 / 2)[f == 1]
        u = np.clip(um / big_u, 0.0, 1.0)
        v = np.mod(s / per, 1.0)
        v[v >= 1.0] = 0.0
        return np.stack([u, v], axis=1)

    def jacobian(self, surface: SurfaceMap, p: np.ndarray) -> np.ndarray:
        pr = surface.params
        face = box_face(surface, p)
        rot = pr["rotation"]
        j = np.empty((p.shape[0], 2, 3))
        j[:, 0, :] = (_BOX_DU[face] / pr["U"]) @ rot
        j[:, 1, :] = (_BOX_DV[face] / pr["P"]) @ rot
        return j

    def from_uv(self, surface: SurfaceMap, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pr = surface.params
        e0, e1, e2 = pr["extents"]
        um = uv[:, 0] * pr["U"]
        s = np.mod(uv[:, 1], 1.0) * pr["P"]
        k = uv.shape[0]
        q = np.zeros((k, 3))
        nl = np.zeros((k, 3))
        band = (um >= e2) & (um <= e2 + e0)
        q[:, 0] = um - e2 - e0 / 2
        # band faces by perimeter position
        f2 = band & (s < e2)
        f4 = band & (s >= e2) & (s < e2 + e1)
        f3 = band & (s >= e2 + e1) & (s < 2 * e2 + e1)
        f5 = band & (s >= 2 * e2 + e1)
        q[f2, 1], q[f2, 2], nl[f2, 1] = e1 / 2, s[f2] - e2 / 2, 1
        q[f4, 1], q[f4, 2], nl[f4, 2] = e2 + e1 / 2 - s[f4], e2 / 2, 1
        q[f3, 1], q[f3, 2], nl[f3, 1] = -e1 / 2, e2 + e1 + e2 / 2 - s[f3], -1
        q[f5, 1], q[f5, 2], nl[f5, 2] = s[f5] - 2 * e2 - e1 - e1 / 2, -e2 / 2, -1
        # caps (void net cells are clamped onto the nearest cap edge and flagged)
        cap = ~band
        in_cap = cap & (s >= e2) & (s <= e2 + e1)
        sc = np.clip(s, e2, e2 + e1)
        top = cap & (um > e2 + e0)
        bot = cap & (um < e2)
        q[cap, 1] = e2 + e1 / 2 - sc[cap]
        q[top, 0], q[top, 2], nl[top, 0] = e0 / 2, e2 / 2 - (um[top] - e2 - e0), 1
        q[bot, 0], q[bot, 2], nl[bot, 0] = -e0 / 2, um[bot] - e2 / 2, -1
        q[:, 2] = np.clip(q[:, 2], -e2 / 2, e2 / 2)
        rot = pr["rotation"]
        pts = pr["centre"] + q @ rot
        normals = nl @ rot
        valid = band | in_cap
        return pts, normals, valid

    def primitive_distance(self, surface, p):
        """Distance to the box's surface."""
        pr = surface.params
        q = (p - pr["centre"]) @ pr["rotation"].T
        h = 0.5 * pr["extents"]
        over = np.abs(q) - h
        outside = np.linalg.norm(np.maximum(over, 0.0), axis=1)
        inside = np.minimum(np.max(over, axis=1), 0.0)
        return np.where(outside > 0, outside, -inside)

    def long_axis_length_m(self, surface):
        return float(surface.params["extents"][0])

    def describe_uv(self, u, v, around):
        return f"u {u[0]:.2f}-{u[1]:.2f}, " + ("v all around" if around else f"v {v[0]:.2f}-{v[1]:.2f}")


# --------------------------------------------------------------------------- charts


class Chart(Protocol):
    """What a surface kind provides: its chart and the quantities layouts and maps need.

    Methods take the :class:`~sphri.types.SurfaceMap` (its ``params`` hold
    the fitted primitive); a chart object holds no state.
    """

    #: True when every cell of a (u, v) grid lies on the surface (no void parts of the chart).
    every_cell_valid: ClassVar[bool]

    def to_uv(self, surface: SurfaceMap, p: np.ndarray) -> np.ndarray: ...

    def jacobian(self, surface: SurfaceMap, p: np.ndarray) -> np.ndarray: ...

    def from_uv(self, surface: SurfaceMap, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def primitive_distance(self, surface: SurfaceMap, p: np.ndarray) -> np.ndarray: ...

    def long_axis_length_m(self, surface: SurfaceMap) -> float: ...

    def describe_uv(self, u: tuple[float, float], v: tuple[float, float], around: bool) -> str: ...


_CHARTS: dict[str, Chart] = {}


def register_chart(kind: str, chart: Chart) -> None:
    """Make ``chart`` the chart of every ``SurfaceMap`` of ``kind`` (call it in the surface's module)."""
    _CHARTS[kind] = chart


def chart_of(surface: SurfaceMap | str) -> Chart:
    """The :class:`Chart` of ``surface`` (or of a kind name)."""
    kind = surface if isinstance(surface, str) else surface.kind
    try:
        return _CHARTS[kind]
    except KeyError:
        raise ValueError(
            f"surface kind {kind!r} has no registered chart; known: {sorted(_CHARTS)} "
            "(register one with sphri.surface.charts.register_chart)"
        ) from None


class MeshChart:
    """``surface=mesh``: no 2-D chart; the link itself is the surface (distance 0)."""

    every_cell_valid: ClassVar[bool] = False

    def _none(self, surface, *_):
        _require_chart(surface)
        raise AssertionError("unreachable: a mesh surface has no chart")

    to_uv = jacobian = from_uv = _none

    def primitive_distance(self, surface, p):
        return np.zeros(p.shape[0])

    def long_axis_length_m(self, surface):
        if "length_m" in surface.params:
            return float(surface.params["length_m"])
        raise ValueError(f"surface kind {surface.kind!r} records no long-axis length (params['length_m'])")

    def describe_uv(self, u, v, around):
        return BoxChart.describe_uv(self, u, v, around)


register_chart("cylinder", CylinderChart())
register_chart("box", BoxChart())
register_chart("mesh", MeshChart())


# --------------------------------------------------------------------------- public


def to_uv(surface: SurfaceMap, points: np.ndarray) -> np.ndarray:
    """(K, 2) float64 chart coordinates of (K, 3) link-frame points (metres).

    ``u`` is clipped to [0, 1]; ``v`` lies in [0, 1) (wraps for cylinders).
    """
    _require_chart(surface)
    return chart_of(surface).to_uv(surface, _points(points))


def jacobian(surface: SurfaceMap, points: np.ndarray) -> np.ndarray:
    """(K, 2, 3) float64 d(u, v)/d(x, y, z) at (K, 3) points, in 1/metres.

    Cylinder: the angle's derivative uses the point's own distance to the
    axis, so a patch on a flat facet maps to the angle it truly subtends.
    """
    _require_chart(surface)
    return chart_of(surface).jacobian(surface, _points(points))


def from_uv(
    surface: SurfaceMap,
    uv: np.ndarray,
    return_normal: bool = False,
    return_valid: bool = False,
):
    """(K, 3) points on the fitted primitive at chart coordinates ``uv (K, 2)``.

    With ``return_normal`` also the primitive's (K, 3) outward unit normals;
    with ``return_valid`` also a (K,) bool mask, False where ``uv`` lies in a
    void part of the chart (box nets: outside every face; the point is then
    clamped onto the nearest cap edge).
    """
    _require_chart(surface)
    uv = np.asarray(uv, dtype=np.float64)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise ValueError(f"uv must be (K, 2), got shape {uv.shape}")
    pts, nrm, valid = chart_of(surface).from_uv(surface, uv)
    out = [pts]
    if return_normal:
        out.append(nrm)
    if return_valid:
        out.append(valid)
    return out[0] if len(out) == 1 else tuple(out)


def primitive_distance(surface: SurfaceMap, points: np.ndarray) -> np.ndarray:
    """(K,) float64 distance (metres) from points to the fitted primitive's surface (mesh: zeros)."""
    return chart_of(surface).primitive_distance(surface, _points(points))
