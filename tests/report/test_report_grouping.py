"""Which jobs make one curve: params that cannot change a result never split one, a point an earlier single
job finished joins the sweep's curve, ``group_by`` chooses the grouping."""

from __future__ import annotations

import os
from pathlib import Path

import forked_cli
import pytest

from sphri.command import main as sphri_main
from sphri.report import load_sweep
from sphri.report.grouping import chosen_keys, group_keys


def main(argv: list[str]) -> int:
    """``sphri report ARGV``."""
    return sphri_main(["report", *argv])


REPO = Path(__file__).resolve().parents[2]


def _jobs(**extra: str) -> list[dict[str, str]]:
    return [{"model": "rf", "layout.res": str(r), "seed": "0", "cv.workers": "1", **extra} for r in (4, 8, 18)]


def test_result_neutral_params_never_split_a_curve():
    jobs = _jobs()
    jobs[2].update({"cv.progress": "True", "plugins": "[]", "run.device": "cpu", "model.n_jobs": "-1"})
    jobs[0]["cv.workers"] = "2"
    assert group_keys(jobs) == []
    jobs[2]["noise.p"] = "0.05"  # a setting that changes the result still does
    assert group_keys(jobs) == ["noise.p"]


def test_group_by_names_the_keys_and_refuses_others():
    jobs = _jobs()
    jobs[2]["cv.progress"] = "True"
    assert chosen_keys(["cv.progress"], jobs) == ["cv.progress"]
    assert chosen_keys(["none"], jobs) == []
    with pytest.raises(ValueError, match=r"'cv.progres' .*did you mean cv.progress\?.*choices: cv.progress, none"):
        chosen_keys(["cv.progres"], jobs)


def test_cli_group_by(two_model_sweep, tmp_path, capsys):
    args = [str(two_model_sweep.sweep_dir), "n_boot=20", "mlflow=false", f"out={tmp_path / 'r'}", "formats=png"]
    assert main([*args, "group_by=modle"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "group_by: 'modle'" in err[0] and "did you mean model" in err[0], err
    assert main([*args, "group_by=none"]) == 0
    out = capsys.readouterr().out
    assert "grouped by nothing (one curve)" in out


def test_the_tour_single_job_then_sweep_then_report_is_one_curve(tmp_path: Path):
    """README's tour: one job at res 18, the sweep over 4,8,18 (res 18 skipped: finished already), the report."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    out, sweep = tmp_path / "outputs", tmp_path / "outputs" / "sweep"
    small = ["+debug=fast", f"output_dir={out}"]
    single = forked_cli.run(["-m", "sphri", "+robot=reachy", "layout.res=18", *small], tmp_path, env)
    assert single.returncode == 0, single.stderr[-3000:]
    multi = forked_cli.run(
        ["-m", "sphri", "-m", "+robot=reachy", "layout.res=4,8,18", *small, f"hydra.sweep.dir={sweep}"],
        tmp_path,
        env,
    )
    assert multi.returncode == 0, multi.stderr[-3000:]
    assert "skipped: MLflow run" in multi.stdout + multi.stderr, "res 18 is the single job's point"
    rep = forked_cli.run(["-m", "sphri", "report", str(sweep), "n_boot=50", "formats=png"], tmp_path, env)
    assert rep.returncode == 0, rep.stderr[-3000:]
    assert "grouped by nothing (one curve)" in rep.stdout, rep.stdout
    assert "joined from earlier jobs outside this sweep" in rep.stdout and "res 18" in rep.stdout
    sw = load_sweep(sweep)
    assert sw.group_keys == [] and sw.runs["group"].nunique() == 1
    assert sorted(sw.runs["res"]) == [4, 8, 18] and sw.runs["joined"].sum() == 1
