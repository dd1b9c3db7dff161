"""model=rf: an sklearn-like estimator that learns gestures from touch features."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from sklearn.base import clone

from sphri.evaluate.cv import LeaveOneSubjectOut
from sphri.models.features import FEATURE_NAMES
from sphri.models.rf import RandomForest
from sphri.testing.toy_windows import blob_windows


@pytest.fixture(scope="module")
def small():
    return blob_windows(participants=4, repetitions=4, res=12, seed=11)


def test_estimator_api_and_determinism(small):
    m = RandomForest(n_estimators=30, geometry=small.geometry, seed=3)
    assert m.get_params()["n_estimators"] == 30
    m.fit(small.x, small.y)
    np.testing.assert_array_equal(m.classes_, np.arange(8))
    p = m.predict_proba(small.x[:10])
    assert p.shape == (10, 8)
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    assert m.predict(small.x[:10]).shape == (10,)
    assert m.feature_importances_.shape == (len(FEATURE_NAMES),)
    again = clone(m).fit(small.x, small.y)
    np.testing.assert_array_equal(again.predict_proba(small.x), m.predict_proba(small.x))
    other = clone(m).set_params(seed=4).fit(small.x, small.y)
    assert not np.array_equal(other.predict_proba(small.x), m.predict_proba(small.x))


def test_needs_geometry_and_matching_taxels(small):
    with pytest.raises(ValueError, match="geometry"):
        RandomForest().fit(small.x, small.y)
    m = RandomForest(geometry=small.geometry)
    with pytest.raises(ValueError, match="taxels"):
        m.fit(small.x[:, :, :-1], small.y)
    with pytest.raises(ValueError, match="y must be"):
        m.fit(small.x, small.y[:-1])


def test_rf_learns_and_resolution_matters():
    """LOSO on synthetic arm touches: far above chance at res 12, clearly worse at res 1."""
    acc = {}
    for res in (1, 12):
        win = blob_windows(participants=4, repetitions=4, res=res, seed=12)
        make = functools.partial(RandomForest, n_estimators=60, geometry=win.geometry)
        result = LeaveOneSubjectOut().run(make, win, seed=0)
        acc[res] = result.summary()["accuracy_mean"]
    assert acc[12] > 0.5, acc  # chance is 0.125
    assert acc[1] < acc[12] - 0.1, acc


def test_rf_on_a_non_grid_layout():
    win = blob_windows(participants=3, repetitions=3, res=10, layout="scatter", seed=13)
    m = RandomForest(n_estimators=30, geometry=win.geometry).fit(win.x, win.y)
    assert m.predict(win.x).shape == win.y.shape
