"""Session and priors file errors are one line naming the file (sphri.errors), in the study's command."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def _run(tmp_path, *overrides):
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "sphri.coverage",
            "+experiment=scenario_study",
            *overrides,
            f"out={tmp_path / 'out'}",
            f"output_dir={tmp_path / 'runs'}",
            f"cache.dir={tmp_path / 'cache'}",
            "tracking.enabled=false",
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
    )


def test_bad_priors_and_session_files_are_one_line(tmp_path):
    priors = tmp_path / "priors.yaml"
    priors.write_text("tail_s: 2.5\nbase_speed_m_s: 0.25\nscenarios:\n  S1: {start_positions: [moon]}\n")
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    (sessions / "sessions.json").write_text("{not json")
    for overrides, needle in (
        ((f"data.priors={priors}",), str(priors)),
        (("data=sessions", f"data.root={sessions}"), str(sessions / "sessions.json")),
    ):
        res = _run(tmp_path, *overrides)
        assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr[-3000:]
        errors = [ln for ln in res.stderr.splitlines() if ln.startswith("sphri")]
        assert len(errors) == 1 and "data error" in errors[0] and needle in errors[0], res.stderr[-3000:]
