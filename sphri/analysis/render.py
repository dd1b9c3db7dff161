"""Pictures and meshes of contact densities (matplotlib Agg, trimesh), in sphri's figure style
(:mod:`sphri.figures`: print sizes, PNG + PDF + SVG, no clipped or overlapping text).

- :class:`LinkView`: the link subdivided for display (edges about 1/80 of
  its size), turned so that its long axis is vertical, with the
  interpolation from surface samples to faces and vertices computed once;
  ``render`` draws several views around the long axis with a colour bar,
  ``write_ply`` writes a vertex-coloured PLY that any viewer opens.
- :func:`render_uv`: the unwrapped (u, v) map where the surface has a chart.
- :func:`plot_overview`: groups x views grid, one picture for all gestures,
  on one colour scale with one colour bar.
- :func:`plot_coverage_curves`, :func:`plot_swd_heatmap`.

Densities are shown as % of contact per cm^2 (density in 1/m^2 times 0.01).

Colour varies smoothly within faces. A robot's collision meshes are coarse (Reachy 2's torso: triangles with
40 cm edges), so a view is first subdivided until no edge is longer than the one that gives the target number of
faces (meshes that already have that many faces included: their few coarse faces are split too), and each face's
density is read from the samples at its centre. The face values are then spread to the vertices (the area-weighted
mean of the faces around each vertex) and every face is drawn with Gouraud shading between its corners'
colours (:meth:`LinkView.corner_values`). The shading uses matplotlib's Gouraud triangles (the renderer
``tripcolor(shading='gouraud')`` draws with), given one RGBA colour per face corner in the view's own depth order:
back faces culled and faces painted far to near exactly as the flat drawing does, each corner's colour darkened by
its face's angle to the viewer, and colours other than the colour scale (the study's grey for no contact) kept.
``tripcolor`` itself would take one scalar per shared vertex, with no per-face lighting or colour outside the
scale, and subdividing further would multiply the faces to draw instead. A face whose own value is zero (or, in
the study's maps, under the no-contact share) stays flat in the zero colour: interpolation fades a touched face
towards its untouched neighbour but never tints the untouched face.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402

from sphri import figures  # noqa: E402
from sphri.analysis.compare import PairwiseComparison  # noqa: E402
from sphri.analysis.placement import CoverageCurve  # noqa: E402
from sphri.surface.density import SurfaceSamples  # noqa: E402
from sphri.types import Link, SurfaceMap  # noqa: E402

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.image import AxesImage

#: density (1/m^2) -> % of contact per cm^2
PERCENT_PER_CM2 = 0.01
CMAP = "YlOrRd"
_AXES = ("x", "y", "z")


def _direction_name(v: np.ndarray) -> str:
    i = int(np.argmax(np.abs(v)))
    return ("+" if v[i] >= 0 else "-") + _AXES[i]


def display_rotation(points: np.ndarray) -> np.ndarray:
    """(3, 3) rotation whose rows are the display x, y, z axes in the link frame.

    Display z is the long (first principal) axis. When that lies within 25
    degrees of a link axis, the display uses the link's own axes (long axis
    positive up, the other two in cyclic order), so that views look along
    link axes; otherwise the principal axes, signs fixed.
    """
    pts = np.asarray(points, dtype=np.float64)
    _, _, vt = np.linalg.svd(pts - pts.mean(axis=0), full_matrices=False)
    long = vt[0]
    i = int(np.argmax(np.abs(long)))
    if abs(long[i]) >= np.cos(np.radians(25.0)):
        eye = np.eye(3)
        return np.stack([eye[(i + 1) % 3], eye[(i + 2) % 3], eye[i]])
    rows = [vt[1], vt[2], vt[0]]
    for r in rows:
        if r[np.argmax(np.abs(r))] < 0:
            r *= -1
    rot = np.stack(rows)
    if np.linalg.det(rot) < 0:
        rot[1] = -rot[1]
    return rot


def _bisect(v: np.ndarray, f: np.ndarray, max_edge: float, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Split triangles at the midpoint of their longest edge until no edge exceeds
    ``max_edge`` (or ``max_faces`` is reached). Keeps the winding; neighbours
    share midpoints where they split the same edge (else a T-junction, harmless
    for display)."""
    v = v.copy()
    for _ in range(40):
        tri = v[f]
        lengths = np.linalg.norm(tri[:, [1, 2, 0]] - tri, axis=2)  # edge i: vertex i -> i+1
        longest = lengths.argmax(axis=1)
        split = lengths.max(axis=1) > max_edge
        if not split.any() or f.shape[0] + split.sum() > max_faces:
            break
        rows = np.flatnonzero(split)
        k = longest[rows]
        a = f[rows, k]
        b = f[rows, (k + 1) % 3]
        c = f[rows, (k + 2) % 3]
        key = np.sort(np.stack([a, b], axis=1), axis=1)
        uniq, inv = np.unique(key, axis=0, return_inverse=True)
        mids = v.shape[0] + np.arange(uniq.shape[0])
        v = np.concatenate([v, 0.5 * (v[uniq[:, 0]] + v[uniq[:, 1]])])
        m = mids[inv.ravel()]
        keep = f[~split]
        f = np.concatenate([keep, np.stack([a, m, c], axis=1), np.stack([m, b, c], axis=1)])
    return v, f


