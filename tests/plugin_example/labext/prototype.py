"""A lab's own model that exports to a model file and runs live, outside sphri: one module, one YAML.

It persists itself (``NAME``, ``save_state``, ``load_state``: see ``sphri.export.registry``); sphri stores its
import path in the file and imports it back only when the reader lists ``plugins=[labext]``.
"""

import numpy as np


class NearestPrototype:
    """Nearest class prototype (time-averaged readings), with softmax probabilities over the distances."""

    NAME = "lab_prototype"
    VERSION = "1"

    def __init__(self, geometry=None, temperature: float = 1.0):
        self.geometry = geometry
        self.temperature = temperature

    @staticmethod
    def _features(x):
        return np.asarray(x, dtype=np.float64).mean(axis=1)

    def fit(self, x, y, groups=None):
        f = self._features(x)
        self.classes_ = np.unique(y)
        self.prototypes_ = np.stack([f[y == c].mean(axis=0) for c in self.classes_])
        return self

    def predict_proba(self, x):
        d = ((self._features(x)[:, None, :] - self.prototypes_[None]) ** 2).sum(axis=2)
        z = -d / float(self.temperature)
        p = np.exp(z - z.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True)

    def predict(self, x):
        return self.classes_[self.predict_proba(x).argmax(axis=1)]

    def save_state(self):
        return {"params": {"temperature": float(self.temperature)}}, {
            "classes": self.classes_,
            "prototypes": self.prototypes_,
        }

    @classmethod
    def load_state(cls, head, arrays, geometry):
        model = cls(geometry=geometry, **head["params"])
        model.classes_ = arrays["classes"]
        model.prototypes_ = arrays["prototypes"]
        if model.prototypes_.shape != (len(model.classes_), geometry.n_taxels):
            raise ValueError(
                f"prototypes of shape {model.prototypes_.shape} for {len(model.classes_)} classes and "
                f"{geometry.n_taxels} taxels"
            )
        return model
