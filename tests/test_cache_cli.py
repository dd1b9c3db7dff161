"""sphri cache: see and trim the stage cache without touching MLflow."""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

import forked_cli
import numpy as np

from sphri.cache import StageCache
from sphri.command import main as sphri_main

REPO = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    """``sphri cache ARGV``."""
    return sphri_main(["cache", *argv])


def _cache(tmp_path):
    root = tmp_path / "cache"
    c = StageCache(root=str(root))
    c.write("data", "k1", {"a": np.arange(10)})
    c.write("evaluate", "k2", {"b": np.arange(1000)})
    c.write("evaluate", "k3", {"b": np.arange(5)})
    (tmp_path / "mlflow.db").write_text("not touched")
    return root


def test_info_and_clear_one_stage(tmp_path, capsys):
    root = _cache(tmp_path)
    assert main(["info", f"dir={root}"]) == 0
    out = capsys.readouterr().out
    assert "data           1 entries" in out and "evaluate       2 entries" in out
    assert main(["clear", "evaluate", f"dir={root}"]) == 0
    assert "removed 2 entries" in capsys.readouterr().out
    assert not list((root / "evaluate").glob("*.entry")) and (root / "data" / "k1.entry").exists()
    assert (tmp_path / "mlflow.db").read_text() == "not touched"
    ok, value = StageCache(root=str(root)).read("data", "k1")
    assert ok and list(value["a"]) == list(range(10))


def test_clear_older_than_keeps_recent_entries(tmp_path, capsys):
    root = _cache(tmp_path)
    old = root / "evaluate" / "k2.entry"
    past = time.time() - 30 * 86400
    os.utime(old, (past, past))
    assert main(["clear", "older_than_days=14", f"dir={root}"]) == 0
    assert not old.exists() and (root / "evaluate" / "k3.entry").exists() and (root / "data" / "k1.entry").exists()


def test_bad_arguments_name_the_problem(tmp_path, capsys):
    root = _cache(tmp_path)
    assert main(["clear", "nostage", f"dir={root}"]) == 2
    assert "no stage ['nostage']" in capsys.readouterr().err
    assert main(["clear", "older_than_days=soon", f"dir={root}"]) == 2
    assert "older_than_days=soon is invalid" in capsys.readouterr().err
    assert main(["info", f"dir={tmp_path / 'nowhere'}"]) == 2


def test_python_m_sphri_cache_runs_the_command(tmp_path):
    """``python -m sphri cache``, in a process of its own: the same command, its errors named by the verb."""
    root = _cache(tmp_path)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}

    def cache(*args: str) -> subprocess.CompletedProcess:
        return forked_cli.run(["-m", "sphri", "cache", *args], tmp_path, env, 120)

    run = cache("info", f"dir={root}")
    assert run.returncode == 0, run.stderr
    assert "evaluate       2 entries" in run.stdout
    bad = cache("info", f"dir={tmp_path / 'none'}")
    assert bad.returncode == 2 and bad.stderr.strip() == f"sphri cache: dir={tmp_path / 'none'}: no cache folder there"
