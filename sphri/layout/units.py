"""A layout's resolution in physical units, for summaries and MLflow.

:func:`describe` reports pitch along (u, the link's long axis) and around
(v) in mm, area per taxel in cm^2, taxels per cm and per 24 cm (the paper's
arm length), and the counts. Regular grids use their chart pitch; irregular
layouts use the mean nearest-neighbour spacing in both directions. To compare
layouts of different kinds at the same density, ``equivalent_pitch_mm`` is the
side of a square taxel of the mean area, and ``nn_spacing_mm`` the mean
nearest-neighbour distance, for every layout.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sphri.layout.common import long_axis_length_m, nn_spacing
from sphri.types import Layout, SurfaceMap


def _length_mm(surface: SurfaceMap) -> float:
    try:
        return long_axis_length_m(surface) * 1e3
    except ValueError:
        return 0.0


def describe(layout: Layout, surface: SurfaceMap) -> dict[str, Any]:
    """Physical resolution of ``layout`` on ``surface``.

    Numbers, plus the strings ``layout_kind`` and ``surface_kind``.
    ``grid_h``/``grid_w`` are 0 for irregular layouts; ``n_taxels_on_surface``
    counts taxels with area (box nets have void cells).
    """
    pu = float(layout.pitch_u_m) * 1e3
    pv = float(layout.pitch_v_m) * 1e3
    area = np.asarray(layout.area_m2, dtype=np.float64)
    real = area > 0
    h, w = layout.grid_shape if layout.grid_shape is not None else (0, 0)
    return {
        "layout_kind": layout.kind,
        "surface_kind": surface.kind,
        "n_taxels": int(layout.n_taxels),
        "n_taxels_on_surface": int(real.sum()),
        "grid_h": int(h),
        "grid_w": int(w),
        "pitch_u_mm": pu,
        "pitch_v_mm": pv,
        "area_per_taxel_cm2": float(area[real].mean() * 1e4) if real.any() else 0.0,
        "skin_area_cm2": float(area.sum() * 1e4),
        "taxels_per_cm_u": 10.0 / pu if pu > 0 else 0.0,
        "taxels_per_cm_v": 10.0 / pv if pv > 0 else 0.0,
        "taxels_per_24cm": 240.0 / pu if pu > 0 else 0.0,
        "equivalent_pitch_mm": float(np.sqrt(area[real].mean()) * 1e3) if real.any() else 0.0,
        "nn_spacing_mm": float(nn_spacing(np.asarray(layout.position_m)[real]).mean() * 1e3) if real.sum() > 1 else 0.0,
        "link_length_mm": _length_mm(surface),
        "circumference_mm": float(surface.metres_per_v) * 1e3,
        "fit_residual_mm": float(surface.fit_residual_m) * 1e3,
    }
