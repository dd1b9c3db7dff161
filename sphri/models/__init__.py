"""Gesture classifiers on skin windows (``model=...``).

- :class:`~sphri.models.rf.RandomForest` (``model=rf``): the reference study's
  Random Forest on 32 hand-crafted touch features
  (:mod:`sphri.models.features`, :data:`~sphri.models.features.FEATURE_NAMES`).
- :class:`~sphri.models.cnn_gru.CnnGru` (``model=cnn_gru``): per-frame CNN
  (MLP on non-grid layouts), GRU over time, linear classifier.

Both are scikit-learn estimators: ``fit(x, y, groups=None)``, ``predict``,
``predict_proba`` on ``WindowedFrames.x`` (n, L, N); constructor = config
fields + ``geometry``. :mod:`sphri.testing.toy_windows` draws synthetic windows
for tests and benchmarks.
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.models",
    {
        "CnnGru": "sphri.models.cnn_gru",
        "RandomForest": "sphri.models.rf",
        "FEATURE_NAMES": "sphri.models.features",
        "extract_features": "sphri.models.features",
    },
)
