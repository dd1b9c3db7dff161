"""A sweep folder holds one sweep: one running now is refused (a lock a real second process holds), and a
sweep with other jobs is refused where another sweep's jobs are kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import forked_cli
import pytest

from sphri.tracking.parent import LOCK_FILE, SweepDirInUse, claim_sweep_dir

REPO = Path(__file__).resolve().parent.parent
HOLD = """
import sys, time
from sphri.tracking.parent import claim_sweep_dir
claim = claim_sweep_dir(sys.argv[1], [["layout.res=2"]], sys.argv[2])
print("held", flush=True)
time.sleep(120)
"""


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(REPO)}


@pytest.fixture
def held(tmp_path: Path):
    """A second process holding the sweep folder's lock: ``(sweep folder, output folder, its pid)``."""
    sweep_dir, out = tmp_path / "sweeps" / "s", tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(sweep_dir), str(out)], env=_env(), stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
        yield sweep_dir, out, proc.pid
    finally:
        proc.kill()
        proc.wait(30)


def test_a_sweep_folder_another_process_holds_is_refused_naming_the_folder_and_holder(held, tmp_path: Path):
    sweep_dir, out, pid = held
    with pytest.raises(SweepDirInUse) as refused:
        claim_sweep_dir(sweep_dir, [["layout.res=2"]], out)
    msg = str(refused.value)
    assert f"hydra.sweep.dir={sweep_dir} is in use by another sweep" in msg and f"pid {pid} (" in msg, msg
    assert "\n" not in msg
    # the command line: one line, exit 1, no job started
    proc = _sweep(tmp_path, out, sweep_dir, "layout.res=2,3", 300)
    assert proc.returncode == 1, (proc.stdout + proc.stderr)[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"pid {pid} (" in lines[0] and str(sweep_dir) in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (sweep_dir / "0").exists() and not (out / "mlflow.db").exists(), "no job started"


def test_the_lock_goes_with_its_holder(held, tmp_path: Path):
    """The lock is the OS's (flock): once its holder is gone, however it ended, the folder is free."""
    sweep_dir, out, pid = held
    os.kill(pid, 9)
    deadline = time.time() + 30
    while time.time() < deadline:
        try:
            claim = claim_sweep_dir(sweep_dir, [["layout.res=2"]], out)
            break
        except SweepDirInUse:
            time.sleep(0.1)
    else:
        raise AssertionError("the lock outlived its holder")
    assert f"pid {os.getpid()} (" in (sweep_dir / LOCK_FILE).read_text()
    claim.release()


def _legacy_statuses(sweep_dir: Path, jobs: list[list[str]]) -> None:
    """Job status files as a sweep leaves them (read when its sweep file records no jobs)."""
    for i, job in enumerate(jobs):
        (sweep_dir / str(i)).mkdir(parents=True)
        status = {"job": i, "status": "FINISHED", "error": None, "mlflow_run_id": None, "overrides": job}
        (sweep_dir / str(i) / "sphri_status.json").write_text(json.dumps(status))
    (sweep_dir / "sphri_sweep.json").write_text(json.dumps({"n_jobs": len(jobs), "started": 0.0}))


def _recorded(sweep_dir: Path, jobs: list[list[str]], out: Path) -> None:
    """The sweep file a sweep writes when it starts: its jobs and output folder."""
    sweep_dir.mkdir(parents=True)
    info = {"n_jobs": len(jobs), "started": 0.0, "jobs": jobs, "output_dir": str(out.resolve())}
    (sweep_dir / "sphri_sweep.json").write_text(json.dumps(info))


def _sweep(tmp_path: Path, out: Path, sweep_dir: Path, grid: str, timeout: int):
    """``python -m sphri -m +debug=fast GRID`` into ``sweep_dir`` (serial launcher), as a user types it."""
    args = ["-m", "sphri", "-m", "+debug=fast", grid, f"output_dir={out}", "hydra/launcher=serial"]
    return forked_cli.run([*args, f"hydra.sweep.dir={sweep_dir}"], tmp_path, _env(), timeout)


@pytest.mark.parametrize("left", ["recorded", "statuses"])
def test_a_sweep_with_other_jobs_into_a_used_folder_is_refused_before_any_job(tmp_path: Path, left: str):
    sweep_dir, out = tmp_path / "sweeps" / "s", tmp_path / "out"
    first = [["debug=fast", "layout.res=2"], ["debug=fast", "layout.res=3"]]
    if left == "recorded":
        _recorded(sweep_dir, first, out)
    else:
        _legacy_statuses(sweep_dir, first)
    before = {p: p.read_bytes() for p in sweep_dir.rglob("*") if p.is_file()}
    proc = _sweep(tmp_path, out, sweep_dir, "layout.res=4,5", 600)
    assert proc.returncode == 1, (proc.stdout + proc.stderr)[-3000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert f"hydra.sweep.dir={sweep_dir} holds another sweep" in lines[0]
    assert "its job #0 ran debug=fast layout.res=2, this sweep's job #0 is debug=fast layout.res=4" in lines[0]
    after = {p: p.read_bytes() for p in sweep_dir.rglob("*") if p.is_file() and p.name != LOCK_FILE}
    assert after == before, "the first sweep's files are untouched"
    assert not (out / "mlflow.db").exists()


def test_the_same_sweep_again_keeps_its_folder(tmp_path: Path):
    """A rerun with other runtime settings (or the overrides in another order) is the same sweep; another
    count of jobs or another output folder is not."""
    sweep_dir, out = tmp_path / "s", tmp_path / "out"
    _recorded(sweep_dir, [["debug=fast", "layout.res=2"], ["debug=fast", "layout.res=3"]], out)
    again = [["layout.res=2", "debug=fast", "cv.workers=2", "hydra/launcher=serial"], ["debug=fast", "layout.res=3"]]
    claim_sweep_dir(sweep_dir, again, out).release()
    with pytest.raises(SweepDirInUse, match=r"holds another sweep \(2 jobs, this sweep 3\)"):
        claim_sweep_dir(sweep_dir, [*again, ["debug=fast", "layout.res=4"]], out)
    with pytest.raises(SweepDirInUse, match=r"holds a sweep recorded in output_dir=.*out, not .*elsewhere"):
        claim_sweep_dir(sweep_dir, again, tmp_path / "elsewhere")
    claim_sweep_dir(tmp_path / "new", again, out).release()  # a new folder: nothing to compare
