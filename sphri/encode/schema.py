"""Config schemas of the encoder group (``conf/encoder/*.yaml``).

The resolution the encoders read through the layout is ``layout.res``
(:class:`sphri.layout.schema.LayoutSchema`); ``encoder.res`` is read as ``layout.res`` for one release
(:func:`sphri.config.normalize_overrides`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from omegaconf import OmegaConf

from sphri.config import ComponentSchema, ConfigError, cross_check, setting, store


@dataclass
class EncoderSchema(ComponentSchema, group="encoder"):
    """Base of the encoder group's schemas."""


@dataclass
class EllipseEncoderSchema(EncoderSchema):
    """The paper's encoder: contact patches as ellipses rasterized on the (u, v) grid."""

    _target_: str = "sphri.encode.ellipse.EllipseEncoder"
    NEEDS_CHART_GRID: ClassVar[bool] = True
    """Rasterizes on a grid layout (``CHART_GRID``) of a surface with a chart (``HAS_CHART``)."""
    binary: bool = True
    """True: uint8 0/1 readings; False: float32 covered fraction of each taxel."""
    threshold: float = setting(0.5, lo=0.0, hi=1.0, lo_open=True)
    """Binary: a taxel is on when at least this fraction of its cell is covered
    (the taxel holding a patch centre is always on)."""
    subsamples: int = setting(8, lo=1, hi=64)
    """Sub-rows per taxel row for the raster (exact along v); more = finer."""


@dataclass
class CoverageEncoderSchema(EncoderSchema):
    """Fraction of each taxel's area covered by contact (float32), any layout."""

    _target_: str = "sphri.encode.coverage.CoverageEncoder"
    subsamples: int = setting(8, lo=1, hi=64)
    """Grid layouts: sub-rows per taxel row of the chart raster."""
    samples_per_taxel: int = setting(32, lo=1, hi=1024)
    """Other layouts: points sampled on each taxel's disc (area fraction resolution)."""


@dataclass
class ProximityEncoderSchema(EncoderSchema):
    """A taxel senses a capsule surface within ``sensing_distance_m``, any layout."""

    _target_: str = "sphri.encode.proximity.ProximityEncoder"
    sensing_distance_m: float = setting(0.005, lo=0.0, hi=0.5)
    """Range of the taxel (metres): active when a capsule surface is this close."""
    intensity: str = setting("binary", choices=("binary", "depth"))
    """binary (uint8 0/1) or depth (float32 pressure proxy, 0 at the range, 1 at depth_scale_m deep)."""
    depth_scale_m: float = setting(0.01, lo=0.0, hi=0.5, lo_open=True)
    """Penetration (metres) that reads 1.0 with intensity=depth."""


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
