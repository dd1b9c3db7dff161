"""bench/cnn_gru_noise_check.py: per-point fold means and SDs, paired differences, refusal of a split point."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

from cnn_gru_noise_check import load, summarize  # noqa: E402


def write_job(
    sweep: Path, out: Path, job: int, overrides: list[str], parts: list[str], acc: list[float], status: str = "FINISHED"
) -> None:
    d = sweep / str(job)
    d.mkdir(parents=True)
    run = f"{sweep.name}-run{job}"
    (d / "sphri_status.json").write_text(
        json.dumps(
            {
                "job": job,
                "status": status,
                "mlflow_run_id": run,
                "overrides": overrides,
                "seconds": 10.0 + job,
                "from_cache": False,
            }
        )
    )
    art = out / "mlartifacts" / run / "artifacts"
    art.mkdir(parents=True)
    pd.DataFrame({"fold": parts, "accuracy": acc, "macro_f1": np.asarray(acc) - 0.05}).to_csv(
        art / "per_participant.csv", index=False
    )


def test_points_and_paired_differences(tmp_path: Path):
    out = tmp_path / "outputs"
    a, b = tmp_path / "a", tmp_path / "b"
    # sweep a: res 8 and 18, 3 folds, both noises; sweep b: res 50 on 2 folds (another cv.max_folds)
    vals = {
        ("salt_pepper", 8): [0.6, 0.3, 0.5],
        ("salt_pepper", 18): [0.5, 0.2, 0.5],
        ("none", 8): [0.7, 0.5, 0.6],
        ("none", 18): [0.8, 0.6, 0.7],
    }
    for j, ((noise, res), acc) in enumerate(vals.items()):
        write_job(
            a,
            out,
            j,
            ["model=cnn_gru", f"layout.res={res}", f"noise={noise}", "cv.max_folds=3"],
            ["p1", "p2", "p3"],
            acc,
        )
    write_job(
        b, out, 0, ["model=cnn_gru", "layout.res=50", "noise=salt_pepper", "cv.max_folds=2"], ["p1", "p2"], [0.9, 0.2]
    )
    write_job(
        b, out, 1, ["model=cnn_gru", "layout.res=50", "noise=none"], ["p1", "p2"], [0.1, 0.1], status="FAILED"
    )  # a failed job is left out
    df, jobs = load([a, b], out)
    s = summarize(df, jobs)
    pts = {(p["noise"], p["res"]): p for p in s["points"]}
    assert set(pts) == set(vals) | {("salt_pepper", 50)}
    p = pts[("salt_pepper", 8)]
    assert p["n_folds"] == 3 and p["accuracy_mean"] == pytest.approx(1.4 / 3)
    assert p["accuracy_sd"] == pytest.approx(np.std([0.6, 0.3, 0.5], ddof=1))
    assert p["macro_f1_mean"] == pytest.approx(p["accuracy_mean"] - 0.05)
    assert pts[("salt_pepper", 50)]["n_folds"] == 2
    d = {(x["noise"], x["diff"]): x for x in s["paired_differences"]}
    assert d[("salt_pepper", "res 8 - res 18")]["mean"] == pytest.approx(0.2 / 3)  # +0.1, +0.1, 0: res 18 below
    assert d[("none", "res 8 - res 18")]["mean"] == pytest.approx(-0.1)
    assert d[("none", "res 8 - res 18")]["sd"] == pytest.approx(0.0, abs=1e-12)
    r50 = d[("salt_pepper", "res 50 - res 18")]  # paired over the 2 participants both points hold
    assert r50["n_participants"] == 2 and r50["per_participant"] == pytest.approx([0.4, 0.0])
    noise8 = d[("salt_pepper - none", "res 8")]
    assert noise8["mean"] == pytest.approx(-0.4 / 3) and noise8["n_participants"] == 3  # -0.1, -0.2, -0.1
    assert ("salt_pepper - none", "res 50") not in d  # no clean res-50 point to pair with


def test_two_jobs_of_one_point_are_refused(tmp_path: Path):
    out = tmp_path / "outputs"
    a, b = tmp_path / "a", tmp_path / "b"
    for sweep in (a, b):
        write_job(sweep, out, 0, ["model=rf", "layout.res=8", "noise=none"], ["p1"], [0.5])
    with pytest.raises(SystemExit, match="two jobs for model=rf noise=none res=8"):
        load([a, b], out)
