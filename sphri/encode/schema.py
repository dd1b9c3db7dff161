"""Config schemas of the encoder group (``conf/encoder/*.yaml``).

Every encoder has ``res``: taxels along the link's long axis (1..1000), which
the pipeline also passes to the layout.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from omegaconf import OmegaConf

from sphri.config import ConfigError, cross_check, require_choice, require_range, store
from sphri.layout.schema import check_res


@dataclass
class EllipseEncoderSchema:
    """The paper's encoder: contact patches as ellipses rasterized on the (u, v) grid."""

    _target_: str = "sphri.encode.ellipse.EllipseEncoder"
    NEEDS_CHART_GRID: ClassVar[bool] = True
    """Rasterizes on a grid layout (``CHART_GRID``) of a surface with a chart (``HAS_CHART``)."""
    res: int = 18
    """Taxels along the link's long axis (the paper saturates near 18 per 24 cm)."""
    binary: bool = True
    """True: uint8 0/1 readings; False: float32 covered fraction of each taxel."""
    threshold: float = 0.5
    """Binary: a taxel is on when at least this fraction of its cell is covered
    (the taxel holding a patch centre is always on)."""
    subsamples: int = 8
    """Sub-rows per taxel row for the raster (exact along v); more = finer."""

    def __post_init__(self) -> None:
        check_res(self.res)
        require_range("encoder.threshold", self.threshold, lo=0.0, hi=1.0, lo_open=True)
        require_range("encoder.subsamples", self.subsamples, lo=1, hi=64)


@dataclass
class CoverageEncoderSchema:
    """Fraction of each taxel's area covered by contact (float32), any layout."""

    _target_: str = "sphri.encode.coverage.CoverageEncoder"
    res: int = 18
    """Taxels along the link's long axis."""
    subsamples: int = 8
    """Grid layouts: sub-rows per taxel row of the chart raster."""
    samples_per_taxel: int = 32
    """Other layouts: points sampled on each taxel's disc (area fraction resolution)."""

    def __post_init__(self) -> None:
        check_res(self.res)
        require_range("encoder.subsamples", self.subsamples, lo=1, hi=64)
        require_range("encoder.samples_per_taxel", self.samples_per_taxel, lo=1, hi=1024)


@dataclass
class ProximityEncoderSchema:
    """A taxel senses a capsule surface within ``sensing_distance_m``, any layout."""

    _target_: str = "sphri.encode.proximity.ProximityEncoder"
    res: int = 18
    """Taxels along the link's long axis."""
    sensing_distance_m: float = 0.005
    """Range of the taxel (metres): active when a capsule surface is this close."""
    intensity: str = "binary"
    """binary (uint8 0/1) or depth (float32 pressure proxy, 0 at the range, 1 at depth_scale_m deep)."""
    depth_scale_m: float = 0.01
    """Penetration (metres) that reads 1.0 with intensity=depth."""

    def __post_init__(self) -> None:
        check_res(self.res)
        require_range("encoder.sensing_distance_m", self.sensing_distance_m, lo=0.0, hi=0.5)
        require_choice("encoder.intensity", self.intensity, ("binary", "depth"))
        require_range("encoder.depth_scale_m", self.depth_scale_m, lo=0.0, hi=0.5, lo_open=True)


@cross_check
def grid_encoder_needs_grid_layout(cfg) -> None:
    """An encoder that rasterizes on the chart grid refuses irregular layouts and chartless surfaces.

    The components say what they are through class attributes of their
    schemas: ``NEEDS_CHART_GRID`` (encoder), ``CHART_GRID`` (layout),
    ``HAS_CHART`` (surface); a new component declares its own.
    """

    def flag(group: str, name: str) -> bool:
        return bool(getattr(OmegaConf.get_type(cfg[group]), name, False))

    if not flag("encoder", "NEEDS_CHART_GRID"):
        return
    if not (flag("layout", "CHART_GRID") and flag("surface", "HAS_CHART")):
        name = cfg.encoder.get("_target_", "?").rsplit(".", 1)[-1].removesuffix("Encoder").lower()
        layout, surface = cfg.layout.get("_target_", "?"), cfg.surface.get("_target_", "?")
        raise ConfigError(
            f"encoder={name} rasterizes on a taxel grid: it needs layout=grid|hex on surface=cylinder|box, "
            f"got layout {layout.rsplit('.', 1)[-1]} on surface {surface.rsplit('.', 1)[-1]}; "
            "for any layout use encoder=coverage (covered area fraction) or encoder=proximity"
        )


store(group="encoder", name="ellipse_schema", node=EllipseEncoderSchema)
store(group="encoder", name="coverage_schema", node=CoverageEncoderSchema)
store(group="encoder", name="proximity_schema", node=ProximityEncoderSchema)
