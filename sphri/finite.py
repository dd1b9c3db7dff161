"""Finite checks at the chain's stage boundaries that can produce NaN or infinity.

A NaN that reaches a classifier does not fail: ``argmax`` over a NaN row is class 0, so a broken model
predicts one gesture for every trial and scores an ordinary-looking accuracy near chance. sphri
therefore checks, where a non-finite number can first appear, and stops with one line naming the
stage and the array:

- the encoder's float frames (coverage and proximity encoders; a degenerate chart divides by zero);
- the Random Forest's 32 features (ratios and circular statistics of empty or one-taxel frames);
- the CNN-GRU's loss and gradients at every optimisation step, and its probabilities;
- any model's probabilities or labels before the cross-validation records a fold.

:func:`require_finite` costs one vectorised pass (``np.isfinite(a).all()``) and nothing for integer
arrays (binary skins), so the checks stay on (measured in ``bench/bench_finite.py``).
"""

from __future__ import annotations

import numpy as np


class NonFiniteError(ArithmeticError):
    """An array that must be finite holds NaN or infinity; the message names the stage and the array.

    Registered in :data:`sphri.errors.EXPECTED` as a ``numerical error`` (one line, exit 1)."""


def count_non_finite(a: np.ndarray) -> int:
    """Entries of ``a`` that are NaN or infinite (0 for integer and boolean arrays, without a pass)."""
    a = np.asarray(a)
    if a.dtype.kind not in "fc":
        return 0
    finite = np.isfinite(a)
    return 0 if finite.all() else int(a.size - np.count_nonzero(finite))


def require_finite(a: np.ndarray, what: str) -> np.ndarray:
    """``a`` unchanged when every entry is finite, else :class:`NonFiniteError` naming ``what``.

    ``what`` names the stage and the array (``"encoder=coverage frames"``); the message adds how many
    entries are NaN or infinite out of how many, and the array's shape."""
    bad = count_non_finite(a)
    if bad:
        a = np.asarray(a)
        n_nan = int(np.isnan(a).sum())
        raise NonFiniteError(
            f"{what}: {bad} of {a.size} values are not finite ({n_nan} NaN, {bad - n_nan} infinite; "
            f"shape {tuple(a.shape)})"
        )
    return a
