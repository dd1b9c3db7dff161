"""Counter-based random numbers: a pure function of (seed, trial, frame, taxel, stream).

SplitMix64 finalizers chained over the key, so a reading's noise never
depends on which other frames are present or in what order they come.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_S40 = np.uint64(40)
_INV53 = 1.0 / 9007199254740992.0
_INV24 = np.float32(1.0 / 16777216.0)


@njit(cache=True, inline="always")
def mix64(z):  # pragma: no cover - numba
    """SplitMix64 finalizer of a uint64."""
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@njit(cache=True, inline="always")
def frame_key(seed, stream, trial, frame):  # pragma: no cover - numba
    """uint64 key of one (seed, stream, trial, frame)."""
    k = mix64(np.uint64(seed) * _GOLDEN + np.uint64(stream))
    k = mix64(k ^ np.uint64(trial))
    return mix64(k ^ (np.uint64(frame) * _GOLDEN))


@njit(cache=True, inline="always")
def uniform(key, n):  # pragma: no cover - numba
    """Uniform float in [0, 1) for element ``n`` under ``key``."""
    return float(mix64(key + np.uint64(n + 1) * _GOLDEN) >> _S11) * _INV53


@njit(cache=True, inline="always")
def uniform24(key, n):  # pragma: no cover - numba
    """float32 uniform in [0, 1 - 2^-24] (24 random bits) for element ``n`` under ``key``."""
    return np.float32(mix64(key + np.uint64(n + 1) * _GOLDEN) >> _S40) * _INV24
