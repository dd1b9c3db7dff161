"""Config schemas of the layout group (``conf/layout/*.yaml``).

Every layout is built with ``res`` (taxels along the link's long axis), ``layout.res``, declared once
on :class:`LayoutSchema` and handed to ``layout.build`` by the pipeline (:func:`layout_res`); ``file``
layouts ignore it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

from sphri.config import ComponentSchema, ConfigError, Range, require, setting, store
from sphri.inputs import input_path

#: Largest ``layout.res`` (taxels along the long axis).
MAX_RES = 1000

#: ``layout.res`` when the config says nothing (a plugin layout without a schema).
DEFAULT_RES = 18

#: The range of ``layout.res``, declared on :attr:`LayoutSchema.res` and checked again where a layout is
#: handed the value (``build(link, surface, res)``).
RES_RANGE = Range(lo=1, hi=MAX_RES, integer=True)


def check_res(res: Any, who: str = "layout.res") -> int:
    """The one check of the resolution (:data:`RES_RANGE`); a component handed the value (``who``,
    e.g. ``layout.grid``) names itself. Raises :class:`~sphri.config.ConfigError` naming ``layout.res``."""
    try:
        RES_RANGE.check("layout.res", res)
    except ConfigError as exc:
        raise ConfigError(f"{exc} (read by {who})" if who != "layout.res" else str(exc)) from None
    return int(res)


def layout_res(cfg: Any, check: bool = True) -> Any:
    """The resolution of a composed config: ``layout.res``, or :data:`DEFAULT_RES` for a plugin layout
    that declares no schema. ``check=False`` returns the value as configured, unchecked (naming a run
    that failed, perhaps on that very value)."""
    node = cfg.get("layout") if hasattr(cfg, "get") else None
    if node is None or "res" not in node:
        return DEFAULT_RES
    return check_res(node.res) if check else node.res


@dataclass
class LayoutSchema(ComponentSchema, group="layout"):
    """Base of the layout group's schemas: the resolution every layout is built at."""

    res: int = setting(DEFAULT_RES, range=RES_RANGE)
    """Taxels along the link's long axis (the paper saturates near 18 per 24 cm); a grid has this many
    rows, a random or density layout as many taxels as that grid, a file layout ignores it."""


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
