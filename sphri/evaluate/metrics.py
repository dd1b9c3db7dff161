"""Classification metrics of cross-validation folds and their summaries.

Pure functions: :func:`fold_metrics` (one fold -> :class:`FoldResult`),
:func:`bootstrap_ci` (percentile interval of a mean over participants) and
:func:`summarize` (a :class:`CVResult` -> flat dict of numbers, e.g. for
MLflow).
"""

from __future__ import annotations

import numpy as np

from sphri.types import GESTURES, CVResult, FoldResult


def confusion(y_true: np.ndarray, y_pred: np.ndarray, n_classes: int = len(GESTURES)) -> np.ndarray:
    """(G, G) int64 counts, rows true label, columns predicted, labels 0..G-1 fixed."""
    y_true = np.asarray(y_true, dtype=np.int64)
    y_pred = np.asarray(y_pred, dtype=np.int64)
    for name, v in (("y_true", y_true), ("y_pred", y_pred)):
        if v.size and (v.min() < 0 or v.max() >= n_classes):
            raise ValueError(f"{name} holds labels outside 0..{n_classes - 1}: {np.unique(v)}")
    flat = np.bincount(y_true * n_classes + y_pred, minlength=n_classes * n_classes)
    return flat.reshape(n_classes, n_classes).astype(np.int64)


def fold_metrics(fold: str, y_true: np.ndarray, y_pred: np.ndarray, n_classes: int = len(GESTURES)) -> FoldResult:
    """Accuracy, macro F1, confusion and per-gesture recall of one fold.

    Macro F1 averages over the gestures present in ``y_true`` or ``y_pred``
    (a gesture neither present nor predicted is left out, not scored 0).
    Recall is NaN for gestures absent from ``y_true``.
    """
    y_true = np.asarray(y_true, dtype=np.int64)
    y_pred = np.asarray(y_pred, dtype=np.int64)
    if y_true.shape != y_pred.shape or y_true.ndim != 1:
        raise ValueError(f"y_true {y_true.shape} and y_pred {y_pred.shape} must be equal-length 1-D arrays")
    if y_true.size == 0:
        raise ValueError(f"fold {fold!r} has no test trials")
    from sklearn.metrics import f1_score  # imported here: a job whose evaluation is cached never needs sklearn

    cm = confusion(y_true, y_pred, n_classes)
    support = cm.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        recall = np.where(support > 0, np.diag(cm) / support, np.nan)
    return FoldResult(
        fold=str(fold),
        n_test=int(y_true.size),
        accuracy=float(np.mean(y_true == y_pred)),
        macro_f1=float(f1_score(y_true, y_pred, average="macro", zero_division=0)),
        confusion=cm,
        recall=recall.astype(np.float64),
    )


def chance_level(cv: CVResult) -> float:
    """Accuracy of uniform guessing among the gestures actually tested: 1 / (classes present).

    Counted from the folds' confusion matrices (rows with any true trial), so
    ``data.gestures=[hit,tap]`` gives 0.5, not 1/8. NaN without folds.
    """
    if not cv.folds:
        return float("nan")
    present = int((np.sum([f.confusion.sum(axis=1) for f in cv.folds], axis=0) > 0).sum())
    return 1.0 / present if present else float("nan")


def bootstrap_ci(values: np.ndarray, n_boot: int = 2000, seed: int = 0, level: float = 0.95) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of ``values`` (one per participant).

    NaNs are dropped; returns (nan, nan) when nothing is left and (v, v) for
    a single value. Deterministic in ``seed``.
    """
    if n_boot < 1:
        raise ValueError(f"n_boot={n_boot} is invalid: must be >= 1")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level={level} is invalid: must be in (0, 1)")
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[~np.isnan(v)]
    if v.size == 0:
        return float("nan"), float("nan")
    if v.size == 1:
        return float(v[0]), float(v[0])
    rng = np.random.default_rng(seed)
    means = v[rng.integers(0, v.size, size=(n_boot, v.size))].mean(axis=1)
    alpha = (1.0 - level) / 2.0
    lo, hi = np.quantile(means, [alpha, 1.0 - alpha])
    return float(lo), float(hi)


def summarize(result: CVResult, n_boot: int = 2000, seed: int = 0) -> dict[str, float]:
    """Flat summary of a cross-validation: what the paper's figure shows and more.

    Keys: ``n_folds``, ``n_test``; for ``accuracy`` and ``macro_f1``:
    ``_mean``, ``_std`` (across folds, ddof 1), ``_ci_low``, ``_ci_high``
    (bootstrap 95 % over folds, i.e. participants under LOSO);
    ``pooled_accuracy`` (all test trials together); ``recall_<gesture>``
    (mean over the folds where the gesture occurs; NaN if never).
    """
    if not result.folds:
        raise ValueError(f"{result.scheme} result of {result.model!r} has no folds to summarize")
    out: dict[str, float] = {"n_folds": float(len(result.folds)), "n_test": float(sum(f.n_test for f in result.folds))}
    out.update(result.summary())
    for key in ("accuracy", "macro_f1"):
        vals = np.array([getattr(f, key) for f in result.folds], dtype=np.float64)
        out[f"{key}_ci_low"], out[f"{key}_ci_high"] = bootstrap_ci(vals, n_boot=n_boot, seed=seed)
    pooled = np.sum([f.confusion for f in result.folds], axis=0)
    out["pooled_accuracy"] = float(np.trace(pooled) / max(1, pooled.sum()))
    recall = np.array([f.recall for f in result.folds], dtype=np.float64)
    for g, name in enumerate(result.labels):
        col = recall[:, g]
        out[f"recall_{name}"] = float(np.nanmean(col)) if np.any(~np.isnan(col)) else float("nan")
    return out
