"""A sweep's MLflow parent run: found or created before any job starts, always ended.

:class:`sphri.tracking.sweeper.SphriSweeper` calls :func:`open_parent` after
every job's config has been validated and before any job starts (so the
SQLite database and the experiment exist before parallel jobs start, and
workers never race to create them), and :func:`close_parent` when the sweep
ends however it ends: FINISHED when every job finished (skipped ones
included), FAILED when a job failed or the sweep raised, KILLED on SIGINT or
SIGTERM. Jobs find the parent through ``<sweep_dir>/mlflow_parent_run.json``;
each job writes ``<job_dir>/sphri_status.json`` so the end of the sweep can
count failures.

A sweep folder holds one sweep. :func:`claim_sweep_dir` takes an exclusive
lock on ``<sweep_dir>/sphri_sweep.lock`` (``fcntl.flock``, released by the
OS when the process ends, however it ends) for the whole sweep and writes
its holder into it (pid, command, start time): a second sweep into the same
folder while the first runs is :class:`SweepDirInUse`, naming the folder and
the holder. ``sphri_sweep.json`` records the sweep's jobs (each job's
overrides without its runtime settings, and the output folder): a later
sweep into the folder must have the same jobs (a rerun, a resumed sweep,
other runtime settings); a sweep with other jobs would overwrite the first
one's job folders and reopen its parent run, and is refused.

A re-run of the same sweep finds its earlier parent: in the same sweep
directory through the parent file, in another one (Hydra's default
timestamped ``hydra.sweep.dir``) through the tag ``sphri.sweep_hash``, a hash
of the sweep's overrides (swept values and fixed ones, ``hydra.*`` excepted).
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import logging
import os
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig

from sphri.config import build, runtime_keys
from sphri.fsutil import write_atomic
from sphri.tracking.mlflow_tracker import PARENT_FILE

log = logging.getLogger(__name__)
STATUS_FILE = "sphri_status.json"
SWEEP_FILE = "sphri_sweep.json"
"""Written into a sweep directory by the sweeper before any job starts: the job count, start time and jobs."""
LOCK_FILE = "sphri_sweep.lock"
"""Locked (``flock``) by the process running the sweep for as long as it runs; holds the holder's line."""

KILLED: list[int] = []
"""Signals received by this process's sweep (set by the sweeper's SIGTERM handler)."""


class SweepKilled(BaseException):
    """SIGTERM (or SIGINT) reached the sweep's process."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def stop_if_killed() -> None:
    """Raise :class:`SweepKilled` in a job that starts after its sweep was signalled (in-process launchers)."""
    if KILLED:
        raise SweepKilled(KILLED[0])


def sweep_id_of(sweep_dir: str | Path) -> str:
    p = Path(sweep_dir)
    return f"{p.parent.name}_{p.name}" if p.parent.name else p.name


def read_parent(sweep_dir: str | Path) -> dict[str, Any] | None:
    path = Path(sweep_dir) / PARENT_FILE
    return json.loads(path.read_text()) if path.exists() else None


def sweep_hash(overrides: Sequence[str]) -> str:
    """What identifies a sweep command: its overrides (``hydra.*`` excepted), in any order."""
    from sphri.integrity import stable_hash

    return stable_hash(sorted(o for o in overrides if not o.lstrip("+~").startswith("hydra")))


def job_statuses(sweep_dir: str | Path) -> list[dict[str, Any]]:
    """Every job's status file in the sweep directory, in job order."""
    out = []
    for p in Path(sweep_dir).glob(f"*/{STATUS_FILE}"):
        try:
            out.append(json.loads(p.read_text()))
        except (OSError, ValueError):  # being written by a parallel job
            continue
    return sorted(out, key=lambda s: int(s.get("job", 0)))


def write_status(
    job_dir: Path, job: int, status: str, error: str | None = None, run_id: str | None = None, **details: Any
) -> None:
    """``sphri_status.json``: the job's end state (and, for the sweep's table, its swept values, accuracy,
    macro-F1, seconds and whether its evaluation came from the cache)."""
    info = {"job": job, "status": status, "error": error, "mlflow_run_id": run_id, **details}
    # a parallel job's progress line never reads half a file
    write_atomic(job_dir / STATUS_FILE, json.dumps(info, default=float).encode())


