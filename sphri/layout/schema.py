"""Config schemas of the layout group (``conf/layout/*.yaml``).

Every layout is built with ``res`` (taxels along the link's long axis) taken
from ``encoder.res`` by the pipeline; ``file`` layouts ignore it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from sphri.config import require, require_range, store
from sphri.inputs import input_path

#: Largest ``encoder.res`` (taxels along the long axis): the one bound, checked by :func:`check_res`.
MAX_RES = 1000


def check_res(res: int, who: str = "encoder.res") -> int:
    """The one check of the resolution (taxels along the long axis): an integer in [1, MAX_RES].

    The user spells it ``encoder.res``; the layout is what uses it (the
    pipeline passes it to ``layout.build``). Raises :class:`~sphri.config.ConfigError`
    naming ``who``.
    """
    try:
        ok = not isinstance(res, bool) and int(res) == res and 1 <= int(res) <= MAX_RES
    except (TypeError, ValueError):
        ok = False
    require(
        ok,
        "encoder.res",
        res,
        f"must be an integer in [1, {MAX_RES}]" + ("" if who == "encoder.res" else f" (read by {who})"),
    )
    return int(res)


def _aspect(value: float) -> None:
    require_range("layout.aspect", value, lo=0.05, hi=20.0)


@dataclass
class GridLayoutSchema:
    """Regular (u, v) grid: H rows along the link, W columns around it."""

    _target_: str = "sphri.layout.grid.GridLayout"
    CHART_GRID: ClassVar[bool] = True
    """An (H, W) grid on the surface chart (what ``encoder=ellipse`` rasterizes on)."""
    aspect: float = 1.0
    """Taxel pitch around / pitch along (1 = square taxels)."""
    seed: int = 0
    """Seed of the surface samples that measure each taxel's area."""

    def __post_init__(self) -> None:
        _aspect(self.aspect)
        require_range("layout.seed", self.seed, lo=0)


@dataclass
class HexLayoutSchema(GridLayoutSchema):
    """Hexagonal (triangular-lattice) grid: odd rows shifted by half a taxel; ``aspect`` stretches
    the lattice around the link (1 = equilateral)."""

    _target_: str = "sphri.layout.grid.HexLayout"


@dataclass
class RandomLayoutSchema:
    """Poisson-disk taxels on the 3-D surface, as many as the grid at this res."""

    _target_: str = "sphri.layout.poisson.RandomLayout"
    aspect: float = 1.0
    """Aspect of the grid whose taxel count is matched."""
    seed: int = 0
    """Seed of the candidate samples (same seed -> same layout)."""
    candidates: int = 5
    """Candidate points per final taxel for sample elimination (>= 2)."""

    def __post_init__(self) -> None:
        _aspect(self.aspect)
        require_range("layout.seed", self.seed, lo=0)
        require_range("layout.candidates", self.candidates, lo=2, hi=50)


@dataclass
class DensityLayoutSchema:
    """Taxels placed by a contact-density map (denser where touch is frequent)."""

    _target_: str = "sphri.layout.poisson.DensityLayout"
    density_path: str = input_path("")
    """.npz with ``points_m (P, 3)`` and ``density (P,)`` (exported by the coverage analysis);
    empty: the density of this run's own contacts."""
    bandwidth_mm: float = 10.0
    """Density from contacts: standard deviation (mm) of the coverage analysis's smoothing kernel."""
    aspect: float = 1.0
    """Aspect of the grid whose taxel count is matched."""
    seed: int = 0
    """Seed of the candidate samples."""
    candidates: int = 5
    """Candidate points per final taxel (>= 2)."""
    min_density_fraction: float = 0.05
    """Floor of the density as a fraction of its mean, so untouched areas keep a few taxels."""

    def __post_init__(self) -> None:
        require_range("layout.bandwidth_mm", self.bandwidth_mm, lo=0.5, hi=500.0)
        _aspect(self.aspect)
        require_range("layout.seed", self.seed, lo=0)
        require_range("layout.candidates", self.candidates, lo=2, hi=50)
        require_range("layout.min_density_fraction", self.min_density_fraction, lo=0.0, hi=1.0)


@dataclass
class FileLayoutSchema:
    """Real sensor layouts: taxel positions and normals read from a file."""

    _target_: str = "sphri.layout.file.FileLayout"
    path: str = input_path("")
    """iCub skin calibration .txt (``[calibration]`` rows x y z nx ny nz) or .npz
    (``position_m``, ``normal``)."""
    transform: list[float] = field(default_factory=list)
    """File frame -> link frame: [] identity, 6 numbers xyz (m) + rpy (rad, URDF), or 16 (4x4 row-major)."""
    scale: float = 1.0
    """Scale applied to file positions before the transform (e.g. 0.001 for mm files)."""
    dedupe_mm: float = 0.05
    """Positions closer than this (mm, after scaling) are one taxel."""
    max_offset_mm: float = 10.0
    """Warn when taxels lie farther than this from the link surface before projection (mm)."""

    def __post_init__(self) -> None:
        require(
            len(self.transform) in (0, 6, 16),
            "layout.transform",
            list(self.transform),
            "must be [] (identity), 6 numbers (xyz + rpy) or 16 (a 4x4 matrix, row-major)",
        )
        require_range("layout.scale", self.scale, lo=0.0, lo_open=True)
        require_range("layout.dedupe_mm", self.dedupe_mm, lo=0.0)
        require_range("layout.max_offset_mm", self.max_offset_mm, lo=0.0, lo_open=True)


store(group="layout", name="grid_schema", node=GridLayoutSchema)
store(group="layout", name="hex_schema", node=HexLayoutSchema)
store(group="layout", name="random_schema", node=RandomLayoutSchema)
store(group="layout", name="density_schema", node=DensityLayoutSchema)
store(group="layout", name="file_schema", node=FileLayoutSchema)
