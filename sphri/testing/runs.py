"""A :class:`~sphri.types.RunMeta` for tests that log or report runs without running a job."""

from __future__ import annotations

from typing import Any

from sphri.types import RunMeta


def toy_meta(**overrides: Any) -> RunMeta:
    """The facts of a small synthetic job (3 participants, the Reachy arm, a res-18 grid); ``overrides`` replace
    fields by name (an unknown name raises TypeError, as :class:`RunMeta` does)."""
    fields: dict[str, Any] = {
        "dataset": "synthetic",
        "synthetic": True,
        "n_participants": 3,
        "n_trials": 48,
        "n_frames": 4800,
        "frame_rate_hz": 30.0,
        "repairs": {},
        "robot": "reachy",
        "region": "arm",
        "link": "arm",
        "surface": "cylinder",
        "surface_fit_residual_mm": 1.2,
        "n_windows": 48,
        "n_dropped_no_contact": 0,
        "window_frames": 50,
        "resolution": {
            "n_taxels": 342,
            "grid_shape": (18, 19),
            "pitch_u_mm": 13.4,
            "pitch_v_mm": 13.2,
            "area_per_taxel_cm2": 1.77,
            "taxels_per_24cm": 17.9,
        },
    }
    return RunMeta(**{**fields, **overrides})