def _subdivide(v: np.ndarray, f: np.ndarray, area: float, target_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Faces small enough to show a density: no edge longer than that of ``target_faces`` equal faces. A mesh
    with that many faces already still has its coarse ones split (a torso of a few large triangles among
    detailed joints), up to ``4 x target_faces`` more faces (Reachy 2's whole body: 36,201 faces, 96,946 split)."""
    edge = float(np.sqrt(4.0 * area / (np.sqrt(3.0) * target_faces))) * 1.2
    return _bisect(v, f, edge, f.shape[0] + 4 * target_faces)


class LinkView:
    """A link prepared for display of sample-based densities."""

    def __init__(self, link: Link, samples: SurfaceSamples, target_faces: int = 8000) -> None:
        v = np.asarray(link.vertices, dtype=np.float64)
        f = np.asarray(link.faces, dtype=np.int64)
        used = v[np.unique(f)]
        centre = 0.5 * (used.min(axis=0) + used.max(axis=0))
        v, f = _subdivide(v, f, samples.total_area_m2, target_faces)
        mesh = trimesh.Trimesh(v, f, process=False, validate=False)
        self.link = link.name
        self.vertices = v
        self.faces = f
        self.centre = centre
        self.rotation = display_rotation(samples.points_m)
        self.display = (v - centre) @ self.rotation.T
        self.face_normal = np.asarray(mesh.face_normals)
        self.face_area = np.asarray(mesh.area_faces)
        self.face_idx, self.face_w = samples.interpolation(v[f].mean(axis=1), self.face_normal)
        self.vert_idx, self.vert_w = samples.interpolation(v, np.asarray(mesh.vertex_normals))

    def face_values(self, density: np.ndarray) -> np.ndarray:
        """(F,) density at the display faces."""
        return np.einsum("fk,fk->f", np.asarray(density)[self.face_idx], self.face_w)

    def vertex_values(self, density: np.ndarray) -> np.ndarray:
        return np.einsum("vk,vk->v", np.asarray(density)[self.vert_idx], self.vert_w)

    def spread_to_vertices(self, face_vals: np.ndarray) -> np.ndarray:
        """(V,) the area-weighted mean of ``face_vals`` (F,) over the faces around each vertex (0 where none)."""
        n = self.vertices.shape[0]
        w = np.repeat(self.face_area, 3)
        num = np.bincount(self.faces.ravel(), weights=w * np.repeat(np.asarray(face_vals, float), 3), minlength=n)
        den = np.bincount(self.faces.ravel(), weights=w, minlength=n)
        return np.divide(num, den, out=np.zeros(n), where=den > 0)

    def corner_values(self, face_vals: np.ndarray, flat: np.ndarray | None = None) -> np.ndarray:
        """(F, 3) values at each face's corners for Gouraud shading: its vertices' values
        (:meth:`spread_to_vertices`); faces in ``flat`` ((F,) bool; default: value 0) keep their own value at
        every corner, so that a face without density is drawn in the zero colour, not tinted by a neighbour."""
        face_vals = np.asarray(face_vals, dtype=np.float64)
        out = self.spread_to_vertices(face_vals)[self.faces]
        flat = face_vals == 0 if flat is None else np.asarray(flat, dtype=bool)
        out[flat] = face_vals[flat, None]
        return out

    def density_colours(self, density: np.ndarray, vmax: float) -> np.ndarray:
        """(F, 3, 4) RGBA at each face's corners of ``density`` (per sample) on the scale 0..``vmax``
        (% per cm^2), smooth within faces (:meth:`corner_values`)."""
        vals = self.corner_values(self.face_values(np.asarray(density)) * PERCENT_PER_CM2)
        return plt.get_cmap(CMAP)(np.clip(vals / vmax, 0.0, 1.0) if vmax > 0 else np.zeros_like(vals))

    @staticmethod
    def _eye(azim_deg: float, elev_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Display-frame camera direction (towards the viewer), screen right and up."""
        a, e = np.radians(azim_deg), np.radians(elev_deg)
        eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        right = np.array([-np.sin(a), np.cos(a), 0.0])
        return eye, right, np.cross(eye, right)

    def camera(self, azim_deg: float, elev_deg: float = 12.0) -> str:
        """Link-frame axis the camera looks from, e.g. ``+x``."""
        return _direction_name(self.rotation.T @ self._eye(azim_deg, elev_deg)[0])

    def face_labels(self, labels: np.ndarray) -> np.ndarray:
        """(F,) the label of the sample that weighs most at each display face (e.g. its body part)."""
        best = np.argmax(self.face_w, axis=1)
        return np.asarray(labels)[self.face_idx[np.arange(len(best)), best]]

    def draw(
        self,
        ax: Axes,
        density: np.ndarray | None,
        azim_deg: float,
        vmax: float,
        elev_deg: float = 12.0,
        colours: np.ndarray | None = None,
    ) -> None:
        """Orthographic view from ``azim_deg`` around the long axis (vertical) on a 2-D axis.

        Back faces are culled and the rest painted far to near, faces coloured by density, smooth within
        faces (:meth:`density_colours`), or by ``colours``: (F, 4) RGBA per display face (flat) or (F, 3, 4) per
        face corner (Gouraud); lightly shaded by their angle to the viewer.
        """
        from matplotlib.collections import PolyCollection, TriMesh
        from matplotlib.tri import Triangulation

        if colours is None:
            colours = self.density_colours(np.asarray(density), vmax)
        colours = np.array(colours, dtype=np.float64)
        eye, right, up = self._eye(azim_deg, elev_deg)
        facing = (self.face_normal @ self.rotation.T) @ eye
        shade = 0.72 + 0.28 * np.clip(facing, 0.0, 1.0)
        colours[..., :3] *= shade.reshape((-1,) + (1,) * (colours.ndim - 1))
        tris = self.display[self.faces]
        depth = tris.mean(axis=1) @ eye
        keep = np.flatnonzero(facing > -0.02)
        keep = keep[np.argsort(depth[keep], kind="stable")]
        xy = np.stack([tris[keep] @ right, tris[keep] @ up], axis=-1)
        # rasterized: thousands of faces as one bitmap inside the PDF/SVG (text and axes stay vector)
        if colours.ndim == 3:
            # Gouraud triangles in this depth order, each with its own three corners (one colour each)
            k = len(keep)
            tri = Triangulation(xy[..., 0].ravel(), xy[..., 1].ravel(), np.arange(3 * k).reshape(k, 3))
            mesh = TriMesh(tri, rasterized=True)
            mesh.set_facecolor(colours[keep].reshape(-1, 4))  # type: ignore[arg-type]  # (N, 4) RGBA array, one per corner
            ax.add_collection(mesh, autolim=False)
        else:
            # filled without antialiasing, so neighbouring faces meet without seams and need no stroked edges
            ax.add_collection(
                PolyCollection(
                    xy,  # type: ignore[arg-type]  # the stub wants a Sequence; matplotlib takes (K, 3, 2) as is
                    facecolors=colours[keep],
                    edgecolors="none",
                    linewidths=0.0,
                    antialiased=False,
                    rasterized=True,
                )
            )
        span_x = np.abs(self.display[:, :2]).max() * 1.05
        span_z = np.abs(self.display[:, 2]).max() * 1.05
        ax.set_xlim(-span_x, span_x)
        ax.set_ylim(-span_z - span_x * np.sin(np.radians(elev_deg)), span_z + span_x * np.sin(np.radians(elev_deg)))
        ax.set_aspect("equal")
        ax.set_axis_off()

    def ends(self) -> tuple[str, str]:
        """Link-frame names of the top and bottom ends of the display's vertical (long) axis, e.g. ``+z end``."""
        up = self.rotation.T @ np.array([0.0, 0.0, 1.0])
        return f"{_direction_name(up)} end", f"{_direction_name(-up)} end"

    def render(
        self,
        density: np.ndarray,
        path: str | Path,
        title: str,
        views: int = 4,
        provenance: figures.Provenance | None = None,
    ) -> Path:
        """``views`` views around the long axis with a shared colour bar -> ``path`` (+ PDF, SVG).

        The first view names the link-frame ends of the long axis (landmarks to orient the views)."""
        vmax = _vmax([density])
        span = np.abs(self.display).max(axis=0)
        tall = float(np.clip(span[2] / max(span[0], span[1], 1e-9), 0.5, 4.0))
        with figures.style():
            fig, axes = figures.new_figure("two", min(1.75 * tall + 0.9, 6.5), ncols=views, squeeze=False)
            for i, az in enumerate(self.azimuths(views)):
                ax = axes[0, i]
                self.draw(ax, density, az, vmax)
                ax.set_title(f"seen from {self.camera(az)}")
            top, bottom = self.ends()
            axes[0, 0].text(0.02, 0.99, top, transform=axes[0, 0].transAxes, ha="left", va="top", color="0.25")
            axes[0, 0].text(0.02, 0.01, bottom, transform=axes[0, 0].transAxes, ha="left", va="bottom", color="0.25")
            _colourbar(fig, vmax, ax=axes[0, :])
            fig.suptitle(title)
            return _save(fig, path, provenance)

    @staticmethod
    def azimuths(views: int) -> list[float]:
        """View azimuths (degrees) around the long axis, starting at display +x."""
        return [360.0 * i / views for i in range(views)]

    def coloured_mesh(self, density: np.ndarray, vmax: float | None = None) -> trimesh.Trimesh:
        """The mesh (link frame, metres) with vertex colours of ``density`` on the scale 0..``vmax`` (% per cm^2;
        default: its maximum)."""
        vals = self.vertex_values(density) * PERCENT_PER_CM2
        vmax = vmax if vmax is not None else float(vals.max())
        rgba = plt.get_cmap(CMAP)(np.clip(vals / vmax, 0, 1) if vmax > 0 else np.zeros_like(vals))
        return trimesh.Trimesh(
            self.vertices, self.faces, vertex_colors=(rgba * 255).astype(np.uint8), process=False, validate=False
        )

    def write_ply(self, density: np.ndarray, path: str | Path, vmax: float | None = None) -> Path:
        """Vertex-coloured PLY (link frame, metres) of ``density``."""
        self.coloured_mesh(density, vmax).export(Path(path))
        return Path(path)


def _vmax(densities: Sequence[np.ndarray]) -> float:
    """Colour scale top: the 99.5th percentile of the densities (% per cm^2)."""
    vals = np.concatenate([np.ravel(d) for d in densities]) * PERCENT_PER_CM2
    v = float(np.percentile(vals, 99.5)) if vals.size else 0.0
    return v if v > 0 else float(vals.max(initial=0.0)) or 1.0


def _colourbar(
    fig: Figure, vmax: float, ax: Axes | np.ndarray, cmap: Any = CMAP, label: str = "contact density (% per cm$^2$)"
) -> None:
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0, vmax))
    fig.colorbar(sm, ax=ax, shrink=0.8, pad=0.02).set_label(label)


def _save(fig: Figure, path: str | Path, provenance: figures.Provenance | None) -> Path:
    """Draw the provenance banner (:func:`sphri.figures.mark`) and write the figure to ``path`` (PNG, PDF, SVG, or
    the formats of the enclosing :func:`sphri.figures.only_formats`)."""
    figures.mark(fig, provenance)
    figures.save(fig, path)
    return Path(path)


def _triangle_colourbar(fig: Figure, ax: Axes, im: AxesImage, n: int, label: str) -> None:
    """The colour bar of an n x n lower-triangle matrix: in its empty upper triangle (n >= 3), not beside it."""
    cax = ax.inset_axes((0.55, 0.82, 0.42, 0.04)) if n >= 3 else None
    cb = fig.colorbar(im, ax=ax, cax=cax, orientation="horizontal" if cax is not None else "vertical", shrink=0.8)
    cb.set_label(label)
    if cax is not None:
        cax.xaxis.set_label_position("top")


def uv_grid(surface: SurfaceMap, samples: SurfaceSamples, n_u: int = 120) -> dict:
    """Points of a (u, v) grid on the chart and their interpolation from samples.

    ``n_v`` follows the chart's aspect so that cells are square in metres.
    """
    from sphri.surface.charts import from_uv

    if not surface.has_uv:
        raise ValueError(f"surface kind {surface.kind!r} has no 2-D chart to unwrap")
    aspect = surface.metres_per_v / surface.metres_per_u if surface.metres_per_u > 0 else 1.0
    n_v = int(np.clip(round(n_u * aspect), 24, 600))
    u = (np.arange(n_u) + 0.5) / n_u
    v = (np.arange(n_v) + 0.5) / n_v
    uu, vv = np.meshgrid(u, v, indexing="ij")
    uv = np.stack([uu.ravel(), vv.ravel()], axis=1)
    pts, nrm, valid = from_uv(surface, uv, return_normal=True, return_valid=True)
    idx, w = samples.interpolation(pts, nrm)
    return {"idx": idx, "w": w, "valid": valid.reshape(n_u, n_v), "shape": (n_u, n_v)}


def draw_uv(
    ax: Axes, grid: dict, surface: SurfaceMap, density: np.ndarray, vmax: float, labels: bool = True
) -> AxesImage:
    img = np.einsum("kj,kj->k", np.asarray(density)[grid["idx"]], grid["w"]).reshape(grid["shape"]) * PERCENT_PER_CM2
    img = np.where(grid["valid"], img, np.nan)
    extent = (0.0, surface.metres_per_v * 100, 0.0, surface.metres_per_u * 100)
    im = ax.imshow(
        img, origin="lower", extent=extent, cmap=CMAP, vmin=0, vmax=vmax, aspect="equal", interpolation="nearest"
    )
    if labels:  # every chart runs u along the link and v around it (sphri.surface.charts)
        ax.set_xlabel("around the link (cm)")
        ax.set_ylabel("along the link (cm)")
    return im


def render_uv(
    surface: SurfaceMap,
    samples: SurfaceSamples,
    density: np.ndarray,
    path: str | Path,
    title: str,
    grid: dict | None = None,
    provenance: figures.Provenance | None = None,
) -> Path:
    """The unwrapped (u, v) map of ``density`` with a colour bar -> ``path`` (+ PDF, SVG)."""
    grid = grid or uv_grid(surface, samples)
    vmax = _vmax([density])
    aspect = surface.metres_per_u / max(surface.metres_per_v, 1e-9)
    with figures.style():
        fig, ax = figures.new_figure("one", float(np.clip(2.3 * aspect + 1.0, 2.0, 6.0)))
        draw_uv(ax, grid, surface, density, vmax)
        _colourbar(fig, vmax, ax=ax)
        ax.set_title(title, loc="left", wrap=True)
        return _save(fig, path, provenance)


def plot_overview(
    view: LinkView,
    densities: dict[str, np.ndarray],
    path: str | Path,
    title: str,
    views: int = 4,
    surface: SurfaceMap | None = None,
    samples: SurfaceSamples | None = None,
    grid: dict | None = None,
    provenance: figures.Provenance | None = None,
) -> Path:
    """One row per group: ``views`` views (and the (u, v) map with a chart), all on one colour scale
    (the rows are compared) with one colour bar -> ``path`` (+ PDF, SVG)."""
    names = list(densities)
    uv: tuple[dict, SurfaceMap] | None = None  # (grid, surface) of the (u, v) column
    if surface is not None and surface.has_uv and samples is not None:
        uv = (grid if grid is not None else uv_grid(surface, samples), surface)
    cols = views + (1 if uv is not None else 0)
    azims = view.azimuths(views)
    vmax = _vmax(list(densities.values()))
    with figures.style():
        fig, axes = figures.new_figure(
            "two", figures.fit_page(1.25 * len(names) + 0.7), nrows=len(names), ncols=cols, squeeze=False
        )
        for r, name in enumerate(names):
            d = densities[name]
            for c, az in enumerate(azims):
                ax = axes[r, c]
                view.draw(ax, d, az, vmax)
                if r == 0:
                    ax.set_title(f"from {view.camera(az)}")
                if c == 0:
                    ax.text(
                        -0.04, 0.5, figures.human(name), transform=ax.transAxes, rotation=90, va="center", ha="right"
                    )
            if uv is not None:
                ax = axes[r, cols - 1]
                draw_uv(ax, uv[0], uv[1], d, vmax, labels=False)
                ax.tick_params(labelsize=figures.MIN_FONT_PT)
                if r == 0:
                    ax.set_title("unwrapped (cm)")
        _colourbar(fig, vmax, ax=axes)
        fig.suptitle(title)
        return _save(fig, path, provenance)


def plot_coverage_curves(
    curves: Sequence[CoverageCurve], path: str | Path, title: str, provenance: figures.Provenance | None = None
) -> Path:
    """Share of contact frames captured vs share of area covered, one line per group -> ``path`` (+ PDF, SVG)."""
    with figures.style():
        fig, ax = figures.new_figure("one", 3.3)
        ax.plot([0, 1], [0, 1], color="0.75", lw=0.8, ls=":", label="uniform")
        for c in curves:
            if c.n_frames == 0:
                continue
            lw, colour = (2.0, "black") if c.group == "all" else (1.0, None)
            r = c.resampled(401)
            (line,) = ax.plot(
                r["area_share"],
                r["frame_share"],
                lw=lw,
                color=colour,
                label=f"{figures.human(c.group)} ({100 * c.area_at_capture:.0f} %)",
            )
            ax.plot([c.area_at_capture], [c.capture], "o", color=line.get_color(), ms=3)
        if curves:
            ax.axhline(curves[0].capture, color="0.5", lw=0.6, ls="--")
        ax.set_xlabel("share of the link's area covered\n(densest first)")
        ax.set_ylabel("share of contact frames captured")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1.01)
        ax.set_title(title, loc="left", wrap=True)
        ax.legend(title="group (area for the target)", loc="lower right")  # below the uniform diagonal: no data there
        return _save(fig, path, provenance)


