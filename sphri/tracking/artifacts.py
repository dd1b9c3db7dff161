"""Files that describe one evaluation: per-participant CSV, confusion matrix PNG."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sphri.types import CVResult


def write_fold_csv(cv: CVResult, path: Path) -> Path:
    """One row per fold (participant): n_test, accuracy, macro F1, per-gesture recall."""
    import pandas as pd

    rows = []
    for f in cv.folds:
        row = {"fold": f.fold, "n_test": f.n_test, "accuracy": f.accuracy, "macro_f1": f.macro_f1}
        row.update({f"recall_{g}": float(r) for g, r in zip(cv.labels, f.recall)})
        rows.append(row)
    pd.DataFrame(rows).to_csv(path, index=False, float_format="%.6g")
    return path


def write_confusion_png(cv: CVResult, path: Path, title: str | None = None) -> Path:
    """Row-normalised confusion matrix summed over folds, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    total = np.sum([f.confusion for f in cv.folds], axis=0).astype(float)
    rows = total.sum(axis=1, keepdims=True)
    norm = np.divide(total, rows, out=np.zeros_like(total), where=rows > 0)
    fig, ax = plt.subplots(figsize=(5.2, 4.6), dpi=120)
    im = ax.imshow(norm, vmin=0, vmax=1, cmap="Blues")
    ax.set_xticks(range(len(cv.labels)), cv.labels, rotation=45, ha="right")
    ax.set_yticks(range(len(cv.labels)), cv.labels)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    for i in range(norm.shape[0]):
        for j in range(norm.shape[1]):
            if total[i].sum() > 0:
                ax.text(j, i, f"{norm[i, j]:.2f}", ha="center", va="center", fontsize=7,
                        color="white" if norm[i, j] > 0.5 else "black")
    ax.set_title(title or f"{cv.model} ({cv.scheme.upper()}, {len(cv.folds)} folds)")
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="recall share")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
