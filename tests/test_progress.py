"""Long steps that print nothing else while they run show a progress bar on stderr when it is a terminal,
and nothing when it is not (a log file, a pipe)."""

from __future__ import annotations

import io
import os
import pty
import re
import subprocess
import sys
from pathlib import Path

from sphri.progress import bar

REPO = Path(__file__).resolve().parents[1]


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_bar_shows_on_a_terminal_only():
    quiet = io.StringIO()
    with bar(3, "warmup", unit="command", file=quiet) as shown:
        shown.update(3)
    assert quiet.getvalue() == ""
    tty = _Terminal()
    with bar(3, "warmup", unit="command", file=tty) as shown:
        shown.update(2)
        shown.refresh()
        assert "warmup" in tty.getvalue() and "2/3" in tty.getvalue()


def _stderr_on_a_terminal(args: list[str], cwd: Path) -> tuple[int, str]:
    """Run ``python args`` with stderr on a pseudo-terminal; (exit status, what it wrote there)."""
    leader, follower = pty.openpty()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, *args], cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=follower)
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 65536)
        except OSError:  # the terminal closed: the process is done
            break
        if not data:
            break
        chunks.append(data)
    os.close(leader)
    return proc.wait(timeout=300), b"".join(chunks).decode(errors="replace")


def test_checking_a_sweeps_jobs_shows_its_progress_on_a_terminal(tmp_path):
    args = ["-m", "sphri", "validate", "-m", "+debug=fast", "layout.res=2,4,8"]
    rc, shown = _stderr_on_a_terminal(args, tmp_path)
    assert rc == 0, shown[-2000:]
    assert "checking the sweep's jobs" in shown and re.search(r"\d/3 \[", shown), shown[-2000:]
    piped = subprocess.run(
        [sys.executable, *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
        timeout=300,
    )
    assert piped.returncode == 0 and "checking the sweep's jobs" not in piped.stderr + piped.stdout


def test_warmup_shows_its_commands_done_on_a_terminal(monkeypatch):
    """`sphri warmup` runs its commands with their output captured: on a terminal a bar counts them."""
    from sphri.command import main

    def fake(cmd, **kwargs):
        return subprocess.CompletedProcess(cmd, 0, stdout="", stderr="")

    tty = _Terminal()
    monkeypatch.setattr(subprocess, "run", fake)
    monkeypatch.setattr(sys, "stderr", tty)
    assert main(["warmup"]) == 0
    assert "warmup:" in tty.getvalue() and "/3 [" in tty.getvalue()
