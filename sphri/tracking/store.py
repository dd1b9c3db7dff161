"""The SQLite MLflow store: created and migrated once, under a file lock; a broken one is refused.

MLflow creates a new SQLite store by running its schema migrations (alembic)
in whichever process opens it first. Two first runs at once race through
the migrations (``table _alembic_tmp_* already exists``, ``duplicate column``)
and can leave the database half-migrated. :func:`ensure_store` takes an
exclusive ``filelock`` lock on ``<db>.lock``, refuses a store that an
interrupted migration left broken (a leftover ``_alembic_tmp_*`` table or a
schema revision other than MLflow's head) with :class:`BrokenStore` naming
the repair command, and otherwise opens the store (creating and migrating it
when new) before releasing the lock. It runs before a job computes anything,
so nothing is computed into a store it cannot log to.

Migrating a new store takes seconds. The first new store on a machine also
leaves a migrated, empty copy (no experiment) per MLflow version in the user's
cache (``$XDG_CACHE_HOME/sphri``, else ``~/.cache/sphri``); later new stores
start as a copy of it, and MLflow adds its Default experiment on first open,
as it does for a fresh store. The copy's SHA-256 is recorded beside it when it
is made (``<template>.sha256``) and checked before each use, and the copy made
from it is checked again: a template changed since (a damaged file, another
program's write) or without its checksum is made anew, with a warning. Any
other problem with that copy falls back to migrating from scratch.

A store whose creation fails midway (a full disk, an interrupted migration)
is removed before the error is raised (:class:`StoreNotCreated`, one line):
no half-made store is left for the next run to take for a store.

A store another process holds locked is not broken: readers wait for the
lock up to :data:`BUSY_TIMEOUT_S` seconds, then raise :class:`StoreBusy`
naming the processes that have the file open (read from ``/proc/*/fd`` where
the OS offers it). A file that is not an MLflow store (not SQLite, or
without MLflow's ``alembic_version``, ``experiments`` and ``runs`` tables) is
:class:`NotAStore`: never offered for repair, never touched.

``sphri store repair PATH/mlflow.db`` repairs one,
refusing a store another process has open or locked, and anything that is not
an MLflow store: a store without runs is moved aside (``mlflow.db.broken-<time>``) and created anew;
otherwise a backup is taken (``mlflow.db.bak-<time>``), each leftover
``_alembic_tmp_X`` is dropped (or renamed to ``X`` when ``X`` is missing) and
the schema upgraded to MLflow's head.
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import hashlib
import json
import logging
import os
import shutil
import sqlite3
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

from sphri.args import arg
from sphri.fsutil import write_atomic

log = logging.getLogger(__name__)

TMP_PREFIX = "_alembic_tmp_"
#: Seconds a reader waits for another process's lock on the store before calling it busy.
BUSY_TIMEOUT_S = 60.0
#: The first bytes of every SQLite database file.
SQLITE_HEADER = b"SQLite format 3\x00"
#: Tables every MLflow store holds (besides ``alembic_version``); a leftover ``_alembic_tmp_`` copy counts.
MLFLOW_TABLES = ("experiments", "runs")


class StoreError(RuntimeError):
    """An MLflow SQLite store that cannot be used now: broken, busy or not a store."""


class BrokenStore(StoreError):
    """An MLflow SQLite store an interrupted schema migration left broken."""


class StoreBusy(StoreError):
    """Another process holds the store's lock for longer than the wait: not broken, busy."""


class NotAStore(StoreError):
    """A file where the MLflow store should be that is not one (not SQLite, or not MLflow's schema)."""


class StoreNotCreated(StoreError):
    """A new store whose creation failed (a full disk...); the half-made file was removed."""


def holders(db: Path) -> list[str]:
    """``pid N (command)`` of every other process with ``db`` (or its journal) open, from ``/proc/*/fd``;
    empty where the OS does not tell."""
    names = {str(Path(db).resolve()) + side for side in ("", "-journal", "-wal")}

    def target(fd: Path) -> str:
        try:
            return os.readlink(fd)
        except OSError:  # closed meanwhile
            return ""

    out = []
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            hit = proc.name != str(os.getpid()) and any(target(fd) in names for fd in (proc / "fd").iterdir())
        except OSError:  # gone, or another user's
            continue
        if hit:
            try:
                cmd = " ".join((proc / "cmdline").read_bytes().decode(errors="replace").replace("\0", " ").split())
            except OSError:
                cmd = "?"
            out.append(f"pid {proc.name} ({cmd[:80]})")
    return out


