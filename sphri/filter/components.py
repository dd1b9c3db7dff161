"""Temporal filters: ``apply(windows) -> WindowedFrames``, per taxel along the window's frames.

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
- ``median`` (``frames`` = k, odd): the median of the last k readings; a
  binary reading stays binary.
- ``none``: unchanged.

Both are ``scipy.ndimage`` filters along the frame axis (``minimum_filter1d``,
``median_filter``) with ``mode="constant", cval=0`` (the "off" history) and
the ``origin`` that puts the k-frame window at t-k+1 .. t.

Outputs are float32 (T, L, N) like the input; shapes never change.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from sphri.config import Configured
from sphri.filter.schema import DebounceFilterSchema, MedianFilterSchema, NoFilterSchema
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

    def apply(self, windows: WindowedFrames) -> WindowedFrames:
        x = _check(windows, f"filter={self.NAME}")
        return dataclasses.replace(windows, x=causal_reduce(x, self.frames, self.HOW))


class DebounceFilter(_CausalFilter):
    """``filter=debounce``: on only after ``frames`` consecutive frames on (minimum of the last k)."""

    HOW, SCHEMA, NAME = "min", DebounceFilterSchema, "debounce"


class MedianFilter(_CausalFilter):
    """``filter=median``: causal running median of each taxel's last ``frames`` (odd) readings."""

    HOW, SCHEMA, NAME = "median", MedianFilterSchema, "median"
