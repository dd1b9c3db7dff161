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

A re-run of the same sweep finds its earlier parent: in the same sweep
directory through the parent file, in another one (Hydra's default
timestamped ``hydra.sweep.dir``) through the tag ``sphri.sweep_hash``, a hash
of the sweep's overrides (swept values and fixed ones, ``hydra.*`` excepted).
"""

from __future__ import annotations

import json
import logging
import signal
from pathlib import Path
from typing import Any, Sequence

from omegaconf import DictConfig

from sphri.tracking.mlflow_tracker import PARENT_FILE

log = logging.getLogger(__name__)
STATUS_FILE = "sphri_status.json"

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
    if not path.exists():
        return None
    return json.loads(path.read_text())


def sweep_hash(overrides: Sequence[str]) -> str:
    """What identifies a sweep command: its overrides (``hydra.*`` excepted), in any order."""
    from sphri.cache import stable_hash

    return stable_hash(sorted(o for o in overrides if not o.lstrip("+~").startswith("hydra")))


def job_statuses(sweep_dir: str | Path) -> list[dict[str, Any]]:
    return [json.loads(p.read_text()) for p in sorted(Path(sweep_dir).glob(f"*/{STATUS_FILE}"))]


def open_parent(config: DictConfig, overrides: Sequence[str]) -> dict[str, Any] | None:
    """Reopen this sweep's earlier parent run, or create one; writes the sweep dir's parent file."""
    from sphri.pipeline import build

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
        (sweep_dir / PARENT_FILE).write_text(json.dumps(info))
        log.info("resuming sweep %s (same overrides) in its MLflow parent run %s", info["sweep_id"], info["run_id"])
        return info
    sweep_id = sweep_id_of(sweep_dir)
    run_id = tracker.start_parent(config.output_dir, str(sweep_dir), sweep_id, list(overrides), sweep_hash=h)
    info = {"run_id": run_id, "sweep_id": sweep_id, "uri": uri}
    (sweep_dir / PARENT_FILE).write_text(json.dumps(info))
    log.info("MLflow parent run %s for sweep %s", run_id, sweep_id)
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
        from sphri.pipeline import build

        try:
            skipped = {int(s["job"]): s["mlflow_run_id"] for s in statuses
                       if s.get("status") == "SKIPPED" and s.get("mlflow_run_id")}
            build(config.tracking).end_parent(config.output_dir, parent["run_id"], len(statuses), len(failed), status,
                                              skipped)
        except Exception as exc:  # never hide the sweep's own outcome
            log.error("could not end the MLflow parent run %s: %s", parent["run_id"], exc)
    msg = f"sweep {sweep_id_of(sweep_dir)}: {len(statuses) - len(failed)} of {len(statuses)} jobs finished"
    if n_skipped:
        msg += f" ({n_skipped} skipped: a finished MLflow run with the same config hash exists)"
    if failed:
        msg += "; FAILED: " + ", ".join(f"#{s['job']}: {s.get('error', '?')}" for s in failed)
    if interrupted:
        msg += f"; sweep {interrupted}"
    log.info(msg)
    print(msg)
    return status, failed
