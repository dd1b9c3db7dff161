"""The benchmarks' shortcuts measure what they claim.

- bench_stability fits its forests on features computed once per
  resolution: the same fold accuracies as the pipeline's Random Forest on
  the windows.
- Its repetition subsets take each participant's first R trials of every
  gesture.
- bench_pipeline's stage probe times a stage without its upstream stages.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

from bench_pipeline import STAGES, MemoryProbe, StageProbe, compose_cfg  # noqa: E402
from bench_scaling import loglog_slope  # noqa: E402
from bench_stability import FeatureForest, feature_windows, repetition_rank  # noqa: E402

from sphri.evaluate.cv import LeaveOneSubjectOut  # noqa: E402
from sphri.models.rf import RandomForest  # noqa: E402
from sphri.testing.toy_windows import blob_windows  # noqa: E402


def test_precomputed_features_give_the_pipelines_fold_accuracies():
    windows = blob_windows(participants=3, repetitions=3, res=6, length=20, seed=1)
    params = dict(n_estimators=15, seed=3, n_jobs=1)
    direct = LeaveOneSubjectOut(progress=False).run(lambda: RandomForest(geometry=windows.geometry, **params), windows)
    feats = RandomForest(geometry=windows.geometry).transform(windows.x)
    rows = np.arange(len(windows.y))
    shortcut = LeaveOneSubjectOut(progress=False).run(
        lambda: FeatureForest(**params), feature_windows(windows, feats, rows)
    )
    assert [f.fold for f in direct.folds] == [f.fold for f in shortcut.folds]
    for a, b in zip(direct.folds, shortcut.folds):
        assert a.accuracy == b.accuracy
        np.testing.assert_array_equal(a.confusion, b.confusion)
    with pytest.raises(ValueError, match="precomputed"):
        FeatureForest().transform(windows.x)


def test_repetition_rank_counts_within_participant_and_gesture():
    trials = pd.DataFrame(
        {
            "participant": ["a", "a", "a", "b", "a", "b"],
            "gesture": ["hit", "pat", "hit", "hit", "hit", "hit"],
            "trial_ordinal": [1, 2, 3, 1, 4, 2],
        }
    )
    assert repetition_rank(trials).tolist() == [0, 0, 1, 0, 2, 1]


def test_stage_probe_times_are_exclusive(tmp_path):
    from sphri.cache import StageCache
    from sphri.pipeline import make_pipeline

    cfg = compose_cfg(2, 1, 4)
    probe = StageProbe(MemoryProbe())
    p = probe.install(make_pipeline(cfg, StageCache(root=tmp_path)))
    p.get("evaluate")  # asks for everything upstream, nested
    assert set(probe.stats) == set(STAGES)
    assert all(s["wall_s"] >= 0 and s["peak_rss_mb"] > 0 for s in probe.stats.values())
    assert all(s["source"] == "computed" for s in probe.stats.values())
    # the pipeline's own records are exclusive too: each stage's time without its upstream stages
    for name, stat in probe.stats.items():
        assert p.records[name].seconds == pytest.approx(stat["wall_s"], rel=0.05, abs=0.02), name
    assert p.records["evaluate"].seconds < sum(r.seconds for r in p.records.values())


def test_loglog_slope_of_linear_and_quadratic_growth():
    x = np.array([10.0, 100.0, 1000.0])
    assert loglog_slope(x, 0.5 * x)["slope"] == pytest.approx(1.0)
    assert loglog_slope(x, 1e-3 * x**2)["slope_top"] == pytest.approx(2.0)
    fit = loglog_slope(x, 2.0 + 0.01 * x)
    assert fit["overhead_s"] == pytest.approx(2.0) and fit["per_unit_s"] == pytest.approx(0.01)
