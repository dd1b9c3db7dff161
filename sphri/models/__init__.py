"""Gesture classifiers on skin windows (``model=...``).

- :class:`~sphri.models.rf.RandomForest` (``model=rf``): the reference study's
  Random Forest on 32 hand-crafted touch features
  (:mod:`sphri.models.features`, :data:`~sphri.models.features.FEATURE_NAMES`).
- :class:`~sphri.models.cnn_gru.CnnGru` (``model=cnn_gru``): per-frame CNN
  (MLP on non-grid layouts), GRU over time, linear classifier.

Both are scikit-learn estimators: ``fit(x, y, groups=None)``, ``predict``,
``predict_proba`` on ``WindowedFrames.x`` (n, L, N); constructor = config
fields + ``geometry``. :mod:`sphri.models.toydata` draws synthetic windows
for tests and benchmarks.
"""

import importlib
from typing import Any

# Lazy: importing the package (e.g. for its config schema) must not import torch.
_LAZY = {
    "CnnGru": "sphri.models.cnn_gru",
    "RandomForest": "sphri.models.rf",
    "FEATURE_NAMES": "sphri.models.features",
    "extract_features": "sphri.models.features",
}
__all__ = list(_LAZY)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'sphri.models' has no attribute {name!r}")
