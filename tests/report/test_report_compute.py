"""The report's compute table: where and how long each curve ran, from the jobs' stage times."""

from __future__ import annotations

import time

import pandas as pd
import pytest
from fake_sweep import make_sweep
from mlflow.entities import Metric
from mlflow.tracking import MlflowClient

from sphri.report import RuleSettings, load_sweep, make_report
from sphri.tracking.machine import cpu

RULE = RuleSettings(n_boot=50, seed=0)


def test_stage_times_are_summed_per_curve_and_the_machine_is_named(store, tmp_path):
    truth = make_sweep(store, tmp_path / "resumed", [2, 6, 18], models=["rf", "cnn_gru"], n_participants=3)
    client = MlflowClient(tracking_uri=truth.uri)
    runs = load_sweep(truth.sweep_dir).runs
    evaluate = {("rf", 2): 60, ("rf", 6): 90, ("rf", 18): 120, ("cnn_gru", 2): 600, ("cnn_gru", 6): 900}
    evaluate[("cnn_gru", 18)] = 3000
    now = int(time.time() * 1000)
    for row in runs.itertuples():  # the fake jobs log time/contact_s = 0.1; the stage times below are added
        stages = {"time/evaluate_s": evaluate[(row.model, row.res)], "time/encode_s": 30.0}
        client.log_batch(row.run_id, metrics=[Metric(k, float(v), now, 0) for k, v in stages.items()])
    # an interrupted attempt of the cnn_gru job at res 18 (resumed later): noted, not counted as a job
    resumed = runs[(runs["model"] == "cnn_gru") & (runs["res"] == 18)].iloc[0]
    exp = client.get_run(resumed.run_id).info.experiment_id
    killed = client.create_run(
        exp, tags={"mlflow.parentRunId": truth.parent_id, "sphri.config_hash": resumed.config_hash}
    )
    client.set_terminated(killed.info.run_id, "KILLED")
    other = client.create_run(exp, tags={"mlflow.parentRunId": truth.parent_id, "sphri.config_hash": "never-done"})
    client.set_terminated(other.info.run_id, "KILLED")

    report, files, text = make_report(
        truth.sweep_dir, rule=RULE, out_dir=tmp_path / "rep", log_to_mlflow=False, formats=("png",)
    )
    table = pd.read_csv(files.tables["compute"]).set_index("group")
    assert table.loc["cnn_gru", "total_h"] == pytest.approx((600 + 900 + 3000 + 3 * 30.1) / 3600, rel=1e-5)
    assert table.loc["cnn_gru", "slowest_res"] == 18
    assert table.loc["cnn_gru", "slowest_h"] == pytest.approx(3030.1 / 3600, rel=1e-5)
    assert table.loc["rf", "total_h"] == pytest.approx((270 + 3 * 30.1) / 3600, rel=1e-5)
    assert (table["jobs"] == 3).all() and (table["jobs_from_cache"] == 0).all()
    here = cpu()
    assert f"{here['cpu_model']} ({here['cpu_count']} CPUs)" in table.loc["rf", "machines"]
    assert any("1 interrupted attempt(s) of jobs that finished later" in n for n in report.notes)
    assert any("1 job(s) not finished (KILLED): left out" in n for n in report.notes)
    assert "[compute: where and how long each curve ran]" in text
    line = next(s for s in text.splitlines() if s.strip().startswith("cnn_gru: 3 jobs"))
    assert "1.28 h wall summed over jobs' stages" in line
    assert "slowest res 18 (50.5 min)" in line and here["cpu_model"] in line
    page = files.html.read_text()
    assert 'id="compute"' in page and "compute.csv" in page
