"""bench/bf16_parity.py: bf16 against float32 on the same (seed, fold) pairs, read from an MLflow store."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

from bf16_parity import collect, compare  # noqa: E402


def _store(out: Path, accuracy: dict[tuple[str, int], list[float]]) -> None:
    """A store with one FINISHED CNN-GRU job per (precision, seed), its fold accuracies as MLflow logs them."""
    from mlflow.entities import Metric, Param
    from mlflow.tracking import MlflowClient

    from sphri.tracking.mlflow_tracker import default_uri

    client = MlflowClient(default_uri(out))
    exp = client.create_experiment("sphri")
    now = int(time.time() * 1000)
    for (precision, seed), folds in accuracy.items():
        run = client.create_run(exp, tags={"sphri.kind": "job", "sphri.machine.cpu_model": "test CPU"})
        params = {"model": "cnn_gru", "layout.res": "18", "run.precision": precision, "model.seed": str(seed)}
        metrics = [Metric("fold_accuracy", a, now, i) for i, a in enumerate(folds)]
        metrics += [Metric("fold_macro_f1", a - 0.1, now, i) for i, a in enumerate(folds)]
        client.log_batch(run.info.run_id, metrics=metrics, params=[Param(k, v) for k, v in params.items()])
        client.set_terminated(run.info.run_id, "FINISHED")
    other = client.create_run(exp, tags={"sphri.kind": "job"})  # an RF job at the same resolution: left out
    client.log_batch(other.info.run_id, params=[Param("model", "rf"), Param("layout.res", "18")])
    client.set_terminated(other.info.run_id, "FINISHED")


def test_paired_difference_and_seed_spread(tmp_path: Path):
    f32 = {0: [0.60, 0.50, 0.70], 1: [0.64, 0.56, 0.72]}  # seed means 0.600 and 0.640: gap 0.04
    _store(
        tmp_path,
        {
            ("float32", 0): f32[0],
            ("float32", 1): f32[1],
            ("bf16", 0): [a + 0.01 for a in f32[0]],  # +0.01 on every fold: inside the gap
            ("bf16", 1): [a + 0.01 for a in f32[1]],
        },
    )
    result = compare(collect(tmp_path, 18))
    acc = result["metrics"]["accuracy"]
    assert result["seeds"] == [0, 1] and acc["n_pairs"] == 6
    assert acc["paired_mean_diff"] == pytest.approx(0.01) and acc["paired_ci95"] == pytest.approx([0.01, 0.01])
    assert acc["largest_float32_seed_gap"] == pytest.approx(0.04) and acc["within_seed_spread"]
    assert acc["float32"]["seed_means"] == pytest.approx([0.6, 0.64])
    assert result["machine"]["bf16"]["sphri.machine.cpu_model"] == "test CPU"


def test_a_shift_larger_than_the_seed_gap_is_not_within(tmp_path: Path):
    _store(
        tmp_path,
        {
            ("float32", 0): [0.60, 0.50, 0.70],
            ("float32", 1): [0.61, 0.51, 0.71],
            ("bf16", 0): [0.50, 0.40, 0.60],
            ("bf16", 1): [0.51, 0.41, 0.61],
        },
    )
    assert not compare(collect(tmp_path, 18))["metrics"]["accuracy"]["within_seed_spread"]


def test_one_seed_gives_the_paired_difference_but_no_verdict(tmp_path: Path):
    _store(tmp_path, {("float32", 0): [0.60, 0.50, 0.70], ("bf16", 0): [0.50, 0.40, 0.60]})
    acc = compare(collect(tmp_path, 18))["metrics"]["accuracy"]
    assert acc["paired_mean_diff"] == pytest.approx(-0.1) and acc["within_seed_spread"] is None


def test_no_seed_in_both_precisions_is_one_line(tmp_path: Path):
    _store(tmp_path, {("float32", 0): [0.6, 0.5]})
    with pytest.raises(SystemExit, match="no seed has a finished job in both precisions"):
        compare(collect(tmp_path, 18))
    with pytest.raises(SystemExit, match="no MLflow store at"):
        collect(tmp_path / "elsewhere", 18)
