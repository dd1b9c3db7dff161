"""New MLflow stores start from a template that is checked by checksum before use, and a store whose
creation fails midway (a full disk) is removed, never left for the next run to take for a store."""

from __future__ import annotations

import errno
import logging
import os
import shutil
import sqlite3
import stat
from pathlib import Path

import pytest

from sphri.tracking import store as store_mod
from sphri.tracking.store import StoreNotCreated, checksum_path, ensure_store, problems, template_path


@pytest.fixture(scope="module")
def made(tmp_path_factory) -> Path:
    """A cache folder holding the template and its checksum, made once (a migration takes seconds)."""
    root = tmp_path_factory.mktemp("template")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CACHE_HOME", str(root / "cache"))
        mp.setenv("SPHRI_STORE_TEMPLATE", "1")
        mp.chdir(root)
        ensure_store(f"sqlite:///{root / 'first' / 'mlflow.db'}")
    return root / "cache"


@pytest.fixture
def cache(made: Path, tmp_path: Path, monkeypatch) -> Path:
    """This test's own copy of the made template's cache folder (``XDG_CACHE_HOME``)."""
    shutil.copytree(made, tmp_path / "cache")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("SPHRI_STORE_TEMPLATE", "1")
    monkeypatch.chdir(tmp_path)
    return tmp_path / "cache"


def _experiments(db: Path) -> list[str]:
    with sqlite3.connect(db) as con:
        return [r[0] for r in con.execute("SELECT name FROM experiments")]


def _tables(db: Path) -> set[str]:
    with sqlite3.connect(db) as con:
        return {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}


def _plant_experiment(tpl: Path) -> None:
    with sqlite3.connect(tpl) as con:  # every store copied from it would hold this experiment
        con.execute(
            "INSERT INTO experiments (experiment_id, name, artifact_location, lifecycle_stage) "
            "VALUES (7, 'planted', '/tmp/planted', 'active')"
        )


def _drop_metrics(tpl: Path) -> None:
    with sqlite3.connect(tpl) as con:  # a store copied from it fails at its first logged metric
        con.execute("DROP TABLE metrics")


@pytest.mark.parametrize("damage", [_plant_experiment, _drop_metrics], ids=["planted experiment", "dropped table"])
def test_a_template_changed_since_it_was_made_is_made_anew_not_copied(cache, tmp_path, caplog, damage):
    tpl = template_path()
    assert tpl.is_file() and checksum_path(tpl).is_file()
    fresh = _tables(tpl)
    damage(tpl)
    assert problems(tpl) == [], "the damage passes the schema check: only the checksum sees it"
    with caplog.at_level(logging.WARNING, logger="sphri.tracking.store"):
        ensure_store(f"sqlite:///{tmp_path / 'second' / 'mlflow.db'}")
    second = tmp_path / "second" / "mlflow.db"
    assert "planted" not in _experiments(second) and _tables(second) == fresh
    assert any(f"MLflow store template {tpl} changed since it was made" in r.getMessage() for r in caplog.records)
    assert "planted" not in _experiments(tpl) and _tables(tpl) == fresh, "the template was made anew"


def test_a_template_without_its_checksum_is_not_trusted(cache, tmp_path, caplog):
    tpl = template_path()
    _plant_experiment(tpl)
    checksum_path(tpl).unlink()
    with caplog.at_level(logging.WARNING, logger="sphri.tracking.store"):
        ensure_store(f"sqlite:///{tmp_path / 'second' / 'mlflow.db'}")
    assert "planted" not in _experiments(tmp_path / "second" / "mlflow.db")
    assert any("has no recorded checksum" in r.getMessage() for r in caplog.records)


