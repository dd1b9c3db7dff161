"""Noise components: ``apply(frames, frame_index, trial_key, seed) -> Frames``.

Every random draw is a pure function of (seed, trial_key, frame, taxel)
(:mod:`sphri.noise.hashing`), so results repeat exactly and a frame's noise
does not depend on which other frames are encoded. Inputs are never mutated.

In the chain, noise is applied to the windows as the model sees them
(:func:`apply_to_windows`): every slot of every window, the zero-padded slots
after a short trial included, with ``frame`` = the slot's position in the
window (0 .. L-1), as in the reference study (clip or pad to 50 frames from
onset, then add noise). Noise applied before padding would leave the padded
slots clean, and their count would tell the model the trial's length.

What each kind stands for, with N taxels per frame:

- ``salt_pepper``: independent per-taxel read errors (electrical noise,
  threshold chatter), ``p`` = probability per taxel and frame that a reading
  is corrupted. ``replace`` draws a random 0/1 so a corruption changes the
  reading with probability 1/2 (``salt_vs_pepper`` of the replacements are 1):
  an untouched taxel reads a false "on" with probability ``p * salt_vs_pepper``
  per frame, so an untouched skin shows on average ``p * salt_vs_pepper * N``
  false taxels per frame (0.01 N at the paper's p = 0.02). ``flip`` inverts
  every corrupted reading: ``p * N`` false taxels per untouched frame.
  Standard definition (scikit-image ``random_noise(mode="s&p")``); dtype kept.
- ``gaussian``: additive read noise on analogue readings, ``sigma`` in reading
  units (1 = full scale), clipped to [0, 1], float32. A binary threshold at
  0.5 would see ``N * P(|N(0, sigma^2)| > 0.5) / 2`` false taxels per untouched
  frame (about 0 at sigma = 0.05; 0.023 N at sigma = 0.25).
- ``dead_taxels``: broken taxels, ``fraction`` of the N (round(fraction * N)
  of them, chosen from ``seed`` alone: the same sensor in every trial) always
  read ``value`` (0 = silent, 1 = stuck on). Stuck-on taxels are
  ``round(fraction * N)`` false taxels in every frame; silent ones add none.
  The dtype is kept.
- ``crosstalk``: electrical or mechanical coupling between neighbours:
  ``y = clip(x + alpha * sum of neighbours' x, 0, 1)`` float32, ``alpha`` =
  fraction of a reading that appears on each neighbour; neighbours are
  :func:`sphri.adjacency.taxel_adjacency`'s: on grids the 4 cells sharing an
  edge (v wraps when the chart does), elsewhere the taxels within 1.5 x the
  median spacing (needs the frames' geometry). It spreads touches and
  adds nothing to an untouched frame (0 false taxels, at any N).
- ``threshold``: a thresholded analogue skin, fed the coverage fraction of
  each taxel (``encoder=coverage``). The signal is the covered area in mm^2
  (fraction x the taxel's area, ``geometry.area_m2``), plus ``crosstalk`` x
  each neighbour's signal (the neighbours of ``crosstalk``), plus white read
  noise N(0, sigma_mm2^2) per taxel and frame, plus a baseline drift: a
  stationary AR(1) per taxel and trial, standard deviation
  ``drift_sigma_mm2``, correlation exp(-dt / drift_tau_ms) between frames dt
  apart (the window's frame rate). The reading is 1 where the sum exceeds
  ``threshold_mm2``, else 0 (float32). Per frame an untouched taxel reads on
  with probability ``Q(threshold / sqrt(sigma^2 + drift_sigma^2))``
  (:func:`threshold_false_on_rate`), the same at every taxel size; a touched
  taxel with covered area a reads off with probability
  ``1 - Q((threshold - a) / sqrt(...))`` (:func:`threshold_false_off_rate`),
  so small taxels, with less covered area per contact, read off more often.
- ``none``: unchanged.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Protocol

import numpy as np
from numba import njit, prange

from sphri.adjacency import grid_adjacency, taxel_adjacency
from sphri.config import Configured
from sphri.noise.hashing import frame_key, uniform, uniform24
from sphri.noise.schema import (
    CrosstalkNoiseSchema,
    DeadTaxelsNoiseSchema,
    GaussianNoiseSchema,
    NoNoiseSchema,
    SaltPepperNoiseSchema,
    ThresholdNoiseSchema,
)
from sphri.types import Frames, SkinFrames, WindowedFrames

log = logging.getLogger(__name__)

#: Stream ids: different noise kinds draw independent numbers for the same key.
STREAM_SALT_PEPPER = 1
STREAM_GAUSSIAN = 2
STREAM_THRESHOLD_READ = 3
STREAM_THRESHOLD_DRIFT = 4


def _check(frames: Frames, frame_index: np.ndarray, trial_key: np.ndarray, seed: int, who: str):
    v = np.asarray(frames.values)
    if v.ndim != 2:
        raise ValueError(f"{who}: frames.values must be (M, N), got shape {v.shape}")
    fi = np.asarray(frame_index)
    tk = np.asarray(trial_key)
    for name, a in (("frame_index", fi), ("trial_key", tk)):
        if a.shape != (v.shape[0],):
            raise ValueError(f"{who}: {name} must be ({v.shape[0]},) like frames.values rows, got {a.shape}")
        if a.size and not np.issubdtype(a.dtype, np.integer):
            raise ValueError(f"{who}: {name} must hold integers, got dtype {a.dtype}")
    if fi.size and fi.min() < 0:
        raise ValueError(f"{who}: frame_index must be >= 0")
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"{who}: seed={seed!r} must be an integer >= 0")
    return v, fi.astype(np.int64).view(np.uint64), tk.astype(np.int64).view(np.uint64), int(seed)


def _like(frames: Frames, values: np.ndarray) -> Frames:
    """New Frames of the same kind (geometry kept) holding ``values``."""
    geom = getattr(frames, "geometry", None)
    if geom is not None or isinstance(frames, SkinFrames):
        return SkinFrames(values=values, grid_shape=frames.grid_shape, geometry=geom)
    return Frames(values=values, grid_shape=frames.grid_shape)


@njit(cache=True, parallel=True)
def _salt_pepper(values, out, fi, tk, seed, p, svp, flip):  # pragma: no cover - numba
    m, n = values.shape
    for i in prange(m):
        key = frame_key(seed, STREAM_SALT_PEPPER, tk[i], fi[i])
        for j in range(n):
            u = uniform(key, j)
            if u < p:
                if flip:
                    out[i, j] = 1 - values[i, j]
                else:
                    out[i, j] = 1 if u < p * svp else 0
            else:
                out[i, j] = values[i, j]


@njit(cache=True, parallel=True, fastmath=True)
def _gaussian(values, out, fi, tk, seed, sigma):  # pragma: no cover - numba
    m, n = values.shape
    one = np.float32(1.0)
    zero = np.float32(0.0)
    two_pi = np.float32(2.0 * np.pi)
    for i in prange(m):
        key = frame_key(seed, STREAM_GAUSSIAN, tk[i], fi[i])
        for j in range(0, n, 2):  # Box-Muller in float32: one pair of uniforms -> two normals
            u1 = uniform24(key, j)
            u2 = uniform24(key, j + 1)
            r = sigma * np.sqrt(np.float32(-2.0) * np.log(one - u1))
            a = two_pi * u2
            out[i, j] = min(max(np.float32(values[i, j]) + r * np.cos(a), zero), one)
            if j + 1 < n:
                out[i, j + 1] = min(max(np.float32(values[i, j + 1]) + r * np.sin(a), zero), one)


@njit(cache=True, parallel=True)
def _crosstalk(values, out, nb, alpha):  # pragma: no cover - numba
    m, n = values.shape
    for i in prange(m):
        for t in range(n):
            acc = np.float32(values[i, t])
            for c in range(nb.shape[1]):
                j = nb[t, c]
                if j >= 0:
                    acc += alpha * np.float32(values[i, j])
            out[i, t] = min(max(acc, np.float32(0.0)), np.float32(1.0))


class SaltPepperNoise(Configured):
    """``noise=salt_pepper``: independent read errors, each reading corrupted with probability ``p``
    per taxel and frame (see the module: ``p * salt_vs_pepper * N`` false taxels per untouched frame
    in replace mode, ``p * N`` in flip mode)."""

    VERSION = "2"

    SCHEMA = SaltPepperNoiseSchema
    p: float  # these three set from SCHEMA by Configured
    mode: str
    salt_vs_pepper: float

    def apply(self, frames: Frames, frame_index: np.ndarray, trial_key: np.ndarray, seed: int) -> Frames:
        """Noisy copy of ``frames`` (M, N), same dtype."""
        v, fi, tk, seed = _check(frames, frame_index, trial_key, seed, "noise=salt_pepper")
        if self.p == 0.0:  # nothing is corrupted: the kernel would copy every reading (seconds at fine grids)
            return _like(frames, v.copy())
        out = np.empty_like(v)
        if v.size:
            _salt_pepper(
                v, out, fi, tk, np.uint64(seed), float(self.p), float(self.salt_vs_pepper), self.mode == "flip"
            )
        return _like(frames, out)


class GaussianNoise(Configured):
    """``noise=gaussian``: analogue read noise, additive N(0, sigma^2) with ``sigma`` in reading units
    (1 = full scale), clipped to [0, 1], float32."""

    VERSION = "2"

    SCHEMA = GaussianNoiseSchema
    sigma: float  # set from SCHEMA by Configured

    def apply(self, frames: Frames, frame_index: np.ndarray, trial_key: np.ndarray, seed: int) -> Frames:
        """Noisy float32 copy of ``frames``."""
        v, fi, tk, seed = _check(frames, frame_index, trial_key, seed, "noise=gaussian")
        out = np.empty(v.shape, dtype=np.float32)
        if v.size:
            _gaussian(v, out, fi, tk, np.uint64(seed), np.float32(self.sigma))
        return _like(frames, out)


def dead_taxel_index(n_taxels: int, fraction: float, seed: int) -> np.ndarray:
    """Sorted indices of the round(fraction * N) dead taxels (depends on seed and N only)."""
    k = int(round(fraction * n_taxels))
    rng = np.random.default_rng([int(seed), 0xDEAD])
    return np.sort(rng.permutation(n_taxels)[:k])


class DeadTaxelsNoise(Configured):
    """``noise=dead_taxels``: broken taxels: a fixed ``fraction`` of the N taxels (the same in every
    trial) always reads ``value`` (0 = silent, 1 = stuck on)."""

    VERSION = "2"

    SCHEMA = DeadTaxelsNoiseSchema
    fraction: float  # these two set from SCHEMA by Configured
    value: float

    def apply(self, frames: Frames, frame_index: np.ndarray, trial_key: np.ndarray, seed: int) -> Frames:
        """Copy of ``frames`` with the dead taxels' columns set to ``value``."""
        v, _, _, seed = _check(frames, frame_index, trial_key, seed, "noise=dead_taxels")
        dead = dead_taxel_index(v.shape[1], self.fraction, seed)
        out = v.copy()
        val = self.value
        if np.issubdtype(out.dtype, np.integer):
            val = int(round(val))
        out[:, dead] = val
        return _like(frames, out)


