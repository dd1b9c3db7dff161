"""Config schemas of the filter group (``conf/filter/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import ComponentSchema, require, setting, store


@dataclass
class FilterSchema(ComponentSchema, group="filter"):
    """Base of the filter group's schemas."""


@dataclass
class NoFilterSchema(FilterSchema):
    """No filter: the model sees the noisy readings as they are (the reference study)."""

    _target_: str = "sphri.filter.components.NoFilter"


@dataclass
class DebounceFilterSchema(FilterSchema):
    """Debounce: a taxel reads on only after it has been on for ``frames`` consecutive frames."""

    _target_: str = "sphri.filter.components.DebounceFilter"
    frames: int = setting(2, lo=1, hi=1000)
    """Consecutive frames (k) a taxel must be on; output = minimum of its last k readings (1 = no filter)."""


@dataclass
class PersistenceFilterSchema(FilterSchema):
    """Persistence: a taxel reads on only after it has been on for ``ms`` milliseconds of consecutive frames
    (``debounce`` with its time in ms: k = ceil(ms x frame rate / 1000) frames at the dataset's frame rate)."""

    _target_: str = "sphri.filter.components.PersistenceFilter"
    ms: float = setting(50.0, lo=0.0, hi=10000.0)
    """How long (ms) a taxel must read on before it is reported on; at 30 Hz, 50 ms is 2 frames and 100 ms is 3
    (0 = no filter). The onset of a touch is delayed by the same k - 1 frames."""


@dataclass
class MedianFilterSchema(FilterSchema):
    """Causal running median of each taxel's last ``frames`` readings."""

    _target_: str = "sphri.filter.components.MedianFilter"
    frames: int = setting(3, lo=1, hi=1000)
    """Readings (k, odd so that a binary reading stays binary) in the median; 1 = no filter."""

    def check(self) -> None:
        require(
            self.frames % 2 == 1,
            self.key("frames"),
            self.frames,
            "must be odd for filter=median (an even window has no middle reading; use filter=debounce)",
        )


@dataclass
class DespeckleFilterSchema(FilterSchema):
    """Spatial despeckle: per frame, groups of touched neighbouring taxels smaller than ``min_area_mm2`` are cleared."""

    _target_: str = "sphri.filter.components.DespeckleFilter"
    min_area_mm2: float = setting(100.0, lo=0.0, hi=1.0e6)
    """Smallest touch area kept (mm^2): a connected group of on-taxels whose summed taxel area is below it is
    set to off in that frame (0 = no filter). Set it below the smallest touch that must be seen: the default,
    100 mm^2 (1 cm^2), clears the largest patch of 11-13 % of poke and tap contact frames on the built-in
    study (res 50, no noise; 80-84 % at 200 mm^2). A lone on-taxel is cleared only where that taxel is smaller
    than it; the reference arm's taxel areas vary with the hull: under 100 mm^2 are none of them up to res 18,
    41 % at res 24, 97 % at res 36; under 200 mm^2 none up to res 12, 73 % at res 18, 99 % at res 26."""
    diagonal: bool = True
    """Grids: taxels sharing a corner are neighbours too (8-connected, as the Random Forest's largest-contact
    feature); false = 4-connected. Scattered layouts: neighbours within 1.5 x the median spacing either way."""
    active_threshold: float = setting(0.5, lo=0.0, hi=1.0, lo_open=True)
    """Readings at or above it count as on (the Random Forest's threshold); readings below are left as they are."""


store(group="filter", name="none_schema", node=NoFilterSchema)
store(group="filter", name="debounce_schema", node=DebounceFilterSchema)
store(group="filter", name="median_schema", node=MedianFilterSchema)
store(group="filter", name="persistence_schema", node=PersistenceFilterSchema)
store(group="filter", name="despeckle_schema", node=DespeckleFilterSchema)
