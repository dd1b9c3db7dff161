"""The report's compute table: where and how long each curve ran, interrupted attempts included."""

from __future__ import annotations

import pandas as pd
import pytest
from fake_sweep import make_sweep
from mlflow.tracking import MlflowClient

from sphri.report import RuleSettings, load_sweep, make_report
from sphri.tracking.machine import cpu

RULE = RuleSettings(n_boot=50, seed=0)
HOUR_MS = 3_600_000


def _set_times(client: MlflowClient, run_id: str, start_ms: int, seconds: float, status: str) -> None:
    """Give a run a known wall time: MLflow keeps start_time from creation, so the end is moved."""
    run = client.get_run(run_id)
    assert run.info.start_time is not None
    client.set_terminated(run_id, status, end_time=int(run.info.start_time + seconds * 1000))


def test_a_resumed_job_counts_its_interrupted_attempt_and_the_machine_is_named(store, tmp_path):
    truth = make_sweep(store, tmp_path / "resumed", [2, 6, 18], models=["rf", "cnn_gru"], n_participants=3)
    client = MlflowClient(tracking_uri=truth.uri)
    runs = load_sweep(truth.sweep_dir).runs
    walls = {("rf", 2): 60, ("rf", 6): 90, ("rf", 18): 120, ("cnn_gru", 2): 600, ("cnn_gru", 6): 900}
    walls[("cnn_gru", 18)] = 1200
    for row in runs.itertuples():
        _set_times(client, row.run_id, row.start_time, walls[(row.model, row.res)], "FINISHED")
    # the cnn_gru job at res 18 was killed once after 30 min, then resumed and finished in another run
    resumed = runs[(runs["model"] == "cnn_gru") & (runs["res"] == 18)].iloc[0]
    exp = client.get_run(resumed.run_id).info.experiment_id
    killed = client.create_run(
        exp,
        tags={"mlflow.parentRunId": truth.parent_id, "sphri.config_hash": resumed.config_hash, "sphri.kind": "job"},
    )
    _set_times(client, killed.info.run_id, killed.info.start_time, 1800, "KILLED")
    # and a job of another config that never finished stays left out, its time in no row
    other = client.create_run(
        exp, tags={"mlflow.parentRunId": truth.parent_id, "sphri.config_hash": "hash-never-finished"}
    )
    _set_times(client, other.info.run_id, other.info.start_time, 999, "KILLED")

    report, files, text = make_report(
        truth.sweep_dir, rule=RULE, out_dir=tmp_path / "rep", log_to_mlflow=False, formats=("png",)
    )
    table = pd.read_csv(files.tables["compute"]).set_index("group")
    assert table.loc["cnn_gru", "earlier_attempts_h"] == pytest.approx(0.5)
    assert table.loc["cnn_gru", "total_h"] == pytest.approx((600 + 900 + 1200 + 1800) / 3600)
    assert table.loc["cnn_gru", "slowest_res"] == 18 and table.loc["cnn_gru", "slowest_h"] == pytest.approx(
        (1200 + 1800) / 3600
    )
    assert table.loc["rf", "total_h"] == pytest.approx(270 / 3600) and table.loc["rf", "earlier_attempts_h"] == 0
    assert (table["jobs"] == 3).all() and (table["jobs_from_cache"] == 0).all()
    here = cpu()
    assert f"{here['cpu_model']} ({here['cpu_count']} CPUs)" in table.loc["rf", "machines"]
    assert any("1 interrupted attempt(s) of jobs that finished later" in n for n in report.notes)
    assert any("1 job(s) not finished (KILLED): left out" in n for n in report.notes)
    assert "[compute: where and how long each curve ran]" in text
    line = next(s for s in text.splitlines() if s.strip().startswith("cnn_gru: 3 jobs"))
    assert "1.25 h wall summed over jobs, 30.0 min of it in interrupted attempts" in line
    assert "slowest res 18 (50.0 min)" in line and here["cpu_model"] in line
    page = files.html.read_text()
    assert 'id="compute"' in page and "compute.csv" in page