class SweepDirInUse(RuntimeError):
    """A sweep folder another sweep holds (running now) or holds the jobs of (another sweep's folder)."""


def job_identity(overrides: Sequence[str], neutral: frozenset[str]) -> list[str]:
    """What identifies a sweep's job in its folder: its overrides, sorted, without ``hydra.*`` and the
    settings in ``neutral`` (runtime settings, the tracking group: they cannot change its result)."""

    def kept(key: str) -> bool:
        return not key.startswith("hydra") and key not in neutral and key.split(".", 1)[0] not in _NOT_JOB

    return sorted(o for o in overrides if kept(o.lstrip("+~").partition("=")[0]))


#: Root keys and groups that say how a job is run or recorded: never part of a job's identity.
_NOT_JOB = ("tracking", "cache", "resume", "output_dir")


class SweepClaim:
    """The sweep folder's lock, held by this process until :meth:`release` (or the process's end)."""

    def __init__(self, sweep_dir: Path, fd: int) -> None:
        self.sweep_dir = sweep_dir
        self.fd: int | None = fd

    def release(self) -> None:
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            os.ftruncate(self.fd, 0)
        os.close(self.fd)  # closing the descriptor releases the flock
        self.fd = None


def _holder_line() -> str:
    cmd = " ".join(sys.argv) or "?"
    since = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    return f"pid {os.getpid()} ({cmd[:200]}), since {since}"


def _lock_sweep_dir(sweep_dir: Path) -> SweepClaim:
    """Take the folder's lock without waiting, or raise :class:`SweepDirInUse` naming its holder."""
    lock = sweep_dir / LOCK_FILE
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)  # never truncated before it is held
    except OSError as exc:
        raise SweepDirInUse(f"hydra.sweep.dir={sweep_dir}: its lock file {lock} cannot be opened ({exc})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        try:
            held = os.pread(fd, 4096, 0).decode(errors="replace").strip()
        finally:
            os.close(fd)
        if not held:  # taken a moment ago, its holder not written yet: ask the OS
            from sphri.tracking.store import holders

            held = ", ".join(holders(lock)) or "a process the OS does not name"
        raise SweepDirInUse(
            f"hydra.sweep.dir={sweep_dir} is in use by another sweep ({held}); no job was started. "
            "Wait for it to end, or give another hydra.sweep.dir"
        ) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, (_holder_line() + "\n").encode(), 0)
    return SweepClaim(sweep_dir, fd)


def _recorded_jobs(sweep_dir: Path) -> tuple[dict[int, list[str]] | None, int | None, str | None]:
    """``(job number -> identity, job count, output folder)`` an earlier sweep recorded in the folder;
    ``(None, None, None)`` when it recorded nothing. Made by an older sphri (no jobs in its sweep file),
    the jobs that wrote a status file are read from it, and the count and folder are unknown (None)."""
    try:
        info = json.loads((sweep_dir / SWEEP_FILE).read_text())
    except (OSError, ValueError, RecursionError):
        info = None
    if isinstance(info, dict) and isinstance(info.get("jobs"), list):
        jobs = [[str(o) for o in j] for j in info["jobs"] if isinstance(j, list)]
        return dict(enumerate(jobs)), len(jobs), info.get("output_dir")
    neutral = runtime_keys()
    statuses = job_statuses(sweep_dir)
    found = {int(s.get("job", 0)): job_identity([str(o) for o in s.get("overrides") or []], neutral) for s in statuses}
    return found or None, None, None


