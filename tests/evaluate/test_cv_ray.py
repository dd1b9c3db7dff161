"""``cv.backend=ray``: every fold a Ray task, with the same fold results as in this process, finished
folds kept by the worker that computed them; a backend that does not exist, or Ray missing, is refused
by name. (The sweep through hydra/launcher=ray: tests/launchers/test_launcher_ray_folds.py.)"""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest

from sphri.cache import StageCache
from sphri.config import ConfigError, compose
from sphri.evaluate.cv import LeaveOneSubjectOut
from sphri.models.rf import RandomForest
from sphri.pipeline import FoldCache
from sphri.testing.toy_windows import blob_windows


def test_an_unknown_backend_is_refused_by_name():
    with pytest.raises(ConfigError, match=r"cv.backend='dask' is invalid: allowed values: \['local', 'ray'\]"):
        compose(["+debug=fast", "cv.backend=dask"])
    with pytest.raises(ConfigError, match=r"cv.backend='dask' is invalid: allowed values: \['local', 'ray'\]"):
        LeaveOneSubjectOut(backend="dask")  # the constructor runs the schema's check, not a copy of it


def test_backend_ray_without_ray_installed_says_how_to_install_it(monkeypatch):
    """cv.backend is a runtime setting: it composes without Ray; the folds refuse to start, naming the fix."""
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ModuleNotFoundError
    cfg = compose(["+debug=fast", "cv.backend=ray"])
    assert cfg.cv.backend == "ray" and compose(["+debug=fast"]).cv.backend == "local"
    win = blob_windows(participants=3, repetitions=2, res=2, length=10)
    with pytest.raises(ConfigError, match=r"cv.backend='ray' is invalid: needs Ray: pip install -e \"\.\[cluster\]\""):
        LeaveOneSubjectOut(progress=False, backend="ray").run(
            lambda: RandomForest(n_estimators=2, geometry=win.geometry), win
        )


@pytest.mark.slow
def test_ray_folds_equal_the_in_process_folds_and_are_kept_by_their_workers(tmp_path):
    """No Ray instance here: the run starts a local one (this process's cores) and stops it at the end."""
    if importlib.util.find_spec("ray") is None:
        pytest.skip('ray is not installed: pip install -e ".[cluster]" (`make test-all` installs it)')
    import ray

    win = blob_windows(participants=4, repetitions=3, res=4, length=20)

    def make_model():
        return RandomForest(n_estimators=12, seed=3, geometry=win.geometry)

    local = LeaveOneSubjectOut(progress=False).run(make_model, win, seed=0)
    seen = []
    store = FoldCache(StageCache(tmp_path / "cache"), evaluate_key="k")  # the pipeline's fold store
    assert not ray.is_initialized()
    tasks = LeaveOneSubjectOut(progress=False, backend="ray").run(
        make_model, win, seed=0, on_fold=lambda r, t: seen.append(r.fold), resume=store
    )
    assert not ray.is_initialized()
    assert [f.fold for f in tasks.folds] == [f.fold for f in local.folds] == seen
    assert len(local.folds) == 4
    for a, b in zip(local.folds, tasks.folds):
        assert a.accuracy == b.accuracy and a.macro_f1 == b.macro_f1
        np.testing.assert_array_equal(a.confusion, b.confusion)
    assert len({f.accuracy for f in local.folds}) > 1  # the folds differ: order matters to the comparison
    # every fold kept by the Ray worker that computed it (this process saves none): a rerun resumes
    kept = [store.load(f) for f in seen]
    assert [k.result.fold for k in kept] == seen
    assert [k.result.accuracy for k in kept] == [f.accuracy for f in local.folds]
