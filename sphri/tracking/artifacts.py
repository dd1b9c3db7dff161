"""Files that describe one evaluation: per-participant CSV, confusion matrix PNG."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sphri.types import CVResult

if TYPE_CHECKING:
    from sphri.figures import Provenance


def write_fold_csv(cv: CVResult, path: Path) -> Path:
    """One row per fold (participant): n_test, accuracy, macro F1, per-gesture recall."""
    import pandas as pd

    rows = [
        {"fold": f.fold, "n_test": f.n_test, "accuracy": f.accuracy, "macro_f1": f.macro_f1}
        | {f"recall_{g}": float(r) for g, r in zip(cv.labels, f.recall)}
        for f in cv.folds
    ]
    pd.DataFrame(rows).to_csv(path, index=False, float_format="%.6g")
    return path


def confusion_counts(cv: CVResult) -> np.ndarray:
    """(G, G) confusion counts summed over folds (rows: true gesture, columns: predicted)."""
    return np.sum([f.confusion for f in cv.folds], axis=0).astype(float)


def write_confusion_csv(cv: CVResult, path: Path) -> Path:
    """The summed confusion counts as CSV (index: true gesture, columns: predicted): the report redraws from it."""
    import pandas as pd

    pd.DataFrame(confusion_counts(cv), index=list(cv.labels), columns=list(cv.labels)).to_csv(path, float_format="%.0f")
    return path


def write_confusion_png(
    cv: CVResult,
    path: Path,
    title: str | None = None,
    provenance: Provenance | None = None,
    formats: Sequence[str] = ("png",),
    check: bool = True,
) -> Path:
    """Row-normalised confusion matrix summed over folds, one column wide (``sphri.figures``).

    ``formats``: files written beside ``path``; ``provenance``: a :class:`sphri.figures.Provenance`;
    ``check``: run the layout check (:func:`sphri.figures.save`).
    """
    title = title or f"{cv.model} ({cv.scheme.upper()}, {len(cv.folds)} folds)"
    return draw_confusion(confusion_counts(cv), list(cv.labels), path, title, provenance, formats, check)


def draw_confusion(
    total: np.ndarray,
    labels: list[str],
    path: Path,
    title: str,
    provenance: Provenance | None = None,
    formats: Sequence[str] = ("png",),
    check: bool = True,
) -> Path:
    """Row-normalised confusion matrix of the counts ``total`` (rows: true) -> ``path`` (and ``formats`` beside it)."""
    from sphri import figures

    total = np.asarray(total, dtype=float)
    rows = total.sum(axis=1, keepdims=True)
    norm = np.divide(total, rows, out=np.zeros_like(total), where=rows > 0)
    with figures.style():  # every artist drawn under the style (fonts are fixed at creation)
        fig, ax = figures.new_figure("one", 3.1)
        im = ax.imshow(norm, vmin=0, vmax=1, cmap="Blues")
        ax.set_xticks(range(len(labels)), labels, rotation=45, ha="right")
        ax.set_yticks(range(len(labels)), labels)
        ax.set_xlabel("predicted gesture")
        ax.set_ylabel("true gesture")
        for i, j in np.ndindex(norm.shape):
            if total[i].sum() > 0:
                text = f"{norm[i, j]:.2f}".lstrip("0") if norm[i, j] < 1 else "1"
                color = "white" if norm[i, j] > 0.5 else "black"
                ax.text(j, i, text, ha="center", va="center", fontsize=figures.MIN_FONT_PT, color=color)
        ax.set_title(title, loc="left")
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03, label="share of the true gesture's trials")
        figures.mark(fig, provenance)
        figures.save(fig, path, formats=formats, check=check)
    return path