def plot_swd_heatmap(
    comp: PairwiseComparison, path: str | Path, title: str, provenance: figures.Provenance | None = None
) -> Path:
    """Mean paired SWD (mm) between conditions with Holm-corrected p-values in the cells (* where <= alpha)
    -> ``path`` (+ PDF, SVG). The matrix is symmetric: drawn once, the lower triangle with the diagonal. The
    colour scale spans the off-diagonal cells; the diagonal (each condition's split-half baseline) is grey,
    its value printed."""
    m = comp.matrix("mean_between_swd_mm").to_numpy(float)
    p = comp.matrix("p_holm")
    c = comp.conditions
    n = len(c)
    off = ~np.eye(n, dtype=bool)
    upper = figures.upper_mask(n)
    vals = m[off & ~upper & np.isfinite(m)]
    lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")
    names = [figures.human(x) for x in c]
    with figures.style():
        # cells of about 0.65 in: the value and its p-value fit inside at 7 pt
        side = float(np.clip(0.65 * n + 2.4, figures.ONE_COLUMN_IN, figures.TWO_COLUMN_IN))
        fig, ax = figures.new_figure(side, figures.fit_page(0.65 * n + 2.3))
        shown = np.ma.masked_array(np.where(off, m, np.nan), mask=upper)
        im = ax.imshow(shown, cmap=cmap, vmin=lo, vmax=hi if hi > lo else lo + 1.0)
        figures.lower_triangle(ax, im, n)
        mid = 0.5 * (lo + hi)
        for i in range(n):
            for j in range(i + 1):
                val = m[i, j]
                if not np.isfinite(val):
                    continue
                text = f"{val:.1f}"
                if i != j and np.isfinite(p.iat[i, j]):
                    pv = p.iat[i, j]
                    text += f"\np={pv:.3f}" if pv >= 0.001 else "\np<.001"
                    text += " *" if pv <= comp.alpha else ""
                ax.text(
                    j,
                    i,
                    text,
                    ha="center",
                    va="center",
                    fontsize=figures.MIN_FONT_PT,
                    color="black" if i == j or val >= mid else "white",
                )
        ax.set_xticks(range(n), names, rotation=45, ha="right")
        ax.set_yticks(range(n), names)
        _triangle_colourbar(fig, ax, im, n, f"mean paired SW{comp.swd_p:g}\ndistance (mm)")
        ax.set_title(title, loc="left", wrap=True)
        ax.set_xlabel(f"Holm-corrected p (* <= {comp.alpha:g})\ngrey diagonal: split-half baseline")
        return _save(fig, path, provenance)
