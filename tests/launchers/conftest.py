"""Fixtures of the launcher tests: the cluster plugins (skipped when absent),
running ``python -m sphri`` and reading a sweep's MLflow runs."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

INSTALL_HINT = 'pip install -e ".[cluster]" (`make test-all` installs it)'


def _missing(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is None
    except ModuleNotFoundError:
        return True


@pytest.fixture
def ray_plugin() -> None:
    """Skips the test unless hydra-ray-launcher (and ray) are installed."""
    if _missing("hydra_plugins.hydra_ray_launcher") or _missing("ray"):
        pytest.skip(f"hydra-ray-launcher is not installed: {INSTALL_HINT}")


@pytest.fixture
def submitit_plugin() -> None:
    """Skips the test unless hydra-submitit-launcher is installed."""
    if _missing("hydra_plugins.hydra_submitit_launcher") or _missing("submitit"):
        pytest.skip(f"hydra-submitit-launcher is not installed: {INSTALL_HINT}")


@pytest.fixture
def run_sphri() -> Callable[..., subprocess.CompletedProcess]:
    """``run_sphri(args, cwd, env=None, timeout=600)``: ``python -m sphri ARGS`` in a subprocess."""

    def run(
        args: list[str], cwd: Path, env: dict[str, str] | None = None, timeout: int = 600
    ) -> subprocess.CompletedProcess:
        full_env = {**os.environ, "PYTHONUNBUFFERED": "1", "HYDRA_FULL_ERROR": "1", **(env or {})}
        return subprocess.run(
            [sys.executable, "-m", "sphri", *args],
            cwd=cwd,
            env=full_env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )

    return run


@dataclass
class SweepRuns:
    """The MLflow runs of the ``sphri`` experiment in one store."""

    parents: list
    children: list


@pytest.fixture
def sweep_runs() -> Callable[[Path], SweepRuns]:
    """``sweep_runs(output_dir)``: parent (``sphri.kind=sweep``) and job runs of the default SQLite store."""

    def read(output_dir: Path) -> SweepRuns:
        from mlflow.tracking import MlflowClient

        from sphri.tracking.mlflow_tracker import default_uri

        client = MlflowClient(default_uri(output_dir))
        exp = client.get_experiment_by_name("sphri")
        assert exp is not None, f"no MLflow experiment 'sphri' in {default_uri(output_dir)}"
        runs = client.search_runs([exp.experiment_id])
        return SweepRuns(
            parents=[r for r in runs if r.data.tags.get("sphri.kind") == "sweep"],
            children=[r for r in runs if r.data.tags.get("sphri.kind") == "job"],
        )

    return read
