"""Cross-validation of gesture models and their metrics (``cv=...``).

- :class:`~sphri.evaluate.cv.LeaveOneSubjectOut` (``cv=loso``, default) and
  :class:`~sphri.evaluate.cv.WithinSubjectKFold` (``cv=kfold``; within-subject,
  not comparable to LOSO): ``run(make_model, windows, seed) -> CVResult``.
- :mod:`sphri.evaluate.metrics`: :func:`fold_metrics`, :func:`bootstrap_ci`,
  :func:`summarize`.
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.evaluate",
    {
        "LeaveOneSubjectOut": "sphri.evaluate.cv",
        "WithinSubjectKFold": "sphri.evaluate.cv",
        "bootstrap_ci": "sphri.evaluate.metrics",
        "fold_metrics": "sphri.evaluate.metrics",
        "summarize": "sphri.evaluate.metrics",
    },
)
