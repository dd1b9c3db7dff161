"""Input fingerprinting reads every file below ``data.root``: a FIFO or a link to a device there must be
skipped with a warning naming it, not read (a FIFO blocks forever, /dev/zero never ends)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent

SCRIPT = """
import logging, sys
from sphri.config import compose
from sphri.inputs import FingerprintMemo, input_fingerprints
logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(message)s")
cfg = compose(["+debug=fast", "data=vr_gesture", "data.root=" + sys.argv[1], "cache.enabled=false"])
fp = input_fingerprints(cfg, FingerprintMemo(None))
print(sorted(fp.get("data", {})))
"""


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_a_fifo_and_a_link_to_dev_zero_under_data_root_are_skipped_and_named(tmp_path: Path):
    root = tmp_path / "dataset"
    (root / "arm").mkdir(parents=True)
    (root / "arm" / "manifest.json").write_text("{}")
    os.mkfifo(root / "arm" / "pipe")
    (root / "arm" / "zeros").symlink_to("/dev/zero")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    try:
        proc = subprocess.run(
            [sys.executable, "-c", SCRIPT, str(root)],
            capture_output=True,
            text=True,
            timeout=120,
            env=env,
            cwd=tmp_path,
        )
    except subprocess.TimeoutExpired:
        pytest.fail("fingerprinting data.root hung on a FIFO or /dev/zero")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert str(root / "arm" / "manifest.json") in proc.stdout
    assert "pipe" not in proc.stdout and "zeros" not in proc.stdout, proc.stdout
    warning = [line for line in proc.stderr.splitlines() if line.startswith("WARNING") and "skipped" in line]
    assert len(warning) == 1, proc.stderr[-3000:]
    assert f"{root / 'arm' / 'pipe'} is a FIFO" in warning[0], warning[0]
    assert f"{root / 'arm' / 'zeros'} is a link to a character device (/dev/zero)" in warning[0], warning[0]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_a_fifo_named_as_an_input_file_is_never_opened(tmp_path: Path):
    from sphri.inputs import FingerprintMemo

    fifo = tmp_path / "layout.npz"
    os.mkfifo(fifo)
    result: list[str] = []
    worker = threading.Thread(target=lambda: result.append(FingerprintMemo(None).digest(fifo)), daemon=True)
    worker.start()
    worker.join(30)
    if worker.is_alive():  # blocked opening the FIFO: release it, then fail
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        worker.join(30)
        pytest.fail("the fingerprint opened a FIFO and blocked")
    assert result == ["special:a FIFO (named pipe)"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_a_fifo_in_place_of_a_cache_entry_is_discarded_never_opened(tmp_path: Path, caplog):
    """A FIFO where a stage's cache entry lies blocked the job for ever (opening it waits for a writer)."""
    import signal

    from sphri.cache import StageCache

    class Blocked(BaseException):
        pass

    def blocked(signum, frame):
        raise Blocked

    cache = StageCache(tmp_path / "cache", key=None)
    entry = cache.path("evaluate", "k1")
    entry.parent.mkdir(parents=True)
    os.mkfifo(entry)
    previous = signal.signal(signal.SIGALRM, blocked)
    signal.alarm(20)
    try:
        value = cache.get_or_compute("evaluate", "k1", lambda: {"x": 2})
    except Blocked:
        pytest.fail("reading a FIFO cache entry blocked")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert value == {"x": 2}
    assert "not a regular file" in caplog.text and str(entry) in caplog.text
    assert entry.is_file(), "the computed entry took the FIFO's place"
