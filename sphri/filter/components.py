"""Skin-side filters: ``apply(windows) -> WindowedFrames``; temporal per taxel, or spatial per frame.

Filters are **causal**, as on a skin's own electronics: the output at frame t
reads only frames t-k+1 .. t. Before a window's first frame the filter's
history is "off" (0): a window starts at contact onset, and a filter started
there reports a touch only once it has seen enough of it (a debounce delays
onset by k-1 frames). Padded slots after a short trial are filtered like any
other (they hold noise).

- ``debounce`` (``frames`` = k): a taxel is on only if it has been on for k
  consecutive frames; for analogue readings the output is the minimum of the
  last k readings (a morphological erosion in time). Isolated one-frame
  salt-and-pepper blips vanish for k >= 2 (a false on survives only when
  the same taxel is corrupted to on in k frames in a row: probability
  ``(p * salt_vs_pepper)^k`` per taxel and frame).
- ``persistence`` (``ms``): ``debounce`` with its duration in milliseconds,
  converted with the windows' frame rate (``windows.frame_rate_hz``, the
  dataset's): k = ceil(ms x rate / 1000) frames, at least 1. The same
  reduction as ``debounce`` (the minimum of the last k readings), so one
  setting means the same time on datasets recorded at different rates.
- ``median`` (``frames`` = k, odd): the median of the last k readings; a
  binary reading stays binary.
- ``none``: unchanged.
- ``despeckle`` (``min_area_mm2``, spatial): in each frame, the on-taxels
  (reading >= ``active_threshold``) form connected groups
  (:func:`sphri.adjacency.taxel_adjacency`: 8- or 4-connected on grids,
  joined across the v seam of a wrapping link; within 1.5 x the median
  spacing on scattered layouts); a group whose area, the sum of its taxels'
  areas (``windows.geometry.area_m2``, the layout's m^2 per taxel), is below
  ``min_area_mm2`` is set to 0. What a skin's firmware does to report touches
  and not speckle: it needs no memory of earlier frames (no onset delay) and
  its unit is physical, so one setting means the same smallest touch at
  every resolution. It cannot tell a false taxel from a real touch that is
  smaller than the threshold (a fingertip that lights one large taxel); a
  false group as large as the threshold survives (rare: several adjacent
  false taxels in one frame). ``min_area_mm2=0`` returns the windows
  unchanged.

Why a filter and not a second feature set on the Random Forest: the filter
changes the readings, so every model (the Random Forest's 32 features, the
CNN-GRU) and every feature sees the same cleaned skin, as it would behind a
skin's firmware; the 32 features stay the paper's reference
(``tests/models/test_features_reference.py`` pins their values), and "with
and without" is one config key (``filter=none|despeckle``) that a sweep can
vary like any other.

The temporal filters are ``scipy.ndimage`` filters along the frame axis (``minimum_filter1d``,
``median_filter``) with ``mode="constant", cval=0`` (the "off" history) and
the ``origin`` that puts the k-frame window at t-k+1 .. t.

Outputs are float32 (T, L, N) like the input; shapes never change.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from sphri.adjacency import taxel_adjacency
from sphri.config import Configured
from sphri.filter.schema import (
    DebounceFilterSchema,
    DespeckleFilterSchema,
    MedianFilterSchema,
    NoFilterSchema,
    PersistenceFilterSchema,
)
from sphri.types import WindowedFrames


def _check(windows: WindowedFrames, who: str) -> np.ndarray:
    x = np.asarray(windows.x)
    if x.ndim != 3:
        raise ValueError(f"{who}: windows.x must be (trials, L, N), got shape {x.shape}")
    return x


def causal_reduce(x: np.ndarray, k: int, how: str) -> np.ndarray:
    """(T, L, N) -> (T, L, N) float32: ``how`` ("min" or "median") of each taxel's readings over
    frames t-k+1 .. t, with zeros before frame 0."""
    from scipy.ndimage import median_filter, minimum_filter1d

    x = np.asarray(x, dtype=np.float32)
    if k <= 1 or x.size == 0:
        return x.copy()
    origin = (k - 1) // 2 if k % 2 else k // 2 - 1  # the window [t-k+1, t] instead of centred on t
    if how == "min":
        return minimum_filter1d(x, k, axis=1, mode="constant", cval=0.0, origin=origin)
    if how == "median":
        return median_filter(x, size=(1, k, 1), mode="constant", cval=0.0, origin=(0, origin, 0))
    raise ValueError(f"causal_reduce: how={how!r} must be 'min' or 'median'")


class NoFilter(Configured):
    """``filter=none``: the windows as they are (the same object)."""

    VERSION = "1"
    SCHEMA = NoFilterSchema

    def apply(self, windows: WindowedFrames) -> WindowedFrames:
        _check(windows, "filter=none")
        return windows


class _CausalFilter(Configured):
    """A causal per-taxel reduction (``HOW``) over each taxel's last ``frames`` readings."""

    VERSION = "1"
    HOW = ""
    NAME = ""
    frames: int  # set from SCHEMA by Configured

    def apply(self, windows: WindowedFrames) -> WindowedFrames:
        x = _check(windows, f"filter={self.NAME}")
        return dataclasses.replace(windows, x=causal_reduce(x, self.frames, self.HOW))


