"""Cross-validation: no participant on both sides, training-only fitting, k-fold, workers."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from sklearn.base import BaseEstimator, ClassifierMixin

from sphri.evaluate.cv import LeaveOneSubjectOut, WithinSubjectKFold
from sphri.models.rf import RandomForest
from sphri.testing.toy_windows import blob_windows
from sphri.types import GESTURES, TaxelGeometry, WindowedFrames


class SpyModel(ClassifierMixin, BaseEstimator):
    """Records what it was fit and asked to predict on; 'scales' inputs like a StandardScaler.

    Trial ids are read from x[:, 0, 0]; the rest of x is the data.
    """

    fitted: list[SpyModel] = []

    def __init__(self, geometry: TaxelGeometry | None = None):
        self.geometry = geometry

    def fit(self, x, y, groups=None):
        self.fit_ids_ = x[:, 0, 0].astype(np.int64)
        self.fit_groups_ = None if groups is None else np.asarray(groups)
        self.mean_ = float(x[:, :, 1:].mean())  # the "scaler", fit here only
        self.classes_, counts = np.unique(y, return_counts=True)
        self.majority_ = self.classes_[np.argmax(counts)]
        self.predicted_ids_ = []
        self.predict_means_ = []
        SpyModel.fitted.append(self)
        return self

    def predict(self, x):
        self.predicted_ids_.append(x[:, 0, 0].astype(np.int64))
        self.predict_means_.append(self.mean_)  # uses the stored scaler, never refits
        return np.full(x.shape[0], self.majority_)


def spy_windows(participants: int = 5, per_class: int = 3) -> WindowedFrames:
    rng = np.random.default_rng(0)
    n = participants * per_class * len(GESTURES)
    groups = np.repeat([f"participant_{p + 1:02d}" for p in range(participants)], per_class * len(GESTURES))
    y = np.tile(np.repeat(np.arange(len(GESTURES)), per_class), participants)
    x = rng.random((n, 4, 6)).astype(np.float32)
    offset = (np.arange(participants) + 1.0) ** 2  # per person; leaving anyone out moves the mean
    x += np.repeat(offset, per_class * len(GESTURES))[:, None, None].astype(np.float32)
    x[:, 0, 0] = np.arange(n)
    geom = TaxelGeometry(
        grid_shape=(2, 3), uv=None, position_m=rng.random((6, 3)), wrap_v=False, metres_per_u=0.0, metres_per_v=0.0
    )
    return WindowedFrames(
        x=x, y=y.astype(np.int64), groups=groups, geometry=geom, trial_row=np.arange(n, dtype=np.int64), n_dropped=0
    )


@pytest.fixture
def spy():
    SpyModel.fitted.clear()
    yield SpyModel
    SpyModel.fitted.clear()


def test_loso_never_puts_a_participant_on_both_sides(spy):
    win = spy_windows()
    result = LeaveOneSubjectOut().run(lambda: spy(geometry=win.geometry), win, seed=0)
    assert result.scheme == "loso" and result.model == "SpyModel"
    assert [f.fold for f in result.folds] == sorted(set(win.groups))
    assert len(spy.fitted) == 5
    seen_test = []
    for fold, model in zip(result.folds, spy.fitted):
        (test_ids,) = model.predicted_ids_
        assert set(win.groups[test_ids]) == {fold.fold}
        assert fold.fold not in set(win.groups[model.fit_ids_])
        assert not set(model.fit_ids_) & set(test_ids)
        assert len(model.fit_ids_) + len(test_ids) == len(win.y)
        # groups handed to fit are those of the training trials (for inner splits)
        np.testing.assert_array_equal(model.fit_groups_, win.groups[model.fit_ids_])
        # the scaler saw training data only, and predict used it as fitted
        assert model.mean_ == pytest.approx(float(win.x[model.fit_ids_, :, 1:].mean()), rel=1e-6)
        assert model.mean_ != pytest.approx(float(win.x[:, :, 1:].mean()), rel=1e-3)
        assert model.predict_means_ == [model.mean_]
        seen_test.extend(test_ids)
        assert fold.n_test == len(test_ids)
    assert sorted(seen_test) == list(range(len(win.y)))


def test_loso_refuses_a_single_participant():
    win = spy_windows(participants=1)
    with pytest.raises(ValueError, match="at least 2 participants"):
        LeaveOneSubjectOut().run(lambda: SpyModel(), win, seed=0)


def test_max_folds_limits_the_folds_and_on_fold_reports_each(spy):
    win = spy_windows()
    seen = []
    result = LeaveOneSubjectOut(max_folds=2).run(lambda: spy(), win, seed=0, on_fold=lambda r, t: seen.append((r, t)))
    assert [f.fold for f in result.folds] == ["participant_01", "participant_02"]
    assert [r.fold for r, _ in seen] == ["participant_01", "participant_02"]
    assert all(t["wall_s"] >= 0 and t["cpu_s"] >= 0 for _, t in seen)


def test_kfold_is_within_subject_stratified_and_labelled(spy):
    win = spy_windows(participants=3, per_class=5)
    cv = WithinSubjectKFold(k=5)
    fold_of = cv.assign(win.y, win.groups, seed=1)
    for g in np.unique(win.groups):
        for c in range(len(GESTURES)):
            counts = np.bincount(fold_of[(win.groups == g) & (win.y == c)], minlength=5)
            assert counts.max() - counts.min() <= 1
    result = cv.run(lambda: spy(), win, seed=1)
    assert result.scheme == "kfold" and len(result.folds) == 5
    for model in spy.fitted:
        (test_ids,) = model.predicted_ids_
        assert not set(model.fit_ids_) & set(test_ids)
        # within-subject: every participant is on both sides
        assert set(win.groups[test_ids]) == set(win.groups) == set(win.groups[model.fit_ids_])
    # deterministic in the seed, different across seeds
    np.testing.assert_array_equal(cv.assign(win.y, win.groups, seed=1), fold_of)
    assert not np.array_equal(cv.assign(win.y, win.groups, seed=2), fold_of)


def test_kfold_with_fewer_trials_than_folds_still_runs(spy):
    win = spy_windows(participants=2, per_class=1)
    result = WithinSubjectKFold(k=3).run(lambda: spy(), win, seed=0)
    assert sum(f.n_test for f in result.folds) == len(win.y)


def test_parallel_workers_give_the_same_result_as_one_process():
    win = blob_windows(participants=3, repetitions=2, res=6, seed=2)
    make = functools.partial(RandomForest, n_estimators=20, geometry=win.geometry)
    one = LeaveOneSubjectOut(workers=1).run(make, win, seed=0)
    two = LeaveOneSubjectOut(workers=2, threads_per_worker=1).run(make, win, seed=0)
    assert [f.fold for f in two.folds] == [f.fold for f in one.folds]
    for a, b in zip(one.folds, two.folds):
        assert a.accuracy == b.accuracy
        np.testing.assert_array_equal(a.confusion, b.confusion)


class PerFoldForest(RandomForest):
    """The Random Forest with its per-trial transform hidden: features recomputed inside every fold."""

    TRANSFORM_PER_TRIAL = False


class CountingForest(RandomForest):
    """Counts the trials its features are computed on (across all instances)."""

    transformed: list[int] = []

    def transform(self, x):
        CountingForest.transformed.append(int(np.shape(x)[0]))
        return super().transform(x)


@pytest.mark.parametrize("workers", [1, 2])
def test_features_computed_once_give_the_same_folds_as_per_fold_features(workers):
    win = blob_windows(participants=4, repetitions=2, res=6, seed=3)
    cv = LeaveOneSubjectOut(workers=workers, threads_per_worker=1)
    per_fold = cv.run(functools.partial(PerFoldForest, n_estimators=15, geometry=win.geometry), win, seed=0)
    CountingForest.transformed.clear()
    once = cv.run(functools.partial(CountingForest, n_estimators=15, geometry=win.geometry), win, seed=0)
    assert CountingForest.transformed == [len(win.y)]  # one pass over all trials, none inside the folds
    assert [f.fold for f in once.folds] == [f.fold for f in per_fold.folds]
    for a, b in zip(per_fold.folds, once.folds):
        assert a.accuracy == b.accuracy
        np.testing.assert_array_equal(a.confusion, b.confusion)


def test_forest_refuses_features_of_the_wrong_shape():
    win = blob_windows(participants=2, repetitions=1, res=4, seed=0)
    rf = RandomForest(n_estimators=5, geometry=win.geometry)
    with pytest.raises(ValueError, match=r"features must be \(n_trials, 32\)"):
        rf.fit_features(win.x, win.y)
    feats = rf.transform(win.x)
    with pytest.raises(ValueError, match="y must be"):
        rf.fit_features(feats, win.y[:-1])
    np.testing.assert_array_equal(rf.fit_features(feats, win.y).predict_features(feats), rf.predict(win.x))


class ThreadSpy(SpyModel):
    """Records the thread count the CV gave it."""

    seen: list[int] = []

    def __init__(self, geometry: TaxelGeometry | None = None, n_jobs: int = -1):
        super().__init__(geometry)
        self.n_jobs = n_jobs

    def fit(self, x, y, groups=None):
        ThreadSpy.seen.append(self.n_jobs)
        return super().fit(x, y, groups)


def test_a_sweep_jobs_thread_budget_caps_the_folds(monkeypatch, spy):
    from sphri.evaluate.cv import available_cores

    monkeypatch.delenv("SPHRI_THREADS", raising=False)
    cores = available_cores()
    monkeypatch.setenv("SPHRI_THREADS", "1")
    assert available_cores() == 1
    ThreadSpy.seen.clear()
    LeaveOneSubjectOut(progress=False).run(lambda: ThreadSpy(), spy_windows(participants=3), seed=0)
    assert ThreadSpy.seen == [1, 1, 1]
    monkeypatch.setenv("SPHRI_THREADS", str(cores + 5))
    assert available_cores() == cores  # a budget never exceeds the machine
    monkeypatch.setenv("SPHRI_THREADS", "two")
    with pytest.raises(ValueError, match="SPHRI_THREADS='two'"):
        available_cores()


def test_thread_caps_reach_the_model(spy):
    from sphri.evaluate.cv import _cap_threads

    rf = RandomForest(n_jobs=-1)
    _cap_threads(rf, 1)
    assert rf.n_jobs == 1
    rf = RandomForest(n_jobs=1)
    _cap_threads(rf, 2)
    assert rf.n_jobs == 1  # a smaller request is kept


def test_bad_windows_are_refused():
    win = spy_windows()
    win.y = win.y.copy()
    win.y[0] = 8
    with pytest.raises(ValueError, match="labels outside"):
        LeaveOneSubjectOut().run(lambda: SpyModel(), win, seed=0)
    with pytest.raises(ValueError, match="workers"):
        LeaveOneSubjectOut(workers=0)
    with pytest.raises(ValueError, match="cv.k"):
        WithinSubjectKFold(k=1)


class DictStore:
    """A :class:`sphri.evaluate.cv.FoldStore` in memory (the pipeline's is the stage cache)."""

    def __init__(self):
        self.records = {}

    def load(self, fold):
        return self.records.get(fold)

    def save(self, record):
        self.records[record.result.fold] = record


def test_resume_computes_only_the_folds_not_kept_and_gives_the_same_result(spy, caplog):
    """Issue 31: a run that kept folds 1 and 3 (an interrupted run, parallel workers finish out of
    order) fits models on folds 2, 4 and 5 only, and the result equals an uninterrupted run's."""
    win = spy_windows()
    make = lambda: spy(geometry=win.geometry)  # noqa: E731
    full_store = DictStore()
    full = LeaveOneSubjectOut().run(make, win, seed=0, resume=full_store)
    assert sorted(full_store.records) == [f.fold for f in full.folds]  # every computed fold is kept
    store = DictStore()
    store.records = {k: v for k, v in full_store.records.items() if k in ("participant_01", "participant_03")}
    spy.fitted.clear()
    seen = []
    with caplog.at_level("INFO", logger="sphri.evaluate.cv"):
        again = LeaveOneSubjectOut().run(make, win, seed=0, resume=store, on_fold=lambda r, t: seen.append(r.fold))
    assert len(spy.fitted) == 3
    tested = [sorted(set(win.groups[m.predicted_ids_[0]])) for m in spy.fitted]
    assert tested == [["participant_02"], ["participant_04"], ["participant_05"]]
    assert "2 of 5 folds loaded from the cache" in caplog.text and "computing 3" in caplog.text
    assert seen == [f.fold for f in full.folds]  # on_fold still in fold order
    assert [(f.fold, f.accuracy, f.macro_f1) for f in again.folds] == [
        (f.fold, f.accuracy, f.macro_f1) for f in full.folds
    ]
    assert sorted(store.records) == sorted(full_store.records)


def test_a_kept_fold_that_does_not_match_is_recomputed(spy, caplog):
    win = spy_windows()
    store = DictStore()
    full = LeaveOneSubjectOut().run(lambda: spy(), win, seed=0, resume=store)
    wrong = store.records["participant_01"]
    store.records = {"participant_02": type(wrong)(result=wrong.result, wall_s=1.0, cpu_s=1.0)}  # another fold's
    spy.fitted.clear()
    again = LeaveOneSubjectOut().run(lambda: spy(), win, seed=0, resume=store)
    assert len(spy.fitted) == 5 and "does not match this fold" in caplog.text
    assert [f.accuracy for f in again.folds] == [f.accuracy for f in full.folds]


def test_workers_save_their_own_folds():
    """With cv.workers=2 each worker saves the fold it computed (through a store that pickles)."""
    from sphri.cache import StageCache
    from sphri.pipeline import FoldCache

    win = blob_windows(participants=3, repetitions=2, res=4, seed=2)
    make = functools.partial(RandomForest, n_estimators=10, geometry=win.geometry)
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        store = FoldCache(StageCache(tmp), "k" * 20)
        two = LeaveOneSubjectOut(workers=2, threads_per_worker=1).run(make, win, seed=0, resume=store)
        kept = {f.fold: store.load(f.fold) for f in two.folds}
        assert all(r is not None for r in kept.values())
        for f in two.folds:
            assert kept[f.fold].result.accuracy == f.accuracy
            np.testing.assert_array_equal(kept[f.fold].result.confusion, f.confusion)
        assert FoldCache(StageCache(tmp), "j" * 20).load(two.folds[0].fold) is None  # another evaluation's key


class NanAfterFold(SpyModel):
    """Predicts NaN labels (a float model gone non-finite) on the held-out fold named ``bad``."""

    bad = "participant_03"

    def predict(self, x):
        pred = super().predict(x).astype(np.float64)
        held_out = set(np.unique(self.fit_groups_)) if self.fit_groups_ is not None else set()
        if self.bad not in held_out:
            pred[:] = np.nan
        return pred


def test_no_fold_is_recorded_from_non_finite_predictions(spy):
    """A NaN label cast to int64 would be an arbitrary class: the fold stops with one line and neither it
    nor any later fold is kept."""
    from sphri.errors import kind_of
    from sphri.finite import NonFiniteError

    win = spy_windows()
    store = DictStore()
    with pytest.raises(NonFiniteError) as err:
        LeaveOneSubjectOut().run(lambda: NanAfterFold(geometry=win.geometry), win, seed=0, resume=store)
    assert str(err.value).startswith("NanAfterFold predictions of fold participant_03: 24 of 24 values are not finite")
    assert kind_of(err.value) == "numerical error"
    assert sorted(store.records) == ["participant_01", "participant_02"]


def test_forest_refuses_non_finite_features():
    """scikit-learn's forest would take a NaN feature as a missing value and score on."""
    from sphri.finite import NonFiniteError

    win = blob_windows(participants=2, repetitions=1, res=4, seed=0)
    rf = RandomForest(n_estimators=5, geometry=win.geometry)
    feats = rf.transform(win.x)
    feats[3, 7] = np.nan
    with pytest.raises(NonFiniteError, match=r"Random Forest features: 1 of \d+ values are not finite \(1 NaN"):
        rf.fit_features(feats, win.y)
    rf.fit_features(rf.transform(win.x), win.y)
    with pytest.raises(NonFiniteError, match="Random Forest features"):
        rf.predict_features(feats)


def test_fold_results_carry_what_the_model_trained_with():
    """The CNN-GRU's runtime_ (device, precision, why, allocator) rides with each fold, so the run records the
    precision each fold really used (a fallback included), not what a fresh model would pick."""
    from sphri.models.allocator import keep_freed_memory
    from sphri.models.cnn_gru import CnnGru
    from sphri.tracking.mlflow_tracker import fold_runtime

    win = blob_windows(participants=3, repetitions=1, res=4, seed=0)
    make = lambda: CnnGru(  # noqa: E731
        geometry=win.geometry, precision="float32", max_epochs=1, hidden=4, channels=[2, 2, 2], threads=1
    )
    cv = LeaveOneSubjectOut(max_folds=2).run(make, win, seed=0)
    allocator = keep_freed_memory()  # this process's allocator setting, as the folds' fits recorded it
    assert [f.runtime for f in cv.folds] == [
        {
            "device": "cpu",
            "precision": "float32",
            "precision_reason": "chosen (model.precision)",
            "allocator": allocator,
        }
    ] * 2
    assert fold_runtime(cv) == {
        "run.device": "cpu",
        "run.precision": "float32",
        "run.precision_reason": "chosen (model.precision)",
        "run.allocator": allocator,
    }
    cv.folds[1].runtime = {**cv.folds[1].runtime, "precision": "bf16"}
    assert fold_runtime(cv)["run.precision"] == f"float32 (folds {cv.folds[0].fold}); bf16 (folds {cv.folds[1].fold})"
