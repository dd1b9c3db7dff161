"""Resume by fold (issue 31): a CNN-GRU job killed mid-way recomputes only its missing folds.

A real kill: the job runs in its own process group, which gets SIGKILL as soon as the first
finished fold's entry appears in the cache (``<cache>/evaluate_fold/``), folds still to come.
The rerun of the same command must say how many folds it loaded and compute only the others,
and its evaluation (entry key and every fold's numbers) must equal an uninterrupted run's.
Folds are made slow enough to be caught mid-way by training more epochs (3 participants leave
2 to train on, too few for early stopping: every fold trains all ``model.max_epochs``), and run
with one thread each, so that serial folds and ``cv.workers=2`` give bit-identical numbers.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import forked_cli
import numpy as np
import pytest

from sphri.cache import read_entry
from sphri.types import CVResult, RunMeta

ARGS = [
    "+debug=fast",
    "model=cnn_gru",
    "layout.res=4",
    "model.max_epochs=10",
    "cv.threads_per_worker=1",
    "tracking.enabled=false",
]
N_FOLDS = 3  # +debug=fast: 3 participants, leave-one-subject-out


def _cmd(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "sphri", *ARGS, f"output_dir={out}", *extra]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1", "HYDRA_FULL_ERROR": "1"}


def _run(out: Path, *extra: str) -> str:
    proc = forked_cli.run(_cmd(out, *extra)[1:], out.parent, _env(), 600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout + proc.stderr


def _evaluation(out: Path) -> tuple[str, CVResult]:
    (entry,) = (out / "cache" / "evaluate").glob("*.entry")
    _, (cv, _meta) = read_entry(entry, contract=(CVResult, RunMeta))
    return entry.stem, cv


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[Path, str, CVResult]:
    """An uninterrupted run: its cache (upstream stages reused by the killed runs) and evaluation."""
    out = tmp_path_factory.mktemp("reference") / "out"
    out.parent.mkdir(exist_ok=True)
    _run(out)
    assert not list((out / "cache").glob("evaluate_fold/*.entry")), (
        "fold entries are removed once the evaluation is stored"
    )
    key, cv = _evaluation(out)
    assert len(cv.folds) == N_FOLDS
    return out, key, cv


def _kill_after_first_fold(out: Path, *extra: str) -> int:
    """Start the job, SIGKILL its process group (loky workers included) once a fold entry exists;
    returns how many fold entries the dead job left."""
    folds = out / "cache" / "evaluate_fold"
    log = (out.parent / "killed.log").open("w")
    proc = subprocess.Popen(
        _cmd(out, *extra), cwd=out.parent, env=_env(), stdout=log, stderr=subprocess.STDOUT, start_new_session=True
    )
    try:
        deadline = time.monotonic() + 600
        while not list(folds.glob("*.entry")):
            assert proc.poll() is None, (
                "the job ended before any fold was kept: " + (out.parent / "killed.log").read_text()[-3000:]
            )
            assert time.monotonic() < deadline, "no fold finished in 600 s"
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)
        log.close()
    time.sleep(0.5)  # nothing of the killed group can still be writing
    assert not list((out / "cache").glob("evaluate/*.entry")), "the killed job must not have stored its evaluation"
    return len(list(folds.glob("*.entry")))


# serial folds in `make test-all` only: the loky workers' kill (the harder case) runs in `make test`
@pytest.mark.parametrize("workers", [pytest.param(1, marks=pytest.mark.slow), 2])
def test_a_killed_cnn_gru_job_recomputes_only_its_missing_folds(reference, tmp_path: Path, workers: int):
    ref_out, ref_key, ref_cv = reference
    out = tmp_path / "out"
    out.mkdir()
    # the upstream stages from the reference's cache: only the evaluation is computed here
    shutil.copytree(ref_out / "cache", out / "cache", ignore=shutil.ignore_patterns("evaluate", "evaluate_fold"))
    kept = _kill_after_first_fold(out, f"cv.workers={workers}")
    assert 1 <= kept < N_FOLDS, f"the kill came after {kept} of {N_FOLDS} folds: not mid-way"
    log = _run(out, f"cv.workers={workers}")
    assert f"{kept} of {N_FOLDS} folds loaded from the cache" in log, log[-3000:]
    assert f"computing {N_FOLDS - kept}" in log
    key, cv = _evaluation(out)
    assert key == ref_key, "fold entries must not change the evaluate stage's key"
    assert [f.fold for f in cv.folds] == [f.fold for f in ref_cv.folds]
    for a, b in zip(cv.folds, ref_cv.folds):
        assert (a.accuracy, a.macro_f1, a.n_test) == (b.accuracy, b.macro_f1, b.n_test), a.fold
        np.testing.assert_array_equal(a.confusion, b.confusion)
    assert not list((out / "cache").glob("evaluate_fold/*.entry")), "kept folds are removed with the evaluation stored"