def _busy(db: Path, waited: float) -> StoreBusy:
    who = holders(db)
    by = f" (open in {', '.join(who)})" if who else ""
    return StoreBusy(
        f"MLflow store {db} is busy: another process{by} held its lock for more than {waited:g} s; it is not "
        "broken. Nothing was computed; run again when that process is done, or give another output_dir"
    )


def _is_lock(exc: sqlite3.Error) -> bool:
    return isinstance(exc, sqlite3.OperationalError) and ("locked" in str(exc) or "busy" in str(exc))


def sqlite_path(uri: str) -> Path | None:
    """The database file of a ``sqlite:///`` URI (None for other stores)."""
    if not uri.startswith("sqlite:///"):
        return None
    return Path(uri[len("sqlite:///") :])


@contextlib.contextmanager
def store_lock(db: Path) -> Iterator[None]:
    """Exclusive inter-process lock on ``<db>.lock`` (the store's creation and repair)."""
    from filelock import FileLock

    db.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(db.with_name(db.name + ".lock")):
        yield


def _read(db: Path, sql: str, timeout: float = BUSY_TIMEOUT_S) -> list:
    """The rows of ``sql`` on the store opened read-only; waits up to ``timeout`` s for another process's lock,
    then :class:`StoreBusy`."""
    try:
        with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=timeout)) as con:
            return con.execute(sql).fetchall()
    except sqlite3.Error as exc:
        if _is_lock(exc):
            raise _busy(db, timeout) from None
        raise


def _tables(db: Path, timeout: float = BUSY_TIMEOUT_S) -> list[str]:
    return [r[0] for r in _read(db, "SELECT name FROM sqlite_master WHERE type='table'", timeout)]


def _revision(db: Path) -> str | None:
    try:
        rows = _read(db, "SELECT version_num FROM alembic_version")
    except sqlite3.OperationalError:  # no such table
        return None
    return rows[0][0] if rows else None


def head_revision(memo_dir: Path | None = None) -> str:
    """MLflow's latest schema revision. It is a constant of the installed MLflow version, and finding it
    reads every migration script (about a second): with ``memo_dir`` it is remembered per MLflow version in
    ``<memo_dir>/mlflow_schema_head.json``."""
    import mlflow

    memo = memo_dir / "mlflow_schema_head.json" if memo_dir is not None else None
    if memo is not None:
        try:
            data = json.loads(memo.read_text())
            if data.get("mlflow") == mlflow.__version__ and data.get("head"):
                return str(data["head"])
        except (OSError, ValueError):
            pass
    from mlflow.store.db.utils import _get_latest_schema_revision

    head = _get_latest_schema_revision()
    if memo is not None:
        with contextlib.suppress(OSError):  # a read-only folder: recompute next time
            write_atomic(memo, json.dumps({"mlflow": mlflow.__version__, "head": head}).encode())
    return head


