"""Config schema of the window group (``conf/window/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import require_choice, require_range, runtime_setting, store


@dataclass
class OnsetWindowSchema:
    """Windows of ``frames`` frames starting at each trial's first contact."""

    _target_: str = "sphri.window.onset.OnsetWindow"
    frames: int = 50
    """Window length L in frames (at the dataset's frame rate); clipped or zero-padded."""
    no_contact: str = "drop"
    """Trials without any contact: drop them, or keep an all-zero window starting at frame 0."""
    max_memory_gib: float | None = runtime_setting(None)
    """Refuse windows (n_windows x frames x taxels float32) larger than this (GiB) before allocating them
    (None: a quarter of the memory available when the stage starts, since the noise and filter stages each
    hold a copy of the windows)."""

    def __post_init__(self) -> None:
        require_range("window.frames", self.frames, lo=1, hi=100_000)
        if self.max_memory_gib is not None:
            require_range("window.max_memory_gib", self.max_memory_gib, lo=0.0, lo_open=True)
        require_choice("window.no_contact", self.no_contact, ("drop", "keep"))


store(group="window", name="onset_schema", node=OnsetWindowSchema)