def neighbour_lists(frames: Frames) -> np.ndarray:
    """(N, K) int64 neighbour taxels (-1 = none) for crosstalk: :func:`sphri.adjacency.taxel_adjacency`
    with taxels sharing an edge on grids."""
    geom = getattr(frames, "geometry", None)
    if geom is None:
        if frames.grid_shape is None:
            raise ValueError(
                "noise=crosstalk on a non-grid layout needs taxel positions: pass the encoder's "
                "SkinFrames (frames.geometry) rather than bare Frames"
            )
        log.info("noise=crosstalk: frames carry no geometry; grid v treated as not wrapping")
        return grid_adjacency(frames.grid_shape, wrap_v=False, diagonal=False).table()
    return taxel_adjacency(geom, diagonal=False).table()


class CrosstalkNoise(Configured):
    """``noise=crosstalk``: neighbour coupling: ``alpha`` (a fraction) of each reading appears on
    each neighbouring taxel (float32); adds nothing to an untouched frame."""

    VERSION = "3"

    SCHEMA = CrosstalkNoiseSchema
    alpha: float  # set from SCHEMA by Configured

    def apply(self, frames: Frames, frame_index: np.ndarray, trial_key: np.ndarray, seed: int) -> Frames:
        """``clip(x + alpha * sum over neighbours, 0, 1)`` as float32 (deterministic)."""
        v, _, _, _ = _check(frames, frame_index, trial_key, seed, "noise=crosstalk")
        nb = neighbour_lists(frames)
        out = np.empty(v.shape, dtype=np.float32)
        if v.size:
            _crosstalk(v, out, np.ascontiguousarray(nb), np.float32(self.alpha))
        return _like(frames, out)


