"""bench/seed_curves.py: seed means and participant-paired differences from a multirun's job files."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

from seed_curves import curves, dips, load_jobs  # noqa: E402


def fake_sweep(tmp_path: Path) -> tuple[Path, Path, dict]:
    """2 variants x res 8/18/33 x 2 seeds x 3 participants with known accuracies (and one failed job)."""
    sweep, out = tmp_path / "sweep", tmp_path / "outputs"
    acc = {}
    job = 0
    for seed in (0, 1):
        for variant, shift in (("reference", 0.0), ("despeckle200", 0.05)):
            for res, level in ((8, 0.62), (18, 0.58), (33, 0.64)):
                a = np.array([level, level + 0.1, level - 0.1]) + (shift if res == 18 else 0.0) + 0.01 * seed
                acc[(variant, res, seed)] = a
                run = f"run{job}"
                d = sweep / str(job)
                d.mkdir(parents=True)
                (d / "sphri_status.json").write_text(
                    json.dumps(
                        {  # job 0 resumed: skipped, no accuracy field
                            "job": job,
                            "status": "SKIPPED" if job == 0 else "FINISHED",
                            "mlflow_run_id": run,
                            "overrides": [
                                f"seed={seed}",
                                f"sensitivity={variant}",
                                f"layout.res={res}",
                                "experiment=despeckle_compare",
                            ],
                        }
                    )
                )
                art = out / "mlartifacts" / run / "artifacts"
                art.mkdir(parents=True)
                pd.DataFrame({"fold": ["p1", "p2", "p3"], "accuracy": a}).to_csv(
                    art / "per_participant.csv", index=False
                )
                job += 1
    (sweep / str(job)).mkdir()
    (sweep / str(job) / "sphri_status.json").write_text(json.dumps({"status": "FAILED", "overrides": []}))
    return sweep, out, acc


def test_seed_means_and_paired_differences(tmp_path: Path):
    sweep, out, acc = fake_sweep(tmp_path)
    jobs = load_jobs(sweep, out)
    assert len(jobs) == 2 * 3 * 2 * 3
    t = curves(jobs, "sensitivity=reference").set_index(["group", "res"])
    ref18 = t.loc[("sensitivity=reference", 18)]
    assert ref18.n_seeds == 2
    assert ref18.accuracy_mean == pytest.approx(np.mean([acc[("reference", 18, s)].mean() for s in (0, 1)]))
    assert ref18.seed_se == pytest.approx(0.005)  # seed means 0.58 and 0.59
    d18 = t.loc[("sensitivity=despeckle200", 18)]
    assert d18["vs_sensitivity=reference"] == pytest.approx(0.05) and d18[
        "vs_sensitivity=reference_se"
    ] == pytest.approx(0.0)
    assert t.loc[("sensitivity=despeckle200", 8)]["vs_sensitivity=reference"] == pytest.approx(0.0)
    lines = {line.split(":")[0]: line for line in dips(jobs)}
    assert "res 8 - res 18 = +0.040" in lines["sensitivity=reference"]
    assert "res 33 - res 18 = +0.060" in lines["sensitivity=reference"]
    assert "res 8 - res 18 = -0.010" in lines["sensitivity=despeckle200"]