def claim_sweep_dir(sweep_dir: str | Path, jobs: Sequence[Sequence[str]], output_dir: str | Path) -> SweepClaim:
    """Lock the sweep folder for this sweep (see the module docstring) and check it holds no other sweep:
    :class:`SweepDirInUse` names the folder and the holder, or the job the two sweeps disagree on."""
    path = Path(sweep_dir)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepDirInUse(f"hydra.sweep.dir={path} cannot be made ({exc.strerror or exc})") from None
    claim = _lock_sweep_dir(path)
    try:
        neutral = runtime_keys()
        mine = [job_identity(j, neutral) for j in jobs]
        theirs, n_theirs, their_out = _recorded_jobs(path)
        out = str(Path(output_dir).resolve())
        if theirs is not None:
            k = next((i for i in sorted(theirs) if i >= len(mine) or theirs[i] != mine[i]), None)
            if k is not None and k < len(mine):
                differs = (
                    f"its job #{k} ran {' '.join(theirs[k]) or 'the defaults'}, this sweep's job #{k} is "
                    f"{' '.join(mine[k]) or 'the defaults'}"
                )
            elif k is not None or (n_theirs is not None and n_theirs != len(mine)):
                differs = f"{n_theirs if n_theirs is not None else max(theirs) + 1} jobs, this sweep {len(mine)}"
            else:
                differs = ""
            if differs:
                raise SweepDirInUse(
                    f"hydra.sweep.dir={path} holds another sweep ({differs}); its job folders would be overwritten "
                    "and its report would count both. No job was started; give another hydra.sweep.dir"
                )
        if their_out is not None and their_out != out:
            raise SweepDirInUse(
                f"hydra.sweep.dir={path} holds a sweep recorded in output_dir={their_out}, not {out}; its job "
                "folders would be overwritten. No job was started; give another hydra.sweep.dir"
            )
    except BaseException:
        claim.release()
        raise
    return claim


def start_sweep_file(
    sweep_dir: str | Path, n_jobs: int, jobs: Sequence[Sequence[str]] | None = None, output_dir: str | None = None
) -> None:
    """Record the job count and start time (the progress lines' denominator and ETA), and the sweep's jobs
    (:func:`job_identity`) and output folder, which a later sweep into the folder must share."""
    info: dict[str, Any] = {"n_jobs": int(n_jobs), "started": time.time()}
    if jobs is not None:
        neutral = runtime_keys()
        info["jobs"] = [job_identity(j, neutral) for j in jobs]
    if output_dir is not None:
        info["output_dir"] = str(Path(output_dir).resolve())
    write_atomic(Path(sweep_dir) / SWEEP_FILE, json.dumps(info).encode())


def progress_line(sweep_dir: str | Path, job: int, what: str) -> str:
    """One line for the sweep's console when a job ends: this job, then done / failed / skipped of all, ETA."""
    try:
        info = json.loads((Path(sweep_dir) / SWEEP_FILE).read_text())
    except (OSError, ValueError, RecursionError):
        return f"[sweep] job #{job} {what}"
    statuses = job_statuses(sweep_dir)
    n, done = int(info["n_jobs"]), len(statuses)
    failed = sum(s.get("status") == "FAILED" for s in statuses)
    skipped = sum(s.get("status") == "SKIPPED" for s in statuses)
    elapsed = time.time() - float(info["started"])
    ran = max(done - skipped, 1)
    eta = elapsed / ran * (n - done) if done < n else 0.0
    return (
        f"[sweep {done}/{n} done: {failed} failed, {skipped} skipped; {elapsed / 60:.1f} min, "
        f"ETA {eta / 60:.1f} min] job #{job} {what}"
    )


