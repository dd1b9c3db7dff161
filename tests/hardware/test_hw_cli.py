"""The command lines as a user runs them: simulator and recorder in separate processes."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from sphri.hardware.recording import load_recording


def start_simulator(args: list[str], timeout_s: float = 60.0) -> tuple[subprocess.Popen, str]:
    """Start ``python -m sphri simulate ...``; return it and the URL it announces."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "sphri", "simulate", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    t0 = time.monotonic()
    assert proc.stdout is not None
    for line in proc.stdout:
        if "ready on" in line:
            return proc, line.split("ready on", 1)[1].split()[0]
        if time.monotonic() - t0 > timeout_s:
            break
    proc.kill()
    raise AssertionError(f"simulator did not announce its port (exit {proc.poll()})")


@pytest.mark.parametrize("port", ["pty", "socket://127.0.0.1:0"])
def test_simulate_then_record_from_the_command_line(tmp_path, port):
    report = tmp_path / "ledger.json"
    extra = [f"link={tmp_path / 'skin.tty'}"] if port == "pty" else []
    sim, url = start_simulator(
        [
            "skin",
            "source=pattern",
            f"port={port}",
            "frames=300",
            "realtime=false",
            "corrupt_rate=0.05",
            "seed=4",
            "hold_s=10",
            f"report={report}",
            *extra,
        ]
    )
    if port == "pty":
        assert url == str(tmp_path / "skin.tty")
    out = tmp_path / "rec.npz"
    try:
        rec_proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "sphri",
                "skin",
                "record",
                f"port={url}",
                f"out={out}",
                "idle_s=5",
                "grid=18x6",
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
    finally:
        sim.wait(timeout=60)
    assert rec_proc.returncode == 0, rec_proc.stdout + rec_proc.stderr
    ledger = json.loads(report.read_text())
    rec = load_recording(out)
    assert rec.n_frames == ledger["good"] and ledger["corrupt"] > 0
    np.testing.assert_array_equal(rec.seq, ledger["good_seq"])
    assert rec.meta["decoder"]["bad_header"] + rec.meta["decoder"]["bad_checksum"] == ledger["corrupt"]
    assert f"saved {ledger['good']} frames" in rec_proc.stdout


def test_record_names_a_missing_port_and_exits_1(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "sphri", "skin", "record", "port=/dev/ttyNOPE9", f"out={tmp_path / 'r.npz'}"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 1
    assert "/dev/ttyNOPE9" in proc.stderr and "cannot open" in proc.stderr


def test_bad_settings_exit_2_naming_the_key():
    proc = subprocess.run(
        [sys.executable, "-m", "sphri", "skin", "live", "port=loop://", "model=m", "stride=-1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2 and "stride" in proc.stderr
    proc = subprocess.run(
        [sys.executable, "-m", "sphri", "simulate", "skin", "corrupt_rate=2"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2 and "corrupt_rate" in proc.stderr