@njit(cache=True, parallel=True)
def _normals(m_out, fi, tk, seed, stream, scale):  # pragma: no cover - numba
    """m_out[i, j] += scale * N(0, 1) drawn from (seed, stream, trial, frame, taxel)."""
    m, n = m_out.shape
    for i in prange(m):
        key = frame_key(seed, stream, tk[i], fi[i])
        for j in range(n):
            u1 = uniform(key, 2 * j)
            u2 = uniform(key, 2 * j + 1)
            m_out[i, j] += scale * np.sqrt(-2.0 * np.log(1.0 - u1)) * np.cos(2.0 * np.pi * u2)


@njit(cache=True, parallel=True)
def _drift(m_out, order, starts, fi, tk, seed, stream, sigma, rho):  # pragma: no cover - numba
    """Adds a stationary AR(1) (sd ``sigma``, lag-one correlation ``rho`` per frame) per trial and taxel.

    ``order`` sorts the rows by (trial, frame); ``starts`` bounds each trial's block. The recursion runs over
    every frame 0 .. the block's last, so a frame's drift does not depend on which other frames are present.
    """
    n = m_out.shape[1]
    innov = np.sqrt(1.0 - rho * rho)
    for b in prange(starts.shape[0] - 1):
        lo, hi = starts[b], starts[b + 1]
        trial = tk[order[lo]]
        for j in range(n):
            d = 0.0
            f = 0
            for r in range(lo, hi):
                row = order[r]
                target = np.int64(fi[row])
                while f <= target:
                    key = frame_key(seed, stream, trial, np.uint64(f))
                    u1 = uniform(key, 2 * j)
                    u2 = uniform(key, 2 * j + 1)
                    e = np.sqrt(-2.0 * np.log(1.0 - u1)) * np.cos(2.0 * np.pi * u2)
                    d = sigma * e if f == 0 else rho * d + innov * sigma * e
                    f += 1
                m_out[row, j] += d


