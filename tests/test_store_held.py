"""The MLflow store held by another process is busy, not broken; ``sphri store`` touches only MLflow
stores nobody holds. The second process is real: a Python subprocess that opens the database and holds
``BEGIN EXCLUSIVE`` (or only keeps it open) for a bounded time."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from sphri.command import main as sphri_main

HOLD = """
import sqlite3, sys, time
con = sqlite3.connect(sys.argv[1], isolation_level=None)
if sys.argv[2] == "lock":
    con.execute("BEGIN EXCLUSIVE")
else:
    con.execute("SELECT count(*) FROM sqlite_master").fetchone()
print("holding", flush=True)
time.sleep(60)
"""


@contextmanager
def held(db: Path, how: str = "lock") -> Iterator[subprocess.Popen]:
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(db), how], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "holding"
        yield proc
    finally:
        proc.kill()
        proc.wait(timeout=10)


def new_store(path: Path, broken: bool = False) -> Path:
    from mlflow.tracking import MlflowClient

    path.parent.mkdir(parents=True, exist_ok=True)
    MlflowClient(f"sqlite:///{path}").search_experiments()
    if broken:  # what a second process's interrupted migration leaves
        with sqlite3.connect(path) as con:
            con.execute("CREATE TABLE _alembic_tmp_latest_metrics (x INTEGER)")
    return path


def test_a_store_another_process_holds_locked_is_busy_not_broken(tmp_path, monkeypatch, capsys):
    """A job found the store "broken ... (database is locked). Repair it with ..." while another process
    held its lock: it waits a bounded, stated time, then says the store is busy and who holds it."""
    from sphri.tracking import store

    db = new_store(tmp_path / "out" / "mlflow.db")
    monkeypatch.setattr(store, "BUSY_TIMEOUT_S", 0.5, raising=False)
    with held(db) as proc:
        with pytest.raises(store.StoreBusy) as err:
            store.ensure_store(f"sqlite:///{db}")
        text = str(err.value)
        assert f"MLflow store {db} is busy" in text and "more than 0.5 s" in text and "not broken" in text, text
        assert f"pid {proc.pid}" in text and "repair" not in text, text
        assert sphri_main(["store", "check", str(db)]) == 1
        err_text = capsys.readouterr().err
        assert "is busy" in err_text and "repair" not in err_text, err_text
    store.ensure_store(f"sqlite:///{db}")  # free again: used as it is


@pytest.mark.parametrize("how", ["lock", "open"])
def test_repair_refuses_a_store_another_process_holds(how, tmp_path, capsys):
    """``repair`` moved a live store aside (its lock read as "not a readable SQLite database", so "no
    runs"): it refuses a store another process has locked or open, and leaves the file as it is."""

    db = new_store(tmp_path / "mlflow.db", broken=True)
    before = db.read_bytes()
    with held(db, how):
        assert sphri_main(["store", "repair", str(db)]) == 1
    err = capsys.readouterr().err
    assert str(db) in err and ("is open in pid" in err or "is busy" in err) and "broken-" not in err, err
    assert db.read_bytes() == before
    assert not [p.name for p in tmp_path.iterdir() if "broken-" in p.name or "bak-" in p.name]
    assert sphri_main(["store", "repair", str(db)]) == 0  # once free, repaired
    assert sphri_main(["store", "check", str(db)]) == 0


@pytest.mark.parametrize("kind", ["passwd", "text", "sqlite"])
def test_check_and_repair_touch_only_mlflow_stores(kind, tmp_path, capsys):
    """``sphri store check /etc/passwd`` suggested repairing it, and ``repair`` would move it aside and
    put a new store in its place; a SQLite database of another program read as a store to upgrade."""

    if kind == "passwd":
        path = Path("/etc/passwd")
    elif kind == "text":
        path = tmp_path / "mlflow.db"
        path.write_text("root:x:0:0:root:/root:/bin/bash\n")
    else:
        path = tmp_path / "mlflow.db"
        with sqlite3.connect(path) as con:
            con.execute("CREATE TABLE notes (body TEXT)")
            con.execute("INSERT INTO notes VALUES ('mine')")
    before = path.read_bytes()
    assert sphri_main(["store", "check", str(path)]) == 1
    out = capsys.readouterr()
    assert f"{path} is not an MLflow store" in out.err and "store repair" not in out.out + out.err, out
    if kind != "passwd":
        assert sphri_main(["store", "repair", str(path)]) == 1
        assert f"{path} is not an MLflow store" in capsys.readouterr().err
        assert path.read_bytes() == before
        assert not [p.name for p in tmp_path.iterdir() if "broken-" in p.name or "bak-" in p.name]
