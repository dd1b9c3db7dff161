"""``layout=file``: real sensor layouts read from a file and placed on a link.

Formats:

- iCub skin calibration (``.txt``, robotology/icub-main
  ``app/skinGui/conf/positions``): header lines, then ``[calibration]`` and one
  row per taxel ``x y z nx ny nz`` (metres, unit normal, in the skin part's
  link frame); all-zero rows are absent taxels. Repeated positions (the iCub
  files list a triangle's representative taxel several times) are merged.
- ``.npz`` with ``position_m (N, 3)`` and ``normal (N, 3)``.

Positions are scaled by ``scale``, moved by ``transform`` (identity, xyz+rpy
in the URDF convention, or a 4x4 matrix) and projected onto the closest point
of the link surface; the file's normals are kept (rotated). ``res`` does not
apply (the file fixes the taxels) and is ignored with a log line.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from sphri.config import Configured
from sphri.geometry.link import check_link, closest_points, face_normals
from sphri.layout.common import LayoutFileError, nn_spacing, npz_arrays, scattered_layout, voronoi_areas
from sphri.layout.schema import FileLayoutSchema
from sphri.types import Layout, Link, SurfaceMap

log = logging.getLogger(__name__)


def read_icub_positions(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Rows of an iCub ``[calibration]`` section: positions (K, 3) m and normals (K, 3).

    All-zero rows (absent taxels) are dropped; duplicates are kept (see
    :func:`dedupe`).
    """
    path = Path(path)
    rows: list[list[float]] = []
    in_cal = False
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise LayoutFileError(f"{path}: not a text file (an iCub calibration .txt, or an .npz)") from None
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith(("#", "//")):
            continue
        if s.startswith("["):
            in_cal = s.lower() == "[calibration]"
            continue
        if not in_cal:
            continue
        parts = s.split()
        if len(parts) != 6:
            raise LayoutFileError(f"{path}:{lineno}: expected 6 numbers 'x y z nx ny nz', got {len(parts)}: {s[:60]!r}")
        try:
            rows.append([float(x) for x in parts])
        except ValueError as exc:
            raise LayoutFileError(f"{path}:{lineno}: not a number in {s[:60]!r}") from exc
    if not rows:
        raise LayoutFileError(f"{path}: no '[calibration]' rows (x y z nx ny nz) found")
    a = np.asarray(rows, dtype=np.float64)
    present = np.any(a != 0.0, axis=1)
    if not present.any():
        raise LayoutFileError(f"{path}: every calibration row is zero (no taxels)")
    return a[present, :3], a[present, 3:]


def dedupe(pos: np.ndarray, nrm: np.ndarray, tol_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge positions closer than ``tol_m`` (first occurrence kept, file order)."""
    if tol_m <= 0 or len(pos) == 0:
        return pos, nrm
    key = np.round(pos / tol_m).astype(np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    first = np.sort(first)
    return pos[first], nrm[first]


def transform_matrix(values: list[float] | tuple[float, ...]) -> np.ndarray:
    """4x4 homogeneous matrix from [] (identity), xyz+rpy (URDF: R = Rz Ry Rx) or 16 numbers."""
    vals = [float(x) for x in values]
    if len(vals) == 0:
        return np.eye(4)
    if len(vals) == 16:
        m = np.asarray(vals).reshape(4, 4)
        if not np.allclose(m[3], [0, 0, 0, 1]):
            raise ValueError(f"layout.transform: last row of the 4x4 must be 0 0 0 1, got {m[3].tolist()}")
        return m
    if len(vals) == 6:
        x, y, z, r, p, yw = vals
        cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(yw), np.sin(yw)
        rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
        ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
        rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
        m = np.eye(4)
        m[:3, :3] = rz @ ry @ rx
        m[:3, 3] = [x, y, z]
        return m
    raise ValueError(f"layout.transform={vals}: must be [] , 6 numbers (xyz + rpy) or 16 (4x4 row-major)")


def read_layout_file(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Positions (K, 3) and normals (K, 3) from an iCub ``.txt`` or an ``.npz``."""
    if not str(path):
        raise ValueError("layout.path is empty: set layout.path=<sensor layout file> (iCub .txt or .npz)")
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"layout.path={str(path)!r}: no such file")
    if p.suffix == ".npz":
        pos, nrm = npz_arrays(p, "layout.path", ("position_m", "normal"))
        if pos.ndim != 2 or pos.shape[1] != 3 or nrm.shape != pos.shape or len(pos) == 0:
            raise LayoutFileError(f"{path}: position_m and normal must both be (N, 3), got {pos.shape}, {nrm.shape}")
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(nrm))):
            raise LayoutFileError(f"{path}: position_m / normal contain NaN or inf")
        return pos, nrm
    return read_icub_positions(p)