class DebounceFilter(_CausalFilter):
    """``filter=debounce``: on only after ``frames`` consecutive frames on (minimum of the last k)."""

    HOW, SCHEMA, NAME = "min", DebounceFilterSchema, "debounce"


def persistence_frames(ms: float, frame_rate_hz: float) -> int:
    """Frames k a taxel must be on to have been on for ``ms`` milliseconds at ``frame_rate_hz``: ceil(ms x rate
    / 1000), at least 1 (a product within 1e-9 of an integer counts as that integer). ValueError for an unknown
    (NaN) or non-positive rate."""
    if not (np.isfinite(frame_rate_hz) and frame_rate_hz > 0):
        raise ValueError(
            f"filter=persistence: the windows' frame rate is {frame_rate_hz!r}; it needs the dataset's frame rate "
            "(windows built by the window stage carry it) to turn milliseconds into frames"
        )
    return max(1, int(np.ceil(ms * frame_rate_hz / 1000.0 - 1e-9)))


class PersistenceFilter(Configured):
    """``filter=persistence``: on only after ``ms`` milliseconds on (``debounce`` with k from the frame rate)."""

    VERSION = "1"
    SCHEMA = PersistenceFilterSchema
    ms: float  # set from SCHEMA by Configured

    def apply(self, windows: WindowedFrames) -> WindowedFrames:
        x = _check(windows, "filter=persistence")
        k = persistence_frames(self.ms, float(windows.frame_rate_hz))
        return dataclasses.replace(windows, x=causal_reduce(x, k, "min"))


class MedianFilter(_CausalFilter):
    """``filter=median``: causal running median of each taxel's last ``frames`` (odd) readings."""

    HOW, SCHEMA, NAME = "median", MedianFilterSchema, "median"


#: Frames x taxels handled per connected-component pass of ``despeckle`` (bounds memory: labels and weights).
_DESPECKLE_CHUNK = 1 << 22

#: Relative slack on the area comparison, so that a group of k taxels whose areas sum to the threshold up to
#: floating-point rounding counts as reaching it.
_AREA_RTOL = 1e-9


def taxel_areas_m2(windows: WindowedFrames, who: str) -> np.ndarray:
    """(N,) float64 taxel areas (m^2) from ``windows.geometry.area_m2``; ``ValueError`` naming the field if unusable."""
    geom = windows.geometry
    n = int(np.asarray(windows.x).shape[2])
    if geom.area_m2 is None:
        raise ValueError(
            f"{who}: windows.geometry.area_m2 is None; a spatial filter needs each taxel's area "
            "(the pipeline's geometries carry the layout's; build TaxelGeometry with area_m2=...)"
        )
    area = np.asarray(geom.area_m2, dtype=np.float64)
    if area.shape != (n,):
        raise ValueError(f"{who}: windows.geometry.area_m2 has shape {area.shape}, the windows have {n} taxels")
    if not np.all(np.isfinite(area)) or np.any(area < 0):
        raise ValueError(f"{who}: windows.geometry.area_m2 holds negative, NaN or infinite areas")
    return area


class DespeckleFilter(Configured):
    """``filter=despeckle``: clear each frame's connected groups of on-taxels smaller than ``min_area_mm2``."""

    VERSION = "1"
    SCHEMA = DespeckleFilterSchema
    min_area_mm2: float  # these three set from SCHEMA by Configured
    diagonal: bool
    active_threshold: float

    def apply(self, windows: WindowedFrames) -> WindowedFrames:
        who = "filter=despeckle"
        x = _check(windows, who)
        if self.min_area_mm2 <= 0:
            return windows
        area = taxel_areas_m2(windows, who)
        adjacency = taxel_adjacency(windows.geometry, diagonal=bool(self.diagonal))
        min_area_m2 = float(self.min_area_mm2) * 1e-6 * (1.0 - _AREA_RTOL)
        t, length, n = x.shape
        out = np.array(x, dtype=np.float32)  # a copy: the input stays as it was
        step = max(1, _DESPECKLE_CHUNK // max(1, length * n))
        for i in range(0, t, step):
            block = out[i : i + step].reshape(-1, n)
            active = block >= self.active_threshold
            small = active & (adjacency.component_weight(active, area) < min_area_m2)
            block[small] = 0.0
        return dataclasses.replace(windows, x=out)
