"""``model=rf``: the reference study's Random Forest on 32 touch features."""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.ensemble import RandomForestClassifier
from sklearn.utils.validation import check_is_fitted

from sphri.finite import require_finite
from sphri.models.features import FEATURE_NAMES, TaxelCoords, extract_features, taxel_coords
from sphri.models.schema import RandomForestSchema as _S  # the defaults, stated once (sklearn reads the signature)
from sphri.types import TaxelGeometry

#: The types the forest's skops payload in a model file may hold besides plain containers and numbers
#: (:data:`sphri.models.persist.PLAIN_TYPES`); the only list skops is given when a file is read.
TRUSTED_TYPES = (
    "sklearn.ensemble._forest.RandomForestClassifier",
    "sklearn.tree._classes.DecisionTreeClassifier",
    "sklearn.tree._tree.Tree",
)


class RandomForest(ClassifierMixin, BaseEstimator):
    """Random Forest on the 32 features of :mod:`sphri.models.features`.

    ``fit(x, y)`` / ``predict(x)`` / ``predict_proba(x)`` take windows x of
    shape (n_trials, L, N_taxels) (``WindowedFrames.x``) and labels y (n,)
    int64. The features need the skin's ``geometry`` (taxel positions).
    Hyperparameters: ``RandomForestSchema`` (``sphri show model=rf``). ``seed`` seeds the forest.

    The features are a fixed function of each trial alone (nothing in them
    is fitted), so ``TRANSFORM_PER_TRIAL`` is set: cross-validation computes
    :meth:`transform` once for all trials and calls :meth:`fit_features` /
    :meth:`predict_features` per fold, which gives the same forests as
    ``fit``/``predict`` on the windows (18x less feature work under LOSO).
    """

    NAME = "rf"
    VERSION = "1"
    TRANSFORM_PER_TRIAL = True

    def __init__(
        self,
        n_estimators: int = _S.n_estimators,
        max_depth: int | None = _S.max_depth,
        min_samples_leaf: int = _S.min_samples_leaf,
        max_features: str = _S.max_features,
        class_weight: str | None = _S.class_weight,
        n_jobs: int = _S.n_jobs,
        seed: int = _S.seed,
        active_threshold: float = _S.active_threshold,
        geometry: TaxelGeometry | None = None,
    ):
        self.n_estimators = n_estimators
        self.max_depth = max_depth
        self.min_samples_leaf = min_samples_leaf
        self.max_features = max_features
        self.class_weight = class_weight
        self.n_jobs = n_jobs
        self.seed = seed
        self.active_threshold = active_threshold
        self.geometry = geometry

    def runtime(self) -> dict[str, str]:
        """Where the forest runs (recorded in MLflow as ``run.*`` params): always the CPU."""
        return {"device": "cpu"}

    def _coords(self) -> TaxelCoords:
        if self.geometry is None:
            raise ValueError(
                "RandomForest needs geometry=TaxelGeometry(...) (the pipeline passes windows.geometry); "
                "its features are computed from taxel positions"
            )
        cached = getattr(self, "_coords_cache", None)
        if cached is None or cached[0] is not self.geometry:
            cached = (self.geometry, taxel_coords(self.geometry))
            self._coords_cache = cached
        return cached[1]

    def transform(self, x: np.ndarray) -> np.ndarray:
        """(n, L, N) windows -> (n, 32) float64 features (:data:`FEATURE_NAMES`)."""
        coords = self._coords()  # raises the ValueError above when geometry is None
        assert self.geometry is not None
        return extract_features(x, self.geometry, self.active_threshold, coords=coords)

    def fit(self, x: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None) -> RandomForest:
        """Fit the forest on windows x (n, L, N) and labels y (n,). ``groups`` is unused."""
        return self.fit_features(self.transform(x), y)

    def fit_features(self, feats: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None) -> RandomForest:
        """Fit the forest on precomputed features (n, 32) (:meth:`transform`) and labels y (n,)."""
        feats = self._check_features(feats)
        y = np.asarray(y)
        if y.ndim != 1 or y.shape[0] != feats.shape[0]:
            raise ValueError(f"y must be (n_trials,) = ({feats.shape[0]},), got shape {y.shape}")
        n_jobs = None if self.n_jobs == 0 else self.n_jobs
        self.forest_ = RandomForestClassifier(
            n_estimators=self.n_estimators,
            max_depth=self.max_depth,
            min_samples_leaf=self.min_samples_leaf,
            max_features=self.max_features,
            class_weight=self.class_weight,
            n_jobs=n_jobs,
            random_state=self.seed,
        ).fit(feats, y)
        self.classes_ = self.forest_.classes_
        self.n_features_in_ = len(FEATURE_NAMES)
        self.feature_names_ = FEATURE_NAMES
        return self

    @staticmethod
    def _check_features(feats: np.ndarray) -> np.ndarray:
        feats = np.asarray(feats)
        if feats.ndim != 2 or feats.shape[1] != len(FEATURE_NAMES):
            raise ValueError(
                f"features must be (n_trials, {len(FEATURE_NAMES)}) from RandomForest.transform, got shape {feats.shape}"
            )
        # scikit-learn's forest takes NaN as a missing value without a word: here it is a defect
        return require_finite(feats, "Random Forest features")

    @property
    def feature_importances_(self) -> np.ndarray:
        """(32,) impurity importances of :data:`FEATURE_NAMES`."""
        check_is_fitted(self, "forest_")
        return self.forest_.feature_importances_

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """(n, n_classes) class probabilities, columns in ``classes_`` order."""
        check_is_fitted(self, "forest_")
        return self.predict_proba_features(self.transform(x))

    def predict_proba_features(self, feats: np.ndarray) -> np.ndarray:
        """(n, n_classes) class probabilities from precomputed features (n, 32), columns in ``classes_`` order."""
        check_is_fitted(self, "forest_")
        return require_finite(self.forest_.predict_proba(self._check_features(feats)), "Random Forest probabilities")

    def predict(self, x: np.ndarray) -> np.ndarray:
        """(n,) predicted labels."""
        return self.predict_features(self.transform(x))

    def predict_features(self, feats: np.ndarray) -> np.ndarray:
        """(n,) predicted labels from precomputed features (n, 32)."""
        check_is_fitted(self, "forest_")
        return self.forest_.predict(self._check_features(feats))

    # -- model files (sphri.export.registry) -------------------------------
    def save_state(self) -> tuple[dict, dict[str, np.ndarray]]:
        """(hyperparameters, arrays: classes and the forest as skops bytes), no pickle."""
        from sphri.models.persist import params_of, skops_array

        check_is_fitted(self, "forest_")
        return {"params": params_of(self)}, {
            "classes": np.asarray(self.classes_),
            "forest_skops": skops_array(self.forest_),
        }

    @classmethod
    def load_state(cls, head: dict, arrays, geometry: TaxelGeometry) -> RandomForest:
        """The fitted forest of :meth:`save_state`'s output; a payload naming a type outside
        :data:`TRUSTED_TYPES` is refused before skops loads anything."""
        from sphri.models.persist import skops_load

        model = cls(**dict(head.get("params") or {}), geometry=geometry)
        model.forest_ = skops_load(arrays["forest_skops"], TRUSTED_TYPES, RandomForestClassifier, "forest payload")
        model.classes_ = model.forest_.classes_
        model.n_features_in_ = len(FEATURE_NAMES)
        model.feature_names_ = FEATURE_NAMES
        return model
