"""Config schemas of the filter group (``conf/filter/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import require, require_range, store


@dataclass
class NoFilterSchema:
    """No filter: the model sees the noisy readings as they are (the reference study)."""

    _target_: str = "sphri.filter.components.NoFilter"


@dataclass
class DebounceFilterSchema:
    """Debounce: a taxel reads on only after it has been on for ``frames`` consecutive frames."""

    _target_: str = "sphri.filter.components.DebounceFilter"
    frames: int = 2
    """Consecutive frames (k) a taxel must be on; output = minimum of its last k readings (1 = no filter)."""

    def __post_init__(self) -> None:
        require_range("filter.frames", self.frames, lo=1, hi=1000)


@dataclass
class MedianFilterSchema:
    """Causal running median of each taxel's last ``frames`` readings."""

    _target_: str = "sphri.filter.components.MedianFilter"
    frames: int = 3
    """Readings (k, odd so that a binary reading stays binary) in the median; 1 = no filter."""

    def __post_init__(self) -> None:
        require_range("filter.frames", self.frames, lo=1, hi=1000)
        require(self.frames % 2 == 1, "filter.frames", self.frames,
                "must be odd for filter=median (an even window has no middle reading; use filter=debounce)")


store(group="filter", name="none_schema", node=NoFilterSchema)
store(group="filter", name="debounce_schema", node=DebounceFilterSchema)
store(group="filter", name="median_schema", node=MedianFilterSchema)
