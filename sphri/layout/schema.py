"""Config schemas of the layout group (``conf/layout/*.yaml``).

Every layout is built with ``res`` (taxels along the link's long axis), owned by
the encoder group (:func:`sphri.encode.schema.grid_res`) and handed to
``layout.build`` by the pipeline; ``file`` layouts ignore it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

from sphri.config import ComponentSchema, ConfigError, Range, require, setting, store
from sphri.inputs import input_path

#: Largest ``encoder.res`` (taxels along the long axis).
MAX_RES = 1000

#: The range of ``encoder.res``, declared on :attr:`sphri.encode.schema.EncoderSchema.res` (which the
#: user sets) and checked here too, where a layout is handed the value (``build(link, surface, res)``).
RES_RANGE = Range(lo=1, hi=MAX_RES, integer=True)


def check_res(res: Any, who: str = "encoder.res") -> int:
    """The one check of the resolution (:data:`RES_RANGE`); a component handed the value (``who``,
    e.g. ``layout.grid``) names itself. Raises :class:`~sphri.config.ConfigError` naming ``encoder.res``."""
    try:
        RES_RANGE.check("encoder.res", res)
    except ConfigError as exc:
        raise ConfigError(f"{exc} (read by {who})" if who != "encoder.res" else str(exc)) from None
    return int(res)


@dataclass
class LayoutSchema(ComponentSchema, group="layout"):
    """Base of the layout group's schemas."""


@dataclass
class GridLayoutSchema(LayoutSchema):
    """Regular (u, v) grid: H rows along the link, W columns around it."""

    _target_: str = "sphri.layout.grid.GridLayout"
    CHART_GRID: ClassVar[bool] = True
    """An (H, W) grid on the surface chart (what ``encoder=ellipse`` rasterizes on)."""
    aspect: float = setting(1.0, lo=0.05, hi=20.0)
    """Taxel pitch around / pitch along (1 = square taxels)."""
    seed: int = setting(0, lo=0)
    """Seed of the surface samples that measure each taxel's area."""


@dataclass
class HexLayoutSchema(GridLayoutSchema):
    """Hexagonal (triangular-lattice) grid: odd rows shifted by half a taxel; ``aspect`` stretches
    the lattice around the link (1 = equilateral)."""

    _target_: str = "sphri.layout.grid.HexLayout"


@dataclass
class RandomLayoutSchema(LayoutSchema):
    """Poisson-disk taxels on the 3-D surface, as many as the grid at this res."""

    _target_: str = "sphri.layout.poisson.RandomLayout"
    aspect: float = setting(1.0, lo=0.05, hi=20.0)
    """Aspect of the grid whose taxel count is matched."""
    seed: int = setting(0, lo=0)
    """Seed of the candidate samples (same seed -> same layout)."""
    candidates: int = setting(5, lo=2, hi=50)
    """Candidate points per final taxel for sample elimination (>= 2)."""


@dataclass
class DensityLayoutSchema(LayoutSchema):
    """Taxels placed by a contact-density map (denser where touch is frequent)."""

    _target_: str = "sphri.layout.poisson.DensityLayout"
    density_path: str = input_path("")
    """.npz with ``points_m (P, 3)`` and ``density (P,)`` (exported by the coverage analysis);
    empty: the density of this run's own contacts."""
    bandwidth_mm: float = setting(10.0, lo=0.5, hi=500.0)
    """Density from contacts: standard deviation (mm) of the coverage analysis's smoothing kernel."""
    aspect: float = setting(1.0, lo=0.05, hi=20.0)
    """Aspect of the grid whose taxel count is matched."""
    seed: int = setting(0, lo=0)
    """Seed of the candidate samples."""
    candidates: int = setting(5, lo=2, hi=50)
    """Candidate points per final taxel (>= 2)."""
    min_density_fraction: float = setting(0.05, lo=0.0, hi=1.0)
    """Floor of the density as a fraction of its mean, so untouched areas keep a few taxels."""


@dataclass
class FileLayoutSchema(LayoutSchema):
    """Real sensor layouts: taxel positions and normals read from a file."""

    _target_: str = "sphri.layout.file.FileLayout"
    path: str = input_path("")
    """iCub skin calibration .txt (``[calibration]`` rows x y z nx ny nz) or .npz
    (``position_m``, ``normal``)."""
    transform: list[float] = field(default_factory=list)
    """File frame -> link frame: [] identity, 6 numbers xyz (m) + rpy (rad, URDF), or 16 (4x4 row-major)."""
    scale: float = setting(1.0, lo=0.0, lo_open=True)
    """Scale applied to file positions before the transform (e.g. 0.001 for mm files)."""
    dedupe_mm: float = setting(0.05, lo=0.0)
    """Positions closer than this (mm, after scaling) are one taxel."""
    max_offset_mm: float = setting(10.0, lo=0.0, lo_open=True)
    """Warn when taxels lie farther than this from the link surface before projection (mm)."""

    def check(self) -> None:
        require(
            len(self.transform) in (0, 6, 16),
            self.key("transform"),
            list(self.transform),
            "must be [] (identity), 6 numbers (xyz + rpy) or 16 (a 4x4 matrix, row-major)",
        )


store(group="layout", name="grid_schema", node=GridLayoutSchema)
store(group="layout", name="hex_schema", node=HexLayoutSchema)
store(group="layout", name="random_schema", node=RandomLayoutSchema)
store(group="layout", name="density_schema", node=DensityLayoutSchema)
store(group="layout", name="file_schema", node=FileLayoutSchema)
