"""The tests' forked ``python -m`` (``tests/forked_cli.py``) answers as a fresh interpreter does."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import forked_cli
import pytest


def _fresh(args: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_exit_codes_stdout_and_stderr_equal_a_fresh_interpreters(tmp_path: Path):
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    for args in (
        ["-m", "sphri", "list", "noise"],  # 0, a table on stdout
        ["-m", "sphri", "layout.res=abc", f"output_dir={tmp_path / 'o'}"],  # 2, one line on stderr
        ["-m", "sphri", "lists"],  # an unknown verb
    ):
        forked, fresh = forked_cli.run(args, tmp_path, env), _fresh(args, tmp_path, env)
        assert (forked.returncode, forked.stdout, forked.stderr) == (fresh.returncode, fresh.stdout, fresh.stderr), args
    assert not (tmp_path / "o").exists()


def test_an_uncaught_exception_is_exit_1_with_its_traceback_and_atexit_runs(tmp_path: Path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "boom.py").write_text(
        "import atexit, os, pathlib, sys\n"
        "atexit.register(lambda: pathlib.Path('atexit-ran').write_text(os.environ['MARK']))\n"
        "print('argv', sys.argv[1:], 'cwd', os.getcwd())\n"
        "raise RuntimeError('boom')\n"
    )
    env = {**os.environ, "MARK": "from-env", "PYTHONPATH": str(tmp_path / "pkg")}
    proc = forked_cli.run(["-m", "boom", "a=1"], tmp_path, env)
    assert proc.returncode == 1
    assert proc.stdout == f"argv ['a=1'] cwd {tmp_path}\n"
    assert proc.stderr.startswith("Traceback") and proc.stderr.rstrip().endswith("RuntimeError: boom")
    assert (tmp_path / "atexit-ran").read_text() == "from-env"
    assert "MARK" not in os.environ, "the request's environment stays in the child"


def test_a_run_past_its_timeout_is_killed_and_raises(tmp_path: Path):
    (tmp_path / "sleepy.py").write_text("import time\ntime.sleep(60)\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    with pytest.raises(subprocess.TimeoutExpired):
        forked_cli.run(["-m", "sleepy"], tmp_path, env, timeout=1)


def test_started_runs_wait_concurrently_and_the_escape_hatch_gives_fresh_interpreters(tmp_path: Path, monkeypatch):
    (tmp_path / "who.py").write_text(
        "import sys\nprint(sys.argv[1], 'preloaded' if 'mlflow' in sys.modules else 'fresh')\n"
    )
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    started = [forked_cli.start(["-m", "who", str(i)], tmp_path, env) for i in range(3)]
    assert [s.wait(60).stdout for s in started] == [f"{i} preloaded\n" for i in range(3)]
    monkeypatch.setenv("SPHRI_TEST_SUBPROCESS", "1")
    assert forked_cli.run(["-m", "who", "a"], tmp_path, env).stdout == "a fresh\n"
    assert forked_cli.start(["-m", "who", "b"], tmp_path, env).wait(60).stdout == "b fresh\n"