def problems(db: Path, timeout: float | None = None) -> list[str]:
    """What is wrong with an existing store file (empty: nothing, or no store yet). Raises
    :class:`StoreBusy` when another process holds its lock longer than ``timeout`` s
    (:data:`BUSY_TIMEOUT_S`), :class:`NotAStore` for a file that is not an MLflow store."""
    if not db.exists() and not db.is_symlink():
        return []
    if not db.is_file():  # a FIFO, a folder, a dangling link: never replaced by a store
        raise NotAStore(f"{db} is not an MLflow store (not a file)")
    if db.stat().st_size == 0:
        return []
    with open(db, "rb") as f:  # SQLite reads a short file of anything as an empty database, and would write over it
        first = f.read(100)
    if first[: len(SQLITE_HEADER)] != SQLITE_HEADER:
        raise NotAStore(f"{db} is not an MLflow store (not a SQLite database: it starts with {first[:16]!r})")
    cut = _truncated(first, db.stat().st_size)
    if cut:
        raise BrokenStore(
            f"MLflow store {db} is truncated ({cut}: a full disk or a copy cut short?); nothing was computed into "
            "it and it is left as it is. Restore it from a backup, or give another output_dir"
        )
    try:
        tables = _tables(db, BUSY_TIMEOUT_S if timeout is None else timeout)
    except sqlite3.DatabaseError as exc:
        raise NotAStore(f"{db} is not an MLflow store (not a SQLite database: {exc})") from None
    if not tables:
        return []
    plain = {t.removeprefix(TMP_PREFIX) for t in tables}
    lacking = [t for t in ("alembic_version", *MLFLOW_TABLES) if t not in plain]
    if lacking:
        raise NotAStore(f"{db} is not an MLflow store (a SQLite database without the table(s) {', '.join(lacking)})")
    out = [f"leftover table {t} of an interrupted schema migration" for t in tables if t.startswith(TMP_PREFIX)]
    rev, head = _revision(db), head_revision(db.parent)
    if rev != head:
        out.append(f"schema revision {rev} is not MLflow's {head} (a migration did not finish)")
    return out


def _truncated(head: bytes, size: int) -> str | None:
    """What says a SQLite file is shorter than its header (its first 100 bytes) declares, or None."""
    if len(head) < 100:
        return f"{size} bytes, shorter than a SQLite header"
    page = int.from_bytes(head[16:18], "big")
    page = 65536 if page == 1 else page
    pages = int.from_bytes(head[28:32], "big")
    if head[24:28] == head[92:96] and pages > 0 and size < page * pages:  # the page count is valid
        return f"{size} bytes, its header says {pages} pages of {page} bytes ({page * pages} bytes)"
    return None


def repair_command(db: Path) -> str:
    return f"sphri store repair {db}"


def _open(db: Path) -> None:
    """Open the SQLite store ``db`` with MLflow: creates and migrates it when new, adds the Default experiment."""
    from mlflow.tracking import MlflowClient

    MlflowClient(tracking_uri=f"sqlite:///{db}").search_experiments(max_results=1)


def template_path() -> Path:
    """Where the migrated, empty store of the installed MLflow version is kept (see the module docstring)."""
    import mlflow

    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "sphri"
    return root / f"mlflow-{mlflow.__version__}-empty.db"


def _sha256(path: Path) -> str:
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def checksum_path(tpl: Path) -> Path:
    """Where the template's SHA-256 is recorded (a JSON file beside it)."""
    return tpl.with_name(tpl.name + ".sha256")


def _verified_template(tpl: Path) -> str | None:
    """The template's SHA-256 when it matches the recorded one; None (with a warning naming what is wrong)
    when it is missing, unrecorded, changed or not a store at MLflow's head revision."""
    if not tpl.exists():
        return None
    try:
        info = json.loads(checksum_path(tpl).read_text())
    except (OSError, ValueError, RecursionError):
        info = None
    recorded = info.get("sha256") if isinstance(info, dict) else None
    actual = _sha256(tpl)
    if not isinstance(recorded, str):
        log.warning("MLflow store template %s has no recorded checksum (%s); made anew", tpl, checksum_path(tpl))
        return None
    if actual != recorded:
        changed = "MLflow store template %s changed since it was made (SHA-256 %s..., recorded %s...); made anew"
        log.warning(changed, tpl, actual[:12], recorded[:12])
        return None
    try:
        if problems(tpl) or _revision(tpl) is None:
            return None
    except StoreError:
        return None
    return actual


