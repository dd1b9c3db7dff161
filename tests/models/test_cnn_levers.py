"""The CNN-GRU's two adopted cost levers: its fit keeps freed memory in its process (glibc's mallopt), in
every fold process; a job's OpenMP threads sleep instead of spinning (``OMP_WAIT_POLICY=PASSIVE``), in the
job and in its fold processes. Neither changes a number: probabilities are bit-identical with and without."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]

glibc_only = pytest.mark.skipif(
    platform.libc_ver()[0] != "glibc", reason="the allocator setting is glibc's (mallopt); this C library is not"
)

#: Fits a tiny CNN-GRU (threads from argv[2]) in a fresh process, saves its probabilities, then frees and
#: allocates 16 buffers of 1 MiB three times; prints the minor page faults of the last round and runtime_.
FIT_THEN_CHURN = """
import json, resource, sys
import numpy as np
from sphri.models.cnn_gru import CnnGru
from sphri.testing.toy_windows import blob_windows

win = blob_windows(participants=3, repetitions=1, res=4, seed=0)
m = CnnGru(
    geometry=win.geometry, precision="float32", max_epochs=1, hidden=8, channels=[4, 4, 4], threads=int(sys.argv[2])
)
m.fit(win.x, win.y)
np.save(sys.argv[1], m.predict_proba(win.x))

def churn():
    bufs = [np.ones(2**17) for _ in range(16)]
    del bufs

churn(); churn()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
churn()
print(json.dumps({"faults": resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before, "runtime": m.runtime_}))
"""

#: glibc's default trim threshold (128 KiB), fixed: the allocator returns freed memory to the kernel at once.
GLIBC_DEFAULT = {"MALLOC_TRIM_THRESHOLD_": "131072"}


def clean_env(**extra: str) -> dict[str, str]:
    drop = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES", "OMP_WAIT_POLICY", "OMP_DISPLAY_ENV")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    env.update(extra, PYTHONPATH=str(ROOT))
    return env


def fit_in_fresh_process(out: Path, env: dict[str, str]) -> dict:
    proc = subprocess.run(
        [sys.executable, "-c", FIT_THEN_CHURN, str(out), "2"],
        env=clean_env(**env),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    row = json.loads(proc.stdout.strip().splitlines()[-1])
    row["proba"] = np.load(out)
    return row


@pytest.fixture(scope="module")
def fits(tmp_path_factory):
    """The same 2-thread fit in three fresh processes: ``both`` levers (the fit's allocator setting, passive
    OpenMP), ``malloc_default`` (glibc's default forced by the environment), ``spinning`` (OMP ACTIVE)."""
    tmp = tmp_path_factory.mktemp("levers")
    cases = {
        "both": {"OMP_WAIT_POLICY": "PASSIVE"},
        "malloc_default": {**GLIBC_DEFAULT, "OMP_WAIT_POLICY": "PASSIVE"},
        "spinning": {"OMP_WAIT_POLICY": "ACTIVE"},
    }
    return {name: fit_in_fresh_process(tmp / f"{name}.npy", env) for name, env in cases.items()}


@glibc_only
def test_fit_keeps_freed_memory_in_its_process(fits):
    """After a fit, memory freed and allocated again costs no page faults; with glibc's default it does
    (16 buffers of 1 MiB: about 4,096 faults)."""
    kept, default = fits["both"], fits["malloc_default"]
    assert default["faults"] >= 2000, f"glibc's default returned no memory here ({default['faults']} faults)"
    assert kept["faults"] < default["faults"] / 10, (kept["faults"], default["faults"])
    assert kept["runtime"]["allocator"].startswith("glibc keeps freed memory")


@glibc_only
def test_the_environments_allocator_setting_stands_and_is_recorded(fits):
    assert fits["malloc_default"]["runtime"]["allocator"] == "glibc as the environment sets it (MALLOC_TRIM_THRESHOLD_)"


def test_probabilities_are_bit_identical_under_either_lever(fits):
    np.testing.assert_array_equal(fits["both"]["proba"], fits["malloc_default"]["proba"])
    np.testing.assert_array_equal(fits["both"]["proba"], fits["spinning"]["proba"])


@glibc_only
def test_every_fold_process_keeps_freed_memory():
    """Folds in 2 loky processes: each fold's model records that its process keeps freed memory."""
    from sphri.evaluate.cv import LeaveOneSubjectOut
    from sphri.models.cnn_gru import CnnGru
    from sphri.testing.toy_windows import blob_windows

    win = blob_windows(participants=3, repetitions=1, res=4, seed=0)
    make = lambda: CnnGru(  # noqa: E731
        geometry=win.geometry, precision="float32", max_epochs=1, hidden=4, channels=[2, 2, 2], threads=1
    )
    cv = LeaveOneSubjectOut(workers=2, max_folds=2).run(make, win, seed=0)
    assert [f.runtime["allocator"].split(" (")[0] for f in cv.folds] == ["glibc keeps freed memory"] * 2


#: A job's entry point, then torch, then 2 folds in loky processes; OMP_DISPLAY_ENV=verbose makes every
#: process's OpenMP runtime print its settings when torch loads it (GOMP_SPINCOUNT 0: no spinning).
JOB_ENTRY_THEN_FOLDS = """
import sys
from sphri.__main__ import main
sys.argv = ["sphri", "--help"]
main()
from sphri.evaluate.cv import LeaveOneSubjectOut
from sphri.models.cnn_gru import CnnGru
from sphri.testing.toy_windows import blob_windows

win = blob_windows(participants=3, repetitions=1, res=4, seed=0)
make = lambda: CnnGru(geometry=win.geometry, max_epochs=1, hidden=4, channels=[2, 2, 2])
LeaveOneSubjectOut(workers=2, max_folds=2).run(make, win, seed=0)
"""


def spin_counts(env: dict[str, str]) -> list[str]:
    proc = subprocess.run(
        [sys.executable, "-c", JOB_ENTRY_THEN_FOLDS],
        env=clean_env(OMP_DISPLAY_ENV="verbose", **env),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return [line.split("=")[1].strip() for line in proc.stderr.splitlines() if "GOMP_SPINCOUNT" in line]


def test_a_jobs_openmp_threads_sleep_in_the_job_and_its_fold_processes():
    """The job process and both fold processes load OpenMP with a spin count of 0."""
    passive = spin_counts({})
    assert len(passive) >= 3 and set(passive) == {"'0'"}, passive


def test_a_wait_policy_the_environment_sets_stands(monkeypatch):
    from sphri.__main__ import passive_openmp

    monkeypatch.setenv("OMP_WAIT_POLICY", "ACTIVE")
    passive_openmp()
    assert os.environ["OMP_WAIT_POLICY"] == "ACTIVE"
    monkeypatch.delenv("OMP_WAIT_POLICY")
    passive_openmp()
    assert os.environ["OMP_WAIT_POLICY"] == "PASSIVE"
