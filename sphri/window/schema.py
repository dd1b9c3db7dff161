"""Config schema of the window group (``conf/window/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import require_choice, require_range, store


@dataclass
class OnsetWindowSchema:
    """Windows of ``frames`` frames starting at each trial's first contact."""

    _target_: str = "sphri.window.onset.OnsetWindow"
    frames: int = 50
    """Window length L in frames (at the dataset's frame rate); clipped or zero-padded."""
    no_contact: str = "drop"
    """Trials without any contact: drop them, or keep an all-zero window starting at frame 0."""

    def __post_init__(self) -> None:
        require_range("window.frames", self.frames, lo=1, hi=100_000)
        require_choice("window.no_contact", self.no_contact, ("drop", "keep"))


store(group="window", name="onset_schema", node=OnsetWindowSchema)
