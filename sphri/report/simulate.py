"""Synthetic accuracy curves with a known answer, for checking the requirement rule's promise.

A draw is ``scores[s, p, r] = mu[r] + a[p] + g[p, r] + e[s, p, r]``: the true
curve ``mu`` (coarse to fine), a participant's level ``a`` (cancels in the
pairs), a participant x resolution effect ``g`` (one person gains more from a
finer skin than another; the same in every seed) and the rerun noise ``e`` of
one seed. The promise of a rule that reports point ``k`` with tolerance ``T``
is kept when every point from ``k`` on is truly within ``T`` of the true best:
``max(mu) - min(mu[k:]) <= T``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: 16 points, the requirement map's resolution grid (taxels along the link).
GRID = np.array([1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 18, 22, 27, 33, 40, 50], dtype=np.float64)


def _flat(res: np.ndarray) -> np.ndarray:
    return np.full(res.shape, 0.70)


def _saturating(res: np.ndarray) -> np.ndarray:
    """A rise of 30 points that approaches its plateau slowly: 1 point short at res ~15, 0.3 at res 27."""
    return 0.45 + 0.30 * (1.0 - np.exp(-res / 3.6))


def _clean_row(res: np.ndarray) -> np.ndarray:
    """A steep rise to res 6, then a slow creep of 3 points to the finest point (log-linear)."""
    steep = 0.40 + 0.32 * (1.0 - np.exp(-res / 1.5))
    return steep + 0.03 * np.log(res / res[0]) / np.log(res[-1] / res[0])


def _dip(res: np.ndarray) -> np.ndarray:
    """Saturated by res 8, a 4-point dip around res 22, recovery at the fine end."""
    return 0.45 + 0.30 * (1.0 - np.exp(-res / 2.0)) - 0.04 * np.exp(-0.5 * (np.log(res / 22.0) / 0.25) ** 2)


SHAPES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "flat": _flat,
    "saturating": _saturating,
    "clean_row": _clean_row,
    "dip": _dip,
}


@dataclass(frozen=True)
class Noise:
    """The simulation's noise (accuracy units). ``seed_sd`` is within the rerun noise the requirement map
    measured (0.013 to 0.029 per participant); ``interaction_sd`` is an assumed size; ``participant_sd``
    cancels in the paired differences."""

    participants: int = 18
    seeds: int = 3
    seed_sd: float = 0.026
    """Rerun noise of one participant's accuracy between seeds."""
    interaction_sd: float = 0.02
    """Participant x resolution effect."""
    participant_sd: float = 0.06
    """Between-participant level (cancels in the paired differences)."""


def draw(mu: np.ndarray, noise: Noise, rng: np.random.Generator) -> np.ndarray:
    """One (S, P, R) draw of scores around the true curve ``mu`` (R,)."""
    p, s, r = noise.participants, noise.seeds, mu.shape[0]
    a = rng.normal(0.0, noise.participant_sd, size=(1, p, 1))
    g = rng.normal(0.0, noise.interaction_sd, size=(1, p, r))
    e = rng.normal(0.0, noise.seed_sd, size=(s, p, r))
    return mu[None, None, :] + a + g + e


def true_gap(mu: np.ndarray, index: int) -> float:
    """The true gap of the worst point from ``index`` on to the true best."""
    return float(mu.max() - mu[index:].min())


def violation_rate(
    rule: Callable[[np.ndarray], tuple[int, float]], mu: np.ndarray, noise: Noise, draws: int, seed: int = 0
) -> tuple[float, float]:
    """(share of draws whose reported point breaks the promise, median tolerance reported) of ``rule``:
    scores (S, P, R) -> (index, tolerance)."""
    rng = np.random.default_rng(seed)
    bad, tols = 0, []
    for _ in range(draws):
        k, t = rule(draw(mu, noise, rng))
        bad += true_gap(mu, k) > t + 1e-12
        tols.append(t)
    return bad / draws, float(np.median(tols))
