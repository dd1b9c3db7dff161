"""Cross-validation of gesture models and their metrics (``cv=...``).

- :class:`~sphri.evaluate.cv.LeaveOneSubjectOut` (``cv=loso``, default) and
  :class:`~sphri.evaluate.cv.WithinSubjectKFold` (``cv=kfold``; within-subject,
  not comparable to LOSO): ``run(make_model, windows, seed) -> CVResult``.
- :mod:`sphri.evaluate.metrics`: :func:`fold_metrics`, :func:`bootstrap_ci`,
  :func:`summarize`.
"""

import importlib
from typing import Any

# Lazy: importing the package (e.g. for its config schema) stays cheap.
_LAZY = {
    "LeaveOneSubjectOut": "sphri.evaluate.cv",
    "WithinSubjectKFold": "sphri.evaluate.cv",
    "bootstrap_ci": "sphri.evaluate.metrics",
    "fold_metrics": "sphri.evaluate.metrics",
    "summarize": "sphri.evaluate.metrics",
}
__all__ = list(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'sphri.evaluate' has no attribute {name!r}")