def _normal_sf(z: float) -> float:
    from scipy.special import ndtr

    return float(ndtr(-z))


def threshold_false_on_rate(sigma_mm2: float, threshold_mm2: float, drift_sigma_mm2: float = 0.0) -> float:
    """Probability per frame that an untouched taxel reads on under ``noise=threshold``:
    ``P(N(0, sigma^2 + drift_sigma^2) > threshold)`` (0 without noise)."""
    s = float(np.hypot(sigma_mm2, drift_sigma_mm2))
    if s == 0.0:
        return 0.0
    return _normal_sf(threshold_mm2 / s)


def threshold_false_off_rate(
    covered_mm2: float, sigma_mm2: float, threshold_mm2: float, drift_sigma_mm2: float = 0.0
) -> float:
    """Probability per frame that a taxel with ``covered_mm2`` of contact reads off under ``noise=threshold``
    (no crosstalk): ``P(covered + N(0, sigma^2 + drift_sigma^2) <= threshold)``."""
    s = float(np.hypot(sigma_mm2, drift_sigma_mm2))
    if s == 0.0:
        return float(covered_mm2 <= threshold_mm2)
    return 1.0 - _normal_sf((threshold_mm2 - covered_mm2) / s)


class ThresholdNoise(Configured):
    """``noise=threshold``: a thresholded analogue skin: covered area (mm^2, from ``encoder=coverage``'s
    fractions and each taxel's area) + crosstalk + white read noise + an AR(1) baseline drift, read on above
    ``threshold_mm2`` (see the module and :func:`threshold_false_on_rate`)."""

    VERSION = "1"

    SCHEMA = ThresholdNoiseSchema
    sigma_mm2: float  # these five set from SCHEMA by Configured
    threshold_mm2: float
    crosstalk: float
    drift_sigma_mm2: float
    drift_tau_ms: float

    #: :func:`apply_to_windows` passes the windows' frame rate (the drift's time step).
    USES_FRAME_RATE = True

    def apply(
        self,
        frames: Frames,
        frame_index: np.ndarray,
        trial_key: np.ndarray,
        seed: int,
        frame_rate_hz: float | None = None,
    ) -> Frames:
        """Binary float32 readings (M, N) from coverage fractions ``frames`` in [0, 1]."""
        v, fi, tk, seed = _check(frames, frame_index, trial_key, seed, "noise=threshold")
        geom = getattr(frames, "geometry", None)
        area = None if geom is None else geom.area_m2
        if area is None:
            raise ValueError(
                "noise=threshold needs each taxel's area: pass the encoder's SkinFrames whose geometry has area_m2"
            )
        area_mm2 = np.asarray(area, dtype=np.float64) * 1e6
        if area_mm2.shape != (v.shape[1],):
            raise ValueError(
                f"noise=threshold: geometry.area_m2 has shape {area_mm2.shape}, frames have {v.shape[1]} taxels"
            )
        x = np.asarray(v, dtype=np.float64)
        if x.size and (x.min() < 0.0 or x.max() > 1.0):
            raise ValueError("noise=threshold reads coverage fractions in [0, 1] (encoder=coverage)")
        signal = x * area_mm2
        if self.crosstalk > 0 and v.size:
            nb = neighbour_lists(frames)
            padded = np.concatenate([signal, np.zeros((signal.shape[0], 1))], axis=1)
            leak = np.zeros_like(signal)
            for c in range(nb.shape[1]):
                leak += padded[:, nb[:, c]]  # -1 (no neighbour) reads the zero column
            signal = signal + self.crosstalk * leak
        if v.size and self.sigma_mm2 > 0:
            _normals(signal, fi, tk, np.uint64(seed), STREAM_THRESHOLD_READ, float(self.sigma_mm2))
        if v.size and self.drift_sigma_mm2 > 0:
            if frame_rate_hz is None or not np.isfinite(frame_rate_hz) or frame_rate_hz <= 0:
                raise ValueError("noise=threshold with drift_sigma_mm2 > 0 needs the frame rate (frame_rate_hz)")
            rho = float(np.exp(-1000.0 / (float(frame_rate_hz) * self.drift_tau_ms)))
            order = np.lexsort((fi, tk)).astype(np.int64)
            cut = np.flatnonzero(tk[order][1:] != tk[order][:-1]) + 1  # each trial's block of rows
            starts = np.concatenate([[0], cut, [len(order)]]).astype(np.int64)
            _drift(
                signal, order, starts, fi, tk, np.uint64(seed), STREAM_THRESHOLD_DRIFT, float(self.drift_sigma_mm2), rho
            )
        out = (signal > self.threshold_mm2).astype(np.float32)
        return _like(frames, out)


