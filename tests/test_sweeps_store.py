"""Concurrent first runs share one MLflow store; sweeps are validated first and always end their parent run."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import forked_cli
import pytest
from sweeper_jobs import hydras_own, plain_task, sweeper

from sphri.tracking.mlflow_tracker import PARENT_FILE, default_uri

REPO = Path(__file__).resolve().parent.parent


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1"}


def _sphri(args: list[str], cwd: Path, timeout: int = 600) -> subprocess.CompletedProcess:
    return forked_cli.run(["-m", "sphri", *args], cwd, _env(), timeout)


def _runs(out: Path, kind: str | None = None) -> list:
    from mlflow.tracking import MlflowClient

    client = MlflowClient(default_uri(out))
    exp = client.get_experiment_by_name("sphri-debug")
    runs = client.search_runs([exp.experiment_id]) if exp else []
    return [r for r in runs if kind is None or r.data.tags.get("sphri.kind") == kind]


# ------------------------------------------------------------------ the store
def test_four_concurrent_first_runs_share_one_new_store(tmp_path: Path):
    """Four first runs at once into one new output_dir (four processes, forked together so they reach the
    new store together): all finish, four runs in the store."""
    out = tmp_path / "race"
    args = [
        "-m",
        "sphri",
        "+debug=fast",
        "layout.res=2",
        "data.participants=2",
        "data.repetitions=1",
        f"output_dir={out}",
    ]
    # four different experiments (seeds): the same one four times would be recorded once
    started = [forked_cli.start([*args, f"seed={i}"], tmp_path, _env()) for i in range(4)]  # four processes at once
    for done in [s.wait(600) for s in started]:
        assert done.returncode == 0, (done.stdout + done.stderr)[-3000:]
    jobs = _runs(out, "job")
    assert len(jobs) == 4 and all(r.info.status == "FINISHED" for r in jobs)
    from sphri.tracking.store import problems

    assert problems(out / "mlflow.db") == []


def _schema(db: Path) -> tuple[list, list]:
    """Tables, indexes and triggers with their definitions, and the schema revision. A definition is compared
    as the set of its lines: two runs of MLflow's own migrations can list a table's constraints in another order."""
    with sqlite3.connect(db) as con:
        rows = con.execute("SELECT type, name, sql FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'").fetchall()
        revision = con.execute("SELECT version_num FROM alembic_version").fetchall()
    lines = lambda sql: sorted(x.strip().rstrip(",").strip() for x in (sql or "").splitlines())  # noqa: E731
    return sorted((kind, name, lines(sql)) for kind, name, sql in rows), revision


def test_new_stores_start_from_a_migrated_template_equal_to_a_fresh_migration(tmp_path, monkeypatch):
    from mlflow.tracking import MlflowClient

    from sphri.tracking.store import ensure_store, problems, template_path

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SPHRI_STORE_TEMPLATE", "0")
    ensure_store(f"sqlite:///{tmp_path / 'fresh' / 'mlflow.db'}")  # MLflow's own migrations
    assert not template_path().exists()
    monkeypatch.setenv("SPHRI_STORE_TEMPLATE", "1")
    for name in ("first", "second"):
        ensure_store(f"sqlite:///{tmp_path / name / 'mlflow.db'}")
    assert template_path().is_file() and str(template_path()).startswith(str(tmp_path / "cache" / "sphri"))
    with sqlite3.connect(template_path()) as con:
        assert con.execute("SELECT count(*) FROM experiments").fetchone() == (0,), "the template holds no experiment"
    fresh = _schema(tmp_path / "fresh" / "mlflow.db")
    for name in ("first", "second"):
        db = tmp_path / name / "mlflow.db"
        assert _schema(db) == fresh and problems(db) == []
        client = MlflowClient(f"sqlite:///{db}")
        default = client.get_experiment("0")  # re-created by MLflow where the store is first opened
        assert default.name == "Default" and default.artifact_location.endswith(str(tmp_path / "mlruns" / "0"))
        run = client.create_run(client.create_experiment("x", artifact_location=str(tmp_path / name / "art")))
        client.set_terminated(run.info.run_id)
    # a template that cannot be made (an unwritable cache) falls back to migrating the store itself
    monkeypatch.setenv("XDG_CACHE_HOME", "/proc/sphri-no-such-cache")
    ensure_store(f"sqlite:///{tmp_path / 'fallback' / 'mlflow.db'}")
    assert _schema(tmp_path / "fallback" / "mlflow.db") == fresh


def test_store_left_broken_by_a_migration_is_refused_before_computing(tmp_path: Path):
    from sphri.command import main as sphri_main

    out = tmp_path / "out"
    out.mkdir()
    db = out / "mlflow.db"
    from mlflow.tracking import MlflowClient

    MlflowClient(f"sqlite:///{db}").search_experiments()  # a valid new store...
    with sqlite3.connect(db) as con:  # ...that a second process's migration left half done
        con.execute("CREATE TABLE _alembic_tmp_latest_metrics (x INTEGER)")
    proc = _sphri(["+debug=fast", "layout.res=2", f"output_dir={out}"], cwd=tmp_path)
    assert proc.returncode == 1
    assert "_alembic_tmp_latest_metrics" in proc.stderr
    assert f"sphri store repair {db}" in proc.stderr
    assert "computing" not in proc.stdout + proc.stderr, "nothing is computed into a broken store"
    assert not (out / "cache").exists()
    assert sphri_main(["store", "repair", str(db)]) == 0
    assert sphri_main(["store", "check", str(db)]) == 0


# ------------------------------------------------------------------ sweeps
@pytest.mark.parametrize("values", ["2,abc", "0,2"])
def test_sweep_with_an_invalid_point_starts_no_job(tmp_path: Path, values: str):
    out = tmp_path / "out"
    proc = _sphri(
        ["-m", "+debug=fast", f"layout.res={values}", f"output_dir={out}", "hydra/launcher=serial"], cwd=tmp_path
    )
    assert proc.returncode == 2, proc.stderr[-3000:]
    bad = "abc" if "abc" in values else "0"
    assert f"layout.res={bad}" in proc.stderr and "no job was started" in proc.stderr
    assert "computing" not in proc.stdout + proc.stderr
    assert not (out / "mlflow.db").exists() or _runs(out) == [], "no parent run is opened (none left RUNNING)"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_killed_sweep_ends_its_parent_killed(tmp_path: Path, sig: int):
    out = tmp_path / "out"
    sweep_dir = out / "sweeps" / "k"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sphri",
            "-m",
            "+debug=fast",
            "layout.res=range(2,20)",
            f"output_dir={out}",
            "hydra/launcher=serial",
            f"hydra.sweep.dir={sweep_dir}",
        ],
        cwd=tmp_path,
        env=_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    deadline = time.time() + 300
    while not (sweep_dir / PARENT_FILE).exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
    time.sleep(2.0)  # inside the first job
    proc.send_signal(sig)
    log = proc.communicate(timeout=300)[0]
    assert proc.returncode == 128 + sig, log[-3000:]
    parent_id = json.loads((sweep_dir / PARENT_FILE).read_text())["run_id"]
    parent = [r for r in _runs(out, "sweep") if r.info.run_id == parent_id][0]
    assert parent.info.status == "KILLED"
    assert "sweep KILLED" in log


def test_a_signal_whose_exception_was_replaced_still_ends_the_sweep_killed():
    """A SIGTERM landing inside OmegaConf while Hydra composes a job surfaced as an AttributeError
    from the half-finished call (seen in CI); once the signal was received the sweep counts as killed."""
    from hydra_plugins.sphri_sweeper.sphri_sweeper import killed_by
    from sphri.tracking.parent import KILLED, SweepKilled

    KILLED.clear()
    try:
        replaced = AttributeError("'NoneType' object has no attribute '_invalidate_flags_cache'")
        assert killed_by(replaced) is None, "no signal received: a real failure"
        assert killed_by(KeyboardInterrupt()) == signal.SIGINT
        assert killed_by(SweepKilled(signal.SIGTERM)) == signal.SIGTERM
        KILLED.append(int(signal.SIGTERM))
        assert killed_by(replaced) == signal.SIGTERM
    finally:
        KILLED.clear()


def test_a_signal_during_an_import_waits_until_the_import_finished(tmp_path: Path, monkeypatch):
    """A SIGTERM landing while an extension module initialised (manifold3d, inside ``import trimesh``)
    aborted the sweep with SIGABRT (seen in CI). Here a module's body sends itself SIGTERM and goes on
    working: the import must finish, then the sweep's exception comes, once, outside the import."""
    from hydra_plugins.sphri_sweeper.sphri_sweeper import _raise_killed
    from sphri.tracking.parent import KILLED, SweepKilled

    (tmp_path / "signalled_in_import.py").write_text(
        "import os, signal, time\n"
        "os.kill(os.getpid(), signal.SIGTERM)\n"
        "time.sleep(0.3)  # the signal is handled here, inside the import\n"
        "DONE = True\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    KILLED.clear()
    previous = signal.signal(signal.SIGTERM, _raise_killed)
    imported = False
    try:
        with pytest.raises(SweepKilled) as killed:
            import signalled_in_import  # noqa: F401

            imported = signalled_in_import.DONE
            deadline = time.time() + 5
            while time.time() < deadline:
                time.sleep(0.01)
        assert imported, "the exception was raised inside the import"
        assert killed.value.signum == signal.SIGTERM and KILLED == [signal.SIGTERM]
    finally:
        signal.signal(signal.SIGTERM, previous)
        KILLED.clear()
        sys.modules.pop("signalled_in_import", None)


def test_rerun_of_a_sweep_skips_finished_jobs_into_its_parent(tmp_path: Path):
    """The same sweep again (with other runtime settings), into its own sweep dir and then into a new
    timestamped one: both skip the finished jobs and reopen the one parent run; a sweep with one more
    point starts only that job, and its new parent names the runs that finished the others; a single
    job with other runtime settings takes every stage from the cache."""
    import re

    out = tmp_path / "out"
    fixed = [
        "-m",
        "+debug=fast",
        "layout.res=2,3",
        f"output_dir={out}",
        "hydra/launcher=serial",
        f"hydra.sweep.dir={out}/sweeps/s",
    ]
    first = _sphri(fixed, cwd=tmp_path)
    assert first.returncode == 0, first.stderr[-3000:]
    again = _sphri([*fixed, "cv.workers=2", "cv.progress=false"], cwd=tmp_path)  # runtime settings: the same jobs
    assert again.returncode == 0, again.stderr[-3000:]
    assert "2 of 2 jobs finished (2 skipped" in again.stdout, again.stdout[-3000:]
    assert len(_runs(out, "sweep")) == 1 and len(_runs(out, "job")) == 2
    # the sweep's console: one line per job with the sweep's progress, then one table of every job
    assert re.search(
        r"\[sweep 2/2 done: 0 failed, 0 skipped; .* ETA .*\] job #1 \(.*layout.res=3.*\) accuracy 0\.\d{3}",
        first.stdout,
    ), first.stdout[-3000:]
    assert re.search(r"#1\s+layout.res=3\s+FINISHED\s+0\.\d{3}\s+0\.\d{3}\s+\d+ s\s+no", first.stdout)
    assert re.search(r"#0\s+layout.res=2\s+SKIPPED", again.stdout) and "=====" not in first.stdout  # no per-job boxes
    # the default sweep dir is timestamped: another directory, the same parent (overrides in another order)
    other = _sphri(["-m", "hydra/launcher=serial", f"output_dir={out}", "layout.res=2,3", "debug=fast"], cwd=tmp_path)
    assert other.returncode == 0, other.stderr[-3000:]
    assert "2 of 2 jobs finished (2 skipped" in other.stdout
    assert len(list((out / "multirun").glob("*/*"))) == 1 and (out / "sweeps" / "s").is_dir(), "two sweep directories"
    parents = _runs(out, "sweep")
    assert len(parents) == 1 and parents[0].info.status == "FINISHED"
    assert len(_runs(out, "job")) == 2
    # the launching process answered the finished jobs: no job started (Hydra writes .hydra/ for each job it runs)
    (new_dir,) = (out / "multirun").glob("*/*")
    assert sorted(p.name for p in new_dir.iterdir() if p.is_dir()) == ["0", "1"]
    assert all(not (new_dir / j / ".hydra").exists() for j in ("0", "1"))
    # one more point: only that job starts, under its own number
    more = _sphri(
        [
            "-m",
            "+debug=fast",
            "layout.res=2,3,4",
            f"output_dir={out}",
            "hydra/launcher=serial",
            f"hydra.sweep.dir={out}/sweeps/t",
        ],
        cwd=tmp_path,
    )
    assert more.returncode == 0, more.stderr[-3000:]
    assert "3 of 3 jobs finished (2 skipped" in more.stdout
    assert [j for j in ("0", "1", "2") if (out / "sweeps" / "t" / j / ".hydra").exists()] == ["2"]
    assert len(_runs(out, "job")) == 3
    # another sweep, another parent: it names the runs that finished its skipped jobs
    done = {r.data.params["layout.res"]: r.info.run_id for r in _runs(out, "job")}
    newest = max(_runs(out, "sweep"), key=lambda r: r.info.start_time)
    assert newest.data.tags["sphri.skipped_jobs"] == f"job 0: run {done['2']}, job 1: run {done['3']}"
    # a single job with other runtime settings: every stage comes from the cache
    single = _sphri(
        [
            "+debug=fast",
            "layout.res=2",
            "cv.progress=false",
            "model.n_jobs=1",
            "contact.chunk_frames=777",
            f"output_dir={out}",
        ],
        cwd=tmp_path,
    )
    assert single.returncode == 0, (single.stdout + single.stderr)[-3000:]
    log = single.stdout + single.stderr
    assert "stage evaluate  from cache" in log, log[-3000:]
    assert "computing (key" not in log and "computed in" not in log, log[-3000:]


def test_the_sweepers_fast_composition_gives_hydras_configs():
    """The sweeper composes each distinct set of group choices once and sets plain values on a copy
    (100 jobs checked in seconds, not a minute): every job's config equals Hydra's own
    load_sweep_config, over group sweeps, value sweeps and an experiment's sweeper params."""
    args = ["experiment=requirement_sensitivity_quick", "encoder=ellipse,coverage", "model.n_estimators=7,9"]
    with sweeper(args) as (found, loader, jobs):
        jobs = jobs[::3]  # every third of the 36: both encoders, both forest sizes, every variant
        compose = found.job_composer()
        for job in jobs:
            assert plain_task(compose(list(job))) == hydras_own(found, loader, job), job
        with pytest.raises(Exception) as err:  # a typed node refuses an unknown key as Hydra does
            compose(["model.lr=0.1"])
    from sphri.config import _explain

    assert _explain(err.value).startswith("model.lr is not a known key")
