"""Paired tests across participants: sign-flip permutation test and Holm correction.

:func:`sign_flip_test` tests whether per-participant paired differences
``d (n,)`` are centred above zero (or away from it). Under the null each
``d_i`` is symmetric about 0 and independent across participants, so every
vector of signs ``s in {-1, +1}^n`` is equally likely to have produced the
data; the p-value is the share of sign vectors whose mean ``mean(s * d)`` is
at least as extreme as the observed ``mean(d)``.

- Exact when ``n <= exact_max`` (all ``2^n`` vectors; p is a multiple of
  ``2^-n``, so it is never below ``2^-n``).
- Monte-Carlo otherwise: ``n_permutations`` random sign vectors plus the
  observed one, ``p = (1 + #{T* >= T}) / (n_permutations + 1)``, which keeps
  the test valid (never anti-conservative).

:func:`holm` is the Holm-Bonferroni step-down adjustment (family-wise error
rate control at any alpha).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ALTERNATIVES = ("greater", "two-sided", "less")

#: Largest n for which all 2^n sign flips may be enumerated (2^20 x n values).
EXACT_LIMIT = 20


@dataclass(frozen=True)
class SignFlipResult:
    """Outcome of one paired sign-flip permutation test."""

    statistic: float
    """Mean paired difference (the unit of ``d``)."""
    p_value: float
    exact: bool
    """True when every sign vector was enumerated."""
    n_permutations: int
    """Sign vectors compared: 2^n (exact) or the Monte-Carlo count (not counting the observed one)."""
    n: int
    """Participants (paired differences) in the test."""
    alternative: str


def _all_signs(n: int) -> np.ndarray:
    """(2^n, n) float64 matrix of every sign vector in {-1, +1}^n."""
    codes = np.arange(2**n, dtype=np.int64)[:, None]
    bits = (codes >> np.arange(n, dtype=np.int64)[None, :]) & 1
    return 1.0 - 2.0 * bits.astype(np.float64)


def sign_flip_test(
    d: np.ndarray,
    alternative: str = "greater",
    exact_max: int = 12,
    n_permutations: int = 9999,
    seed: int = 0,
) -> SignFlipResult:
    """Paired sign-flip permutation test of ``mean(d)`` against 0.

    ``d (n,)`` finite per-participant differences. ``alternative``:
    ``"greater"`` (mean > 0), ``"less"`` or ``"two-sided"`` (|mean|).
    """
    if alternative not in ALTERNATIVES:
        raise ValueError(f"alternative={alternative!r} is invalid: allowed values: {list(ALTERNATIVES)}")
    if not 0 <= int(exact_max) <= EXACT_LIMIT:
        raise ValueError(f"exact_max={exact_max} is invalid: must be in [0, {EXACT_LIMIT}] (2^n sign vectors)")
    if int(n_permutations) < 1:
        raise ValueError(f"n_permutations={n_permutations} is invalid: must be >= 1")
    d = np.asarray(d, dtype=np.float64).ravel()
    n = d.size
    if n == 0:
        raise ValueError("sign_flip_test needs at least one paired difference")
    if not np.all(np.isfinite(d)):
        raise ValueError("paired differences contain NaN or inf")
    stat = float(d.mean())
    exact = n <= int(exact_max)
    if exact:
        signs = _all_signs(n)
    else:
        rng = np.random.default_rng(seed)
        signs = np.where(rng.random((int(n_permutations), n)) < 0.5, -1.0, 1.0)
    null = signs @ d / n
    tol = 1e-12 * max(float(np.abs(d).mean()), 1e-300)  # ties up to rounding count as extreme
    if alternative == "greater":
        hits = np.count_nonzero(null >= stat - tol)
    elif alternative == "less":
        hits = np.count_nonzero(null <= stat + tol)
    else:
        hits = np.count_nonzero(np.abs(null) >= abs(stat) - tol)
    if exact:
        p = hits / signs.shape[0]
        count = signs.shape[0]
    else:
        p = (1 + hits) / (int(n_permutations) + 1)
        count = int(n_permutations)
    return SignFlipResult(stat, float(min(p, 1.0)), exact, count, n, alternative)


def holm(p_values: np.ndarray) -> np.ndarray:
    """Holm-Bonferroni adjusted p-values (same shape; NaN entries stay NaN and
    are not counted in the family).

    Sorted ascending, ``p_adj(i) = max_{j <= i} min(1, (m - j + 1) * p(j))``
    (1-based ranks); reject where ``p_adj <= alpha``.
    """
    p = np.asarray(p_values, dtype=np.float64)
    out = np.full(p.shape, np.nan)
    flat = p.ravel()
    ok = np.flatnonzero(np.isfinite(flat))
    if ok.size == 0:
        return out
    if np.any((flat[ok] < 0) | (flat[ok] > 1)):
        raise ValueError("p-values must lie in [0, 1]")
    m = ok.size
    order = ok[np.argsort(flat[ok], kind="stable")]
    scaled = np.minimum(1.0, (m - np.arange(m)) * flat[order])
    adj = np.maximum.accumulate(scaled)
    res = out.ravel()
    res[order] = adj
    return res.reshape(p.shape)
