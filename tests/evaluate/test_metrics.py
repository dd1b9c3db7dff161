"""Fold metrics, bootstrap intervals and the CV summary."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.metrics import accuracy_score, confusion_matrix, f1_score

from sphri.evaluate.metrics import bootstrap_ci, fold_metrics, summarize
from sphri.types import GESTURES, CVResult


def test_fold_metrics_match_sklearn_with_fixed_labels():
    rng = np.random.default_rng(0)
    y = rng.integers(0, 7, size=200)  # grab (7) absent, as for participants 01 and 02
    pred = np.where(rng.random(200) < 0.7, y, rng.integers(0, 8, size=200))
    r = fold_metrics("participant_01", y, pred)
    assert r.fold == "participant_01" and r.n_test == 200
    assert r.confusion.shape == (8, 8) and r.confusion.dtype == np.int64
    np.testing.assert_array_equal(r.confusion, confusion_matrix(y, pred, labels=range(8)))
    assert r.accuracy == pytest.approx(accuracy_score(y, pred))
    assert r.macro_f1 == pytest.approx(f1_score(y, pred, average="macro", zero_division=0))
    assert np.isnan(r.recall[GESTURES.index("grab")])
    for g in range(7):
        assert r.recall[g] == pytest.approx(np.mean(pred[y == g] == g))


def test_fold_metrics_refuse_bad_labels():
    with pytest.raises(ValueError, match="outside"):
        fold_metrics("x", np.array([0, 9]), np.array([0, 1]))
    with pytest.raises(ValueError, match="no test trials"):
        fold_metrics("x", np.array([], dtype=int), np.array([], dtype=int))


def test_bootstrap_ci_brackets_the_mean_and_narrows_with_more_participants():
    rng = np.random.default_rng(1)
    few = rng.normal(0.7, 0.1, size=6)
    many = rng.normal(0.7, 0.1, size=60)
    lo, hi = bootstrap_ci(few, n_boot=2000, seed=3)
    assert lo < few.mean() < hi
    assert (lo, hi) == bootstrap_ci(few, n_boot=2000, seed=3)  # deterministic
    lo2, hi2 = bootstrap_ci(many, n_boot=2000, seed=3)
    assert hi2 - lo2 < hi - lo
    # roughly the normal-theory width for 60 values: 2 * 1.96 * sd / sqrt(n)
    assert (hi2 - lo2) == pytest.approx(2 * 1.96 * many.std(ddof=1) / np.sqrt(60), rel=0.25)
    assert bootstrap_ci([0.5]) == (0.5, 0.5)
    assert all(np.isnan(bootstrap_ci([np.nan])))
    with pytest.raises(ValueError, match="n_boot"):
        bootstrap_ci(few, n_boot=0)


def test_summarize_gives_means_intervals_and_recalls():
    rng = np.random.default_rng(2)
    folds = []
    for p in range(5):
        y = np.arange(40) % 8 if p else np.arange(40) % 7  # first participant without grab
        pred = np.where(rng.random(40) < 0.6 + 0.05 * p, y, (y + 1) % 8)
        folds.append(fold_metrics(f"participant_{p + 1:02d}", y, pred))
    res = CVResult(scheme="loso", model="rf", folds=folds)
    s = summarize(res, n_boot=500, seed=0)
    acc = np.array([f.accuracy for f in folds])
    assert s["accuracy_mean"] == pytest.approx(acc.mean())
    assert s["accuracy_std"] == pytest.approx(acc.std(ddof=1))
    assert s["accuracy_ci_low"] <= s["accuracy_mean"] <= s["accuracy_ci_high"]
    assert s["n_folds"] == 5 and s["n_test"] == 200
    grab = [f.recall[7] for f in folds[1:]]
    assert s["recall_grab"] == pytest.approx(np.mean(grab))
    assert set(f"recall_{g}" for g in GESTURES) <= set(s)
    with pytest.raises(ValueError, match="no folds"):
        summarize(CVResult(scheme="loso", model="rf", folds=[]))
