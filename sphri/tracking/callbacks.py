"""Hydra callbacks: one MLflow parent run per multirun, created before any worker.

Creating the experiment and the parent run in the launching process means
the SQLite database and the experiment exist before parallel jobs start, so
workers never race to create them. Jobs find the parent through
``<sweep_dir>/mlflow_parent_run.json``; each job writes
``<job_dir>/sphri_status.json`` so the end of the sweep can count failures.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from sphri.tracking.mlflow_tracker import PARENT_FILE

log = logging.getLogger(__name__)
STATUS_FILE = "sphri_status.json"


def sweep_id_of(sweep_dir: str | Path) -> str:
    p = Path(sweep_dir)
    return f"{p.parent.name}_{p.name}" if p.parent.name else p.name


def read_parent(sweep_dir: str | Path) -> dict[str, Any] | None:
    path = Path(sweep_dir) / PARENT_FILE
    if not path.exists():
        return None
    return json.loads(path.read_text())


class MlflowSweepCallback(Callback):
    """Opens the sweep's parent run on multirun start and closes it at the end."""

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        from sphri.config import build, register_schemas

        register_schemas()
        sweep_dir = Path(config.hydra.sweep.dir)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        if not config.tracking.enabled:
            return
        tracker = build(config.tracking)
        for old in sweep_dir.glob(f"*/{STATUS_FILE}"):  # statuses of an earlier attempt
            old.unlink()
        previous = read_parent(sweep_dir)
        if previous and previous.get("uri") == tracker.resolve_uri(config.output_dir) and tracker.reopen_parent(
            config.output_dir, previous["run_id"]
        ):
            log.info("resuming sweep %s in MLflow parent run %s", previous["sweep_id"], previous["run_id"])
            return
        sweep_id = sweep_id_of(sweep_dir)
        overrides = list(config.hydra.overrides.task)
        run_id = tracker.start_parent(config.output_dir, str(sweep_dir), sweep_id, overrides)
        info = {"run_id": run_id, "sweep_id": sweep_id, "uri": tracker.resolve_uri(config.output_dir)}
        (sweep_dir / PARENT_FILE).write_text(json.dumps(info))
        log.info("MLflow parent run %s for sweep %s", run_id, sweep_id)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        statuses = [json.loads(p.read_text()) for p in sorted(sweep_dir.glob(f"*/{STATUS_FILE}"))]
        n_failed = sum(1 for s in statuses if s.get("status") == "FAILED")
        n_skipped = sum(1 for s in statuses if s.get("status") == "SKIPPED")
        parent = read_parent(sweep_dir)
        if parent and config.tracking.enabled:
            # a resumed sweep's parent is FINISHED when every job is (skipped ones included)
            from sphri.config import build

            build(config.tracking).end_parent(config.output_dir, parent["run_id"], len(statuses), n_failed)
        msg = f"sweep {sweep_id_of(sweep_dir)}: {len(statuses) - n_failed} of {len(statuses)} jobs finished"
        if n_skipped:
            msg += f" ({n_skipped} skipped: a finished MLflow run with the same config hash exists)"
        if n_failed:
            failed = ", ".join(f"#{s['job']}: {s.get('error', '?')}" for s in statuses if s.get("status") == "FAILED")
            msg += f"; FAILED: {failed}"
        log.info(msg)
        print(msg)
