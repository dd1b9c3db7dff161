"""Config schema of the window group (``conf/window/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import ComponentSchema, setting, store


@dataclass
class WindowSchema(ComponentSchema, group="window"):
    """Base of the window group's schemas."""


@dataclass
class OnsetWindowSchema(WindowSchema):
    """Windows of ``frames`` frames starting at each trial's first contact."""

    _target_: str = "sphri.window.onset.OnsetWindow"
    frames: int = setting(50, lo=1, hi=100_000)
    """Window length L in frames (at the dataset's frame rate); clipped or zero-padded."""
    no_contact: str = setting("drop", choices=("drop", "keep"))
    """Trials without any contact: drop them, or keep an all-zero window starting at frame 0."""
    max_memory_gib: float | None = setting(None, runtime=True, lo=0.0, lo_open=True, optional=True)
    """Refuse windows (n_windows x frames x taxels float32) larger than this (GiB) before allocating them
    (None: a quarter of the memory available when the stage starts, since the noise and filter stages each
    hold a copy of the windows)."""


store(group="window", name="onset_schema", node=OnsetWindowSchema)