class NoNoise(Configured):
    """``noise=none``: readings unchanged (the same array, never mutated downstream)."""

    VERSION = "2"

    SCHEMA = NoNoiseSchema

    def apply(self, frames: Frames, frame_index: np.ndarray, trial_key: np.ndarray, seed: int) -> Frames:
        """``frames`` as they are (a new Frames object sharing the values)."""
        v, _, _, _ = _check(frames, frame_index, trial_key, seed, "noise=none")
        return _like(frames, v)


class NoiseModel(Protocol):
    """What a ``noise`` component implements (``sphri.stages``: the group's method ``apply``)."""

    def apply(self, frames: Frames, frame_index: np.ndarray, trial_key: np.ndarray, seed: int) -> Frames: ...


def apply_to_windows(noise: NoiseModel, windows: WindowedFrames, trial_key: np.ndarray, seed: int) -> WindowedFrames:
    """``noise`` applied to the windows as the model sees them: every slot, padded slots included.

    ``windows.x`` (T, L, N) is read as T * L frames whose ``frame_index`` is
    the slot in the window (0 .. L-1) and whose ``trial_key`` is the window's
    trial key (``trial_key`` (T,), one per window), so every draw is a pure
    function of (seed, trial, slot, taxel). Returns new windows (float32 x,
    same shape; everything else shared); ``windows`` is not mutated.
    """
    x = np.asarray(windows.x)
    if x.ndim != 3:
        raise ValueError(f"noise: windows.x must be (trials, L, N), got shape {x.shape}")
    t, length, n = x.shape
    tk = np.asarray(trial_key)
    if tk.shape != (t,):
        raise ValueError(f"noise: trial_key must be ({t},), one per window, got shape {tk.shape}")
    geom = windows.geometry
    frames = SkinFrames(values=x.reshape(t * length, n), grid_shape=geom.grid_shape, geometry=geom)
    slot = np.tile(np.arange(length, dtype=np.int64), t)
    keys = np.repeat(tk.astype(np.int64), length)
    if getattr(noise, "USES_FRAME_RATE", False):
        out = noise.apply(frames, slot, keys, seed, frame_rate_hz=float(windows.frame_rate_hz))  # type: ignore[call-arg]
    else:
        out = noise.apply(frames, slot, keys, seed)
    y = np.asarray(out.values, dtype=np.float32).reshape(t, length, n)
    return dataclasses.replace(windows, x=y)