def _full_disk_copy(src, dst, *args, **kwargs):
    """``shutil.copyfile`` on a disk that fills halfway through the copy."""
    data = Path(src).read_bytes()
    Path(dst).write_bytes(data[: len(data) // 2])
    raise OSError(errno.ENOSPC, "No space left on device", str(dst))


def _full_disk_migration(db: Path) -> None:
    """MLflow's migration of a new store on a disk that fills midway: tables made, then ENOSPC."""
    with sqlite3.connect(db) as con:
        con.execute("CREATE TABLE alembic_version (version_num VARCHAR(32) NOT NULL)")
        con.execute("CREATE TABLE experiments (experiment_id INTEGER)")
        con.execute("CREATE TABLE _alembic_tmp_runs (x INTEGER)")
    raise OSError(errno.ENOSPC, "No space left on device")


@pytest.mark.parametrize("where", ["template copy", "migration"])
def test_a_store_whose_creation_fills_the_disk_is_removed_with_one_line(cache, tmp_path, monkeypatch, where):
    db = tmp_path / "out" / "mlflow.db"
    if where == "template copy":
        monkeypatch.setattr(store_mod.shutil, "copyfile", _full_disk_copy)
    else:
        monkeypatch.setenv("SPHRI_STORE_TEMPLATE", "0")
        monkeypatch.setattr(store_mod, "_open", _full_disk_migration)
    with pytest.raises(StoreNotCreated) as refused:
        ensure_store(f"sqlite:///{db}")
    msg = str(refused.value)
    assert f"MLflow store {db} could not be created" in msg and "No space left on device" in msg, msg
    assert "half-made store was removed" in msg and "\n" not in msg
    assert sorted(p.name for p in db.parent.iterdir()) == ["mlflow.db.lock"], "no half-made store, no temporary file"
    monkeypatch.setattr(store_mod.shutil, "copyfile", shutil.copyfile)
    monkeypatch.undo()
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache))
    ensure_store(f"sqlite:///{db}")  # the next run makes a whole store there
    assert problems(db) == [] and "Default" in _experiments(db)


@pytest.mark.parametrize("text", [b"0", b"notes\n", b"SQLite"])
def test_a_short_file_that_is_not_sqlite_is_never_made_a_store(cache, tmp_path, text):
    """SQLite reads a file shorter than its header as an empty database: a job, ``check`` and ``repair``
    took a one-byte text file at ``mlflow.db`` for a new store and wrote a store over it."""
    from sphri.tracking.store import NotAStore, repair

    db = tmp_path / "o" / "mlflow.db"
    db.parent.mkdir()
    db.write_bytes(text)
    for step in (lambda: ensure_store(f"sqlite:///{db}"), lambda: problems(db), lambda: repair(db)):
        with pytest.raises(NotAStore, match="not a SQLite database"):
            step()
    assert db.read_bytes() == text


def test_a_truncated_store_is_refused_and_kept(cache, tmp_path):
    """A store cut short (a full disk, a copy interrupted) read as a store: a job computed, then failed
    to log; it is refused before computing, named as truncated, and left as it is."""
    from sphri.tracking.store import BrokenStore

    whole = template_path().read_bytes()
    db = tmp_path / "o" / "mlflow.db"
    db.parent.mkdir()
    db.write_bytes(whole[: len(whole) // 2])
    with pytest.raises(BrokenStore, match=r"is truncated \(\d+ bytes, its header says \d+ pages"):
        ensure_store(f"sqlite:///{db}")
    assert db.read_bytes() == whole[: len(whole) // 2]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
def test_a_fifo_at_the_store_path_is_refused_never_replaced(cache, tmp_path):
    """A FIFO (size 0) at ``mlflow.db`` read as "no store yet" and was replaced by a new store."""
    from sphri.tracking.store import NotAStore

    db = tmp_path / "o" / "mlflow.db"
    db.parent.mkdir()
    os.mkfifo(db)
    with pytest.raises(NotAStore, match="not a file"):
        ensure_store(f"sqlite:///{db}")
    assert stat.S_ISFIFO(db.lstat().st_mode)