def _empty_store_template() -> tuple[Path, str]:
    """The migrated, empty store of this MLflow version and its SHA-256, made once (under its lock) when
    missing, and again when it no longer matches its recorded checksum."""
    tpl = template_path()
    with store_lock(tpl):
        digest = _verified_template(tpl)
        if digest is not None:
            return tpl, digest
        # a name of its own each time: MLflow keeps the store of a URI it opened (a second template made
        # in this process at the same path would be given the first one's, which is gone)
        tmp = tpl.with_name(f"{tpl.stem}.{os.getpid()}.{uuid.uuid4().hex[:12]}.tmp.db")
        sums = checksum_path(tpl)
        sums_tmp = sums.with_name(f"{sums.name}.{os.getpid()}.tmp")
        try:
            tmp.unlink(missing_ok=True)
            _open(tmp)
            with contextlib.closing(sqlite3.connect(tmp)) as con:  # MLflow re-creates Default (id 0) where it opens
                con.execute("DELETE FROM experiment_tags WHERE experiment_id = 0")
                con.execute("DELETE FROM experiments WHERE experiment_id = 0")
                con.commit()
            digest = _sha256(tmp)
            import mlflow

            sums_tmp.write_text(json.dumps({"sha256": digest, "mlflow": mlflow.__version__}))
            checksum_path(tpl).unlink(missing_ok=True)  # never a new template beside an old checksum
            tmp.replace(tpl)
            sums_tmp.replace(sums)
        finally:
            tmp.unlink(missing_ok=True)
            sums_tmp.unlink(missing_ok=True)
    return tpl, digest


def _copy_template(db: Path) -> None:
    """Start the new store ``db`` as a copy of :func:`_empty_store_template`, checked against the template's
    SHA-256 (an atomic replace: ``db`` is whole or untouched); on any problem but a full disk leave it to
    MLflow's own migration."""
    tmp = db.with_name(f"{db.name}.{os.getpid()}.tmp")
    try:
        tpl, digest = _empty_store_template()
        shutil.copyfile(tpl, tmp)
        if _sha256(tmp) != digest:
            raise OSError(f"the copy of {tpl} does not match its checksum")
        tmp.replace(db)
    except Exception as exc:  # an unwritable cache, a changed MLflow schema...: migrate from scratch instead
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
            raise  # a full disk: migrating from scratch cannot succeed either


def _remove_half_made(db: Path, existed: bool) -> None:
    """Undo a store creation that failed: remove the new file and its journal (an empty file that was
    there is left empty)."""
    for side in ("-journal", "-wal", "-shm"):
        with contextlib.suppress(OSError):
            db.with_name(db.name + side).unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        if existed:
            os.truncate(db, 0)
        else:
            db.unlink(missing_ok=True)


def ensure_store(uri: str) -> None:
    """Create/migrate the SQLite store at ``uri`` once, under the lock; raise :class:`BrokenStore` if broken."""
    db = sqlite_path(uri)
    if db is None:
        return
    if db.exists() and not (os.access(db, os.R_OK | os.W_OK) and os.access(db.parent, os.W_OK)):
        # SQLite writes a journal beside the file (and the lock lives there): both must be writable
        raise BrokenStore(
            f"MLflow store {db} is read-only (the file or its folder); nothing was computed. "
            "Make it writable, or give another tracking.uri or output_dir"
        )
    with store_lock(db):
        try:
            found = problems(db)
        except NotAStore as exc:
            raise NotAStore(f"{exc}; nothing was computed. Give another tracking.uri or output_dir") from None
        if found:
            raise BrokenStore(
                f"MLflow store {db} is broken: {'; '.join(found)}. Nothing was computed into it. "
                f"Repair it with: {repair_command(db)}"
            )
        if db.exists() and db.stat().st_size > 0 and _revision(db) is not None:
            return  # an existing store at MLflow's head revision (problems() checked it): nothing to create
        existed = db.exists()  # an empty file (problems() found nothing in it) or none
        try:
            if os.environ.get("SPHRI_STORE_TEMPLATE", "1") != "0":
                _copy_template(db)
            _open(db)  # migrates a new store (or only adds the Default experiment to the template's copy)
        except BaseException as exc:
            _remove_half_made(db, existed)
            if not isinstance(exc, Exception):
                raise
            reason = " ".join(str(exc).split())[:300] or type(exc).__name__
            raise StoreNotCreated(
                f"MLflow store {db} could not be created ({type(exc).__name__}: {reason}); the half-made store was "
                "removed and nothing was computed. Free space there, or give another output_dir"
            ) from None


