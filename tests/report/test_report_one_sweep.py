"""The report reads one sweep: a folder holding the jobs of two sweeps is refused with one line, or read
for the sweep a parent run id picks."""

from __future__ import annotations

import pytest
from fake_sweep import make_sweep

from sphri.command import main as sphri_main
from sphri.report.sweep import ReportError, load_sweep
from sphri.tracking.mlflow_tracker import default_uri


def main(argv: list[str]) -> int:
    """``sphri report ARGV``."""
    return sphri_main(["report", *argv])


def test_a_folder_holding_two_sweeps_is_refused_or_read_for_the_parent_named(store, tmp_path, capsys):
    folder = tmp_path / "shared"
    first = make_sweep(store, folder, [2, 3, 4], seed=1)
    second = make_sweep(store, folder, [5, 6], seed=2)  # job folders 0 and 1 rewritten, job 2 the first sweep's
    with pytest.raises(ReportError) as refused:
        load_sweep(folder, output_dir=store)
    msg = str(refused.value)
    assert f"{folder.resolve()} holds the jobs of more than one sweep" in msg and "\n" not in msg
    assert first.parent_id in msg and second.parent_id in msg
    assert main([str(folder), "--output-dir", str(store)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the report reads one sweep only" in err[0], err
    # the parent run id picks one: only its own jobs, the other's named in a note
    picked = load_sweep(second.parent_id, uri=default_uri(store))
    assert sorted(picked.runs["res"]) == [5, 6]
    assert any("belongs to another sweep" in n for n in picked.notes)


def test_two_sweeps_sharing_one_parent_run_are_refused(store, tmp_path):
    """A sweep whose folder and parent run another sweep reopened: one job folder, two jobs' runs."""
    from mlflow.tracking import MlflowClient

    folder = tmp_path / "reopened"
    sweep = make_sweep(store, folder, [2, 3], seed=3)
    client = MlflowClient(default_uri(store))
    parent = client.get_run(sweep.parent_id)
    job = client.search_runs(
        [parent.info.experiment_id], f"tags.`mlflow.parentRunId` = '{sweep.parent_id}' and params.`encoder.res` = '2'"
    )[0]
    tags = {k: v for k, v in job.data.tags.items() if not k.startswith("mlflow.") or k == "mlflow.parentRunId"}
    other = client.create_run(parent.info.experiment_id, tags=tags)
    for k, v in {**job.data.params, "encoder.res": "9"}.items():
        client.log_param(other.info.run_id, k, v)
    client.set_terminated(other.info.run_id)
    with pytest.raises(
        ReportError, match=r"was used by more than one sweep under parent run .*encoder.res=(2 vs 9|9 vs 2)"
    ):
        load_sweep(folder, output_dir=store)