def results_table(statuses: Sequence[dict[str, Any]]) -> str:
    """The sweep's jobs, one row each: swept values, status, accuracy, macro-F1, seconds, from cache."""
    rows = [("job", "swept values", "status", "accuracy", "macro-F1", "time", "cache")]
    seen: dict[str, set[str]] = {}
    for s in statuses:
        for o in s.get("overrides") or []:
            key, _, value = o.partition("=")
            seen.setdefault(key, set()).add(value)
    fixed = {k for k, v in seen.items() if len(v) == 1 and len(statuses) > 1}  # the same in every job: not swept
    for s in statuses:
        acc, f1 = s.get("accuracy"), s.get("macro_f1")
        rows.append(
            (
                f"#{s.get('job')}",
                " ".join(o for o in s.get("overrides") or [] if o.partition("=")[0] not in fixed) or "-",
                str(s.get("status", "?")) + ("" if s.get("status") != "FAILED" else f": {str(s.get('error'))[:60]}"),
                f"{acc:.3f}" if isinstance(acc, (int, float)) else "-",
                f"{f1:.3f}" if isinstance(f1, (int, float)) else "-",
                f"{s['seconds']:.0f} s" if isinstance(s.get("seconds"), (int, float)) else "-",
                "yes" if s.get("from_cache") else ("-" if s.get("status") != "FINISHED" else "no"),
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows)


def open_parent(config: DictConfig, overrides: Sequence[str]) -> dict[str, Any] | None:
    """Reopen this sweep's earlier parent run, or create one; writes the sweep dir's parent file."""
    sweep_dir = Path(config.hydra.sweep.dir)
    sweep_dir.mkdir(parents=True, exist_ok=True)
    for old in sweep_dir.glob(f"*/{STATUS_FILE}"):  # statuses of an earlier attempt
        old.unlink()
    if not config.tracking.enabled:
        return None
    tracker = build(config.tracking)
    uri = tracker.resolve_uri(config.output_dir)
    h = sweep_hash(overrides)
    previous = read_parent(sweep_dir)
    if previous and previous.get("uri") == uri and tracker.reopen_parent(config.output_dir, previous["run_id"]):
        log.info("resuming sweep %s in MLflow parent run %s", previous["sweep_id"], previous["run_id"])
        return previous
    earlier = tracker.find_parent(config.output_dir, h)
    if earlier is not None and tracker.reopen_parent(config.output_dir, earlier["run_id"]):
        info = {**earlier, "uri": uri}
        log.info("resuming sweep %s (same overrides) in its MLflow parent run %s", info["sweep_id"], info["run_id"])
    else:
        sweep_id = sweep_id_of(sweep_dir)
        swept = {str(k): str(v) for k, v in (config.hydra.sweeper.get("params") or {}).items()}
        run_id = tracker.start_parent(
            config.output_dir, str(sweep_dir), sweep_id, list(overrides), sweep_hash=h, base=config, swept=swept
        )
        info = {"run_id": run_id, "sweep_id": sweep_id, "uri": uri}
        log.info("MLflow parent run %s for sweep %s", run_id, sweep_id)
    (sweep_dir / PARENT_FILE).write_text(json.dumps(info))
    return info


def close_parent(config: DictConfig, interrupted: str | None = None) -> tuple[str, list[dict[str, Any]]]:
    """End the parent run and print the sweep's summary; returns ``(status, failed job statuses)``.

    ``interrupted``: ``"KILLED"`` (a signal) or ``"FAILED"`` (the sweep itself raised).
    """
    sweep_dir = Path(config.hydra.sweep.dir)
    statuses = job_statuses(sweep_dir)
    failed = [s for s in statuses if s.get("status") == "FAILED"]
    n_skipped = sum(1 for s in statuses if s.get("status") == "SKIPPED")
    status = interrupted or ("FAILED" if failed else "FINISHED")
    parent = read_parent(sweep_dir)
    if parent and config.tracking.enabled:
        try:
            skipped = {
                int(s["job"]): s["mlflow_run_id"]
                for s in statuses
                if s.get("status") == "SKIPPED" and s.get("mlflow_run_id")
            }
            build(config.tracking).end_parent(
                config.output_dir, parent["run_id"], len(statuses), len(failed), status, skipped
            )
        except Exception as exc:  # never hide the sweep's own outcome
            log.error("could not end the MLflow parent run %s: %s", parent["run_id"], exc)
    if statuses:
        print(results_table(statuses))
    msg = f"sweep {sweep_id_of(sweep_dir)}: {len(statuses) - len(failed)} of {len(statuses)} jobs finished"
    if n_skipped:
        msg += f" ({n_skipped} skipped: a finished MLflow run with the same config hash exists)"
    if failed:
        msg += "; FAILED: " + ", ".join(f"#{s['job']}: {s.get('error', '?')}" for s in failed)
    if interrupted:
        msg += f"; sweep {interrupted}"
    report = sweep_dir / "report" / "report.html"
    msg += f"; report: {report}" if report.is_file() else f"; its report: sphri report {sweep_dir}"
    print(msg)
    return status, failed