#: Taxels closer than this on the link (median nearest neighbour, metres) are a file in other units.
MIN_PITCH_M = 0.5e-3


def build_file_layout(
    link: Link,
    surface: SurfaceMap,
    path: str,
    transform: list[float] | tuple[float, ...] = (),
    scale: float = 1.0,
    dedupe_mm: float = 0.05,
    max_offset_mm: float = 10.0,
) -> Layout:
    """Taxels from ``path`` placed on ``link`` (see module docstring)."""
    pos, nrm = read_layout_file(path)
    check_link(link)
    pos = pos * scale
    pos, nrm = dedupe(pos, nrm, dedupe_mm * 1e-3)
    m = transform_matrix(transform)
    pos = pos @ m[:3, :3].T + m[:3, 3]
    nrm = nrm @ m[:3, :3].T
    cp, dist, tri = closest_points(link, pos)
    med, worst = float(np.median(dist)) * 1e3, float(dist.max()) * 1e3
    if worst > max_offset_mm:
        log.warning(
            "layout.file %s: taxels lie up to %.1f mm (median %.1f mm) from link %r's surface "
            "(> layout.max_offset_mm=%g): check layout.transform / layout.scale",
            path,
            worst,
            med,
            link.name,
            max_offset_mm,
        )
    fn = face_normals(link)[tri]
    n_norm = np.linalg.norm(nrm, axis=1, keepdims=True)
    nrm = np.where(n_norm > 0.5, nrm / np.maximum(n_norm, 1e-300), fn)
    spacing = nn_spacing(cp)
    pitch = float(np.mean(spacing)) if len(cp) > 1 else 0.0
    if len(cp) > 1 and float(np.median(spacing)) < MIN_PITCH_M:
        span = float(np.ptp(pos, axis=0).max())
        size = float(np.ptp(link.vertices, axis=0).max())
        raise LayoutFileError(
            f"{path}: the taxels lie {float(np.median(spacing)) * 1e3:.3g} mm apart on link {link.name!r} (median "
            f"nearest neighbour, less than {MIN_PITCH_M * 1e3:g} mm) with layout.scale={scale:g}: the file's taxels "
            f"span {span:.3g} m against the link's {size:.3g} m; set layout.scale to the file's units "
            f"(0.001 for mm, 0.01 for cm), or check layout.transform"
        )
    reach = 1.5 * float(np.median(spacing)) if len(cp) > 1 else None
    area = voronoi_areas(link, cp, seed=0, max_dist_m=reach)
    return scattered_layout(surface, "file", cp, nrm, area, pitch)


class FileLayout(Configured):
    """``layout=file``: a real sensor's taxels (iCub skin files, .npz) on the link."""

    VERSION = "1"

    SCHEMA = FileLayoutSchema
    path: str  # these five set from SCHEMA by Configured
    transform: list[float]
    scale: float
    dedupe_mm: float
    max_offset_mm: float

    def configured(self) -> None:
        self.transform = [float(x) for x in self.transform]

    def build(self, link: Link, surface: SurfaceMap, res: int) -> Layout:
        """Read, place and project the file's taxels; ``res`` is ignored (logged)."""
        log.info("layout=file ignores res=%s: the sensor file %s fixes the taxels", res, self.path)
        return build_file_layout(
            link, surface, self.path, self.transform, self.scale, self.dedupe_mm, self.max_offset_mm
        )
