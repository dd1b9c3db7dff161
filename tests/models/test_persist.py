"""Each model saves and loads its own state (save_state/load_state) in plain arrays, no pickle."""

from __future__ import annotations

import io
import pickle

import numpy as np
import pytest

from sphri.models.persist import skops_array, skops_load, torch_state_load
from sphri.testing.toy_windows import blob_windows


@pytest.fixture(scope="module")
def small():
    return blob_windows(participants=2, repetitions=2, res=6, seed=5)


def _through_npz(arrays: dict) -> dict:
    """The arrays as a model file stores them: an npz read back with allow_pickle=False."""
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    with np.load(io.BytesIO(buf.getvalue()), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def test_rf_state_round_trip(small):
    from sphri.models.rf import RandomForest

    model = RandomForest(n_estimators=5, n_jobs=1, seed=2, max_depth=4, geometry=small.geometry).fit(small.x, small.y)
    head, arrays = model.save_state()
    assert head["params"]["max_depth"] == 4 and "geometry" not in head["params"]
    back = RandomForest.load_state(head, _through_npz(arrays), small.geometry)
    np.testing.assert_array_equal(back.predict_proba(small.x), model.predict_proba(small.x))
    np.testing.assert_array_equal(back.feature_importances_, model.feature_importances_)


def test_cnn_gru_state_round_trip(small):
    from sphri.models.cnn_gru import CnnGru

    model = CnnGru(
        max_epochs=1, batch_size=8, hidden=4, channels=(2,), strides=(1,), threads=1, geometry=small.geometry
    ).fit(small.x, small.y)
    head, arrays = model.save_state()
    assert head["params"]["channels"] == [2] and head["precision_"] == model.precision_
    back = CnnGru.load_state(head, _through_npz(arrays), small.geometry)
    np.testing.assert_array_equal(back.predict_proba(small.x), model.predict_proba(small.x))
    head["params"]["hidden"] = 5  # weights that do not fit the hyperparameters: one line, no traceback
    with pytest.raises(ValueError, match="network weights do not fit the saved hyperparameters"):
        CnnGru.load_state(head, _through_npz(arrays), small.geometry)


def test_safe_formats_refuse_what_they_do_not_trust():
    from sklearn.linear_model import LogisticRegression
    from sklearn.tree import DecisionTreeClassifier

    tree = DecisionTreeClassifier(max_depth=2).fit(np.eye(4), np.arange(4))
    trusted = ("sklearn.tree._classes.DecisionTreeClassifier", "sklearn.tree._tree.Tree")
    assert type(skops_load(skops_array(tree), trusted, DecisionTreeClassifier)) is DecisionTreeClassifier
    other = LogisticRegression().fit(np.eye(4), np.arange(4) % 2)
    with pytest.raises(ValueError, match=r"untrusted types .*LogisticRegression"):
        skops_load(skops_array(other), trusted, DecisionTreeClassifier)
    with pytest.raises(ValueError, match="holds a DecisionTreeClassifier, not a LogisticRegression"):
        skops_load(skops_array(tree), trusted, LogisticRegression)
    with pytest.raises(ValueError, match="payload is unreadable"):
        skops_load(np.frombuffer(b"not a zip", dtype=np.uint8), trusted, DecisionTreeClassifier)
    import torch

    crafted = np.frombuffer(pickle.dumps({"w": object()}, protocol=2), dtype=np.uint8)
    with pytest.raises(ValueError, match="not a plain state dict"):
        torch_state_load(crafted, torch.nn.Linear(2, 2))


RF_FILE_WITHOUT_TORCH = """
import json, sys
from sphri.models.persist import skops_array, skops_load
from sphri.models.rf import TRUSTED_TYPES, RandomForest
from sphri.testing.toy_windows import blob_windows
small = blob_windows(participants=2, repetitions=2, res=6, seed=5)
model = RandomForest(n_estimators=3, n_jobs=1, seed=2, geometry=small.geometry).fit(small.x, small.y)
back = skops_load(skops_array(model.forest_), TRUSTED_TYPES, type(model.forest_))
assert (back.predict_proba(model.transform(small.x)) == model.forest_.predict_proba(model.transform(small.x))).all()
from skops.io import _trusted_types
print(json.dumps({"torch": "torch" in sys.modules, "types": sorted(_trusted_types.SKLEARN_ESTIMATOR_TYPE_NAMES)}))
"""

PLAIN_SKOPS_TYPES = """
import json
from skops.io import _trusted_types
print(json.dumps({"types": sorted(_trusted_types.SKLEARN_ESTIMATOR_TYPE_NAMES)}))
"""


def test_a_forest_is_written_and_read_without_importing_torch(tmp_path):
    """A fresh process (a live session, an MLflow pyfunc server): a Random Forest's skops archive is
    written and read back without torch (skops' import walked scikit-learn into its torch adapter:
    ~180 MiB and 1.5-4 s), and skops trusts the same scikit-learn types as when imported plainly."""
    import json
    import subprocess
    import sys

    def run(code: str) -> dict:
        out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-3000:]
        return json.loads(out.stdout.strip().splitlines()[-1])

    ours, plain = run(RF_FILE_WITHOUT_TORCH), run(PLAIN_SKOPS_TYPES)
    assert ours["torch"] is False
    assert ours["types"] == plain["types"] and len(plain["types"]) > 100