def _n_runs(db: Path) -> int:
    """The runs the store holds (in ``runs``, else in an interrupted migration's copy of it)."""
    for table in ("runs", f"{TMP_PREFIX}runs"):
        with contextlib.suppress(sqlite3.OperationalError):  # no such table
            return int(_read(db, f"SELECT count(*) FROM {table}", 5.0)[0][0])
    return 0


def _check_free(db: Path, timeout: float) -> None:
    """Raise :class:`StoreBusy` when another process has ``db`` open or holds a lock on it past ``timeout``."""
    who = holders(db)
    if who:
        raise StoreBusy(f"{db} is open in {', '.join(who)}; not repaired while another process holds it")
    try:
        with contextlib.closing(sqlite3.connect(db, timeout=timeout, isolation_level=None)) as con:
            con.execute("BEGIN EXCLUSIVE")
            con.execute("ROLLBACK")
    except sqlite3.Error as exc:
        if _is_lock(exc):
            raise StoreBusy(f"{db} is locked by another process; not repaired while it holds it") from None
        raise


def repair(db: Path, timeout: float = 5.0) -> str:
    """Repair a broken store (see the module docstring); returns what was done. Refuses (:class:`StoreBusy`,
    :class:`NotAStore`) a store another process holds (waiting up to ``timeout`` s for a lock) and any file
    that is not an MLflow store: such a file is never moved or replaced."""
    db = Path(db).absolute()
    stamp = time.strftime("%Y%m%d-%H%M%S")
    with store_lock(db):
        found = problems(db, timeout)  # NotAStore: never touched
        if not found:
            return f"{db}: nothing to repair"
        _check_free(db, timeout)
        n_runs = _n_runs(db)
        if n_runs == 0:
            aside = db.with_name(f"{db.name}.broken-{stamp}")
            db.rename(aside)
            _open(db)
            return f"{db}: held no runs; moved to {aside} and created a new store"
        backup = db.with_name(f"{db.name}.bak-{stamp}")
        shutil.copy2(db, backup)
        with contextlib.closing(sqlite3.connect(db)) as con:
            for t in _tables(db):
                real = t.removeprefix(TMP_PREFIX)
                if real != t:  # dropped where the migration made the table, else renamed to it
                    con.execute(f'DROP TABLE "{t}"' if real in _tables(db) else f'ALTER TABLE "{t}" RENAME TO "{real}"')
            con.commit()
        import sqlalchemy
        from mlflow.store.db.utils import _upgrade_db

        revision = _revision(db)
        if revision != head_revision():
            try:
                _upgrade_db(sqlalchemy.create_engine(f"sqlite:///{db}"))
            except Exception as exc:  # alembic: a revision this MLflow does not know (a newer MLflow's, or damage)
                import mlflow

                raise BrokenStore(
                    f"{db}: schema revision {revision} cannot be migrated by MLflow {mlflow.__version__} "
                    f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); written by another "
                    f"MLflow version (open it with that one) or damaged; the original is at {backup}"
                ) from None
        left = problems(db)
        if left:
            raise BrokenStore(f"{db}: still broken after repair ({'; '.join(left)}); the original is at {backup}")
        return f"{db}: repaired ({n_runs} runs kept; backup at {backup})"


@dataclasses.dataclass
class StoreArgs:
    action: Literal["check", "repair"] = arg(
        positional=True, metavar="check|repair", help="check: say what is wrong (exit 1 if anything); repair: fix it"
    )
    db: Path = arg(positional=True, metavar="PATH/mlflow.db", help="the SQLite MLflow store")


def command(args: StoreArgs) -> int:
    """Check an MLflow SQLite store for what an interrupted migration leaves, or repair it (a backup is
    kept; a store without runs is moved aside and created anew)."""
    try:
        if args.action == "check":
            found = problems(args.db)
            print(f"{args.db}: " + ("; ".join(found) + f" (repair: {repair_command(args.db)})" if found else "ok"))
            return 1 if found else 0
        print(repair(args.db))
    except StoreError as exc:
        print(f"sphri: {exc}", file=sys.stderr)
        return 1
    return 0
