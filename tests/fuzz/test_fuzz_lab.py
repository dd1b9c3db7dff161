"""Fuzz campaign, the long-running lab's surfaces: MLflow stores, output folders, links, FIFOs, huge sizes,
crafted codec payloads and URDF mesh paths.

Each surface has its own counts (``lab-<surface>``, written with ``SPHRI_FUZZ_COUNTS=DIR``). A case draws
one way the surface can be wrong and calls sphri where a job, ``sphri store``, ``sphri cache clear`` or the
robot loader would, in process. Its verdict is a **named error** (an error of ``sphri.errors.EXPECTED``,
one line), a **documented warning** (accepted with a logged warning), or **accepted unchanged** (accepted,
and what a correct run gives). Every case also checks what it must not do: no file outside what it may
write is changed, created or removed (a **silent change** or a **lost file**, snapshots before and after),
and nothing blocks (a SIGALRM after ``HANG_S`` seconds is a failure). Anything else is a traceback.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import io
import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fuzz_support import NAMED, UNCHANGED, WARNED, Tally, WarningCatcher, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st
from time_limit import time_limit

from sphri.config import ConfigError
from tests.robots.test_mesh_paths import urdf_with
from tests.test_store_held import HOLD

SURFACES = ("store", "outputs", "links", "fifo", "huge", "codec", "urdf")
HANG_S = 20
TALLIES = {s: Tally(f"lab-{s}") for s in SURFACES}
FRESH = "__fresh__"


@pytest.fixture(scope="module", autouse=True)
def _write_counts():
    yield
    for t in TALLIES.values():
        t.write()


def verdict(surface: str, kind: str, exc: BaseException | None, warned: bool = False) -> str:
    """Count the case: a named error (else it is a traceback, re-raised), a warning, or unchanged."""
    tally = TALLIES[surface]
    if exc is not None:
        out = tally.named(f"{surface}: {kind}", exc)
    else:
        out = WARNED if warned else UNCHANGED
    tally.add(f"{surface}: {kind}", out)
    return out


def lost(surface: str, kind: str, what: str) -> None:
    TALLIES[surface].add(f"{surface}: {kind}", "lost file" if "lost" in what else "silent change")
    raise AssertionError(f"{surface}: {kind}: {what}")


class Hung(BaseException):
    """A case blocked for more than HANG_S seconds (a BaseException: no ``except Exception`` hides it)."""


def no_hang(what: str) -> contextlib.AbstractContextManager[None]:
    """SIGALRM after HANG_S seconds: a case that blocks fails (:class:`Hung`) instead of hanging the suite."""
    return time_limit(HANG_S, what, Hung)


def snapshot(root: Path) -> dict[str, str]:
    """Every entry below ``root`` (links not followed): a file's SHA-256, a link's target, a folder."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(root))
            if p.is_symlink():
                out[rel] = "link:" + os.readlink(p)
            elif p.is_dir():
                out[rel] = "dir"
            elif p.is_file():
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
            else:
                out[rel] = "special"
    return out


def unchanged(surface: str, kind: str, before: dict[str, str], after: dict[str, str], may: set[str]) -> None:
    """Nothing but the names in ``may`` changed between the snapshots (a missing name is a lost file)."""
    gone = sorted(k for k in before if k not in after and k not in may)
    if gone:
        lost(surface, kind, f"lost files: {gone}")
    changed = sorted(k for k in before if k in after and before[k] != after[k] and k not in may)
    made = sorted(k for k in after if k not in before and k not in may)
    if changed or made:
        lost(surface, kind, f"changed {changed}, made {made}")


# ------------------------------------------------------------------ stores
@pytest.fixture(scope="module")
def a_store(tmp_path_factory) -> Path:
    """A real MLflow store holding one finished run (made once: a migration takes seconds)."""
    from mlflow.tracking import MlflowClient

    root = tmp_path_factory.mktemp("store")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("XDG_CACHE_HOME", str(root / "cache"))
        mp.chdir(root)
        from sphri.tracking.store import ensure_store

        db = root / "o" / "mlflow.db"
        ensure_store(f"sqlite:///{db}")
        client = MlflowClient(f"sqlite:///{db}")
        run = client.create_run(client.create_experiment("lab", artifact_location=str(root / "art")))
        client.log_metric(run.info.run_id, "accuracy", 0.5)
        client.set_terminated(run.info.run_id)
    return db


def _not_a_store(data) -> bytes | None:
    """A file where the store should be that is not an MLflow store (None: another program's SQLite)."""
    kind = data.draw(st.sampled_from(["text", "binary", "sqlite"]), label="not a store")
    if kind == "text":
        return data.draw(st.text(min_size=1, max_size=200), label="text").encode()
    if kind == "binary":
        return data.draw(st.binary(min_size=1, max_size=4096), label="binary")
    return None


def _store_case(data, tmp: Path, made: Path) -> tuple[str, Path]:
    """Lay out one damaged store at ``tmp/o/mlflow.db``: ``(kind, db)``."""
    store = made.read_bytes()
    db = tmp / "o" / "mlflow.db"
    db.parent.mkdir(parents=True)
    kind = data.draw(st.sampled_from(["not mlflow", "half-made", "truncated"]), label="store")
    if kind == "not mlflow":
        blob = _not_a_store(data)
        if blob is None:
            tables = data.draw(
                st.lists(st.sampled_from(["runs", "experiments", "alembic_version", "notes", "metrics"]), max_size=3),
                label="tables",
            )
            with contextlib.closing(sqlite3.connect(db)) as con:
                con.execute("CREATE TABLE other_program (x INTEGER)")
                for t in sorted(set(tables) - {"runs", "experiments"} if "alembic_version" in tables else set(tables)):
                    con.execute(f"CREATE TABLE {t} (x INTEGER)")
                con.commit()
        else:
            db.write_bytes(blob)
    elif kind == "half-made":
        db.write_bytes(store)
        with contextlib.closing(sqlite3.connect(db)) as con:
            how = data.draw(st.sampled_from(["leftover table", "revision"]), label="half")
            if how == "leftover table":
                name = data.draw(st.sampled_from(["runs", "metrics", "latest_metrics", "params", "x"]), label="tmp")
                con.execute(f"CREATE TABLE _alembic_tmp_{name} (x INTEGER)")
            else:
                rev = data.draw(st.sampled_from(["", "0000", "deadbeef", "451aebb31d03"]), label="revision")
                con.execute("UPDATE alembic_version SET version_num = ?", (rev,))
            con.commit()
    else:
        db.write_bytes(store[: data.draw(st.integers(1, len(store) - 1), label="keep")])
    return kind, db


def _integrity_ok(db: Path) -> bool:
    try:
        with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True)) as con:
            return con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    except sqlite3.DatabaseError:
        return False


@fuzz_settings(small=5, large=160)
@given(data=st.data())
def test_a_damaged_store_is_refused_named_and_left_as_it_is(data, a_store, tmp_path_factory, monkeypatch):
    """A job (``ensure_store``), ``sphri store check`` and ``sphri store repair`` on a store that is not
    MLflow's, half-made (an interrupted migration) or truncated: a named error, or the store accepted
    whole; ``check`` and a refusal never change the file."""
    from sphri.tracking.store import ensure_store, problems, repair

    tmp = tmp_path_factory.mktemp("case")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp / "cache"))
    monkeypatch.setenv("SPHRI_STORE_TEMPLATE", "0")
    kind, db = _store_case(data, tmp, a_store)
    before = snapshot(db.parent)
    with no_hang(f"store {kind}"):
        try:
            ensure_store(f"sqlite:///{db}")
            exc = None
        except Exception as e:  # named, or a traceback
            exc = e
    may = {"mlflow.db.lock", "mlflow_schema_head.json"}
    if exc is None and not _integrity_ok(db):
        lost("store", kind, "a damaged store was accepted without a word")
    if exc is not None:
        unchanged("store", kind, before, snapshot(db.parent), may)
    verdict("store", kind, exc)
    # `sphri store check`, then `repair`: named or done; a file that is not a store is never touched
    with no_hang(f"store check {kind}"):
        try:
            found = problems(db, timeout=1.0)
        except Exception as e:
            verdict("store", f"check {kind}", e)
        else:  # `sphri store check` prints what it found (exit 1), or ok
            TALLIES["store"].add(f"store: check {kind}", NAMED if found else UNCHANGED)
    if kind == "not mlflow":
        before = snapshot(db.parent)
        with no_hang("repair"):
            try:
                repair(db, timeout=1.0)
                exc = None
            except Exception as e:
                exc = e
        assert exc is not None, "repair accepted a file that is not an MLflow store"
        unchanged("store", "repair not mlflow", before, snapshot(db.parent), may)
        verdict("store", "repair not mlflow", exc)


@pytest.mark.parametrize("how", ["lock", "open"])
def test_a_store_another_process_holds_is_busy_and_kept(how, a_store, tmp_path, monkeypatch):
    """A second process holds the store (``BEGIN EXCLUSIVE``, or only open): check and repair are named,
    busy not broken, and the file is kept byte for byte."""
    from sphri.tracking.store import StoreBusy, problems, repair

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    db = tmp_path / "o" / "mlflow.db"
    db.parent.mkdir()
    db.write_bytes(a_store.read_bytes())
    with contextlib.closing(sqlite3.connect(db)) as con:  # broken, so that repair has something to do
        con.execute("CREATE TABLE _alembic_tmp_runs (x INTEGER)")
        con.commit()
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(db), how], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "holding"
        before = snapshot(db.parent)
        for step in ("check", "repair"):
            with no_hang(f"{step} held {how}"):
                try:
                    (problems if step == "check" else repair)(db, timeout=0.5)
                    exc = None
                except Exception as e:
                    exc = e
            if step == "repair" or how == "lock":
                assert isinstance(exc, StoreBusy), exc
            verdict("store", f"{step} held ({how})", exc)
        unchanged("store", f"held ({how})", before, snapshot(db.parent), {"mlflow.db.lock", "mlflow_schema_head.json"})
    finally:
        proc.kill()
        proc.wait(30)


# ------------------------------------------------------------------ output folders
def _target(data, root: Path) -> tuple[str, Path]:
    """An ``out`` that already holds something: ``(kind, path)``."""
    kind = data.draw(
        st.sampled_from(
            [
                "folder with files",
                "file",
                "link to a folder outside",
                "link to a file outside",
                "dangling link",
                "below a file",
                "empty folder",
                "new",
            ]
        ),
        label="target",
    )
    outside = root / "outside"
    (outside / "keep").mkdir(parents=True)
    (outside / "keep" / "data.bin").write_bytes(b"keep me")
    out = root / "work" / "out"
    out.parent.mkdir()
    if kind == "folder with files":
        out.mkdir()
        for i in range(data.draw(st.integers(1, 3), label="files")):
            (out / f"part{i}.parquet").write_bytes(b"old")
    elif kind == "file":
        out.write_bytes(b"an old model")
    elif kind == "link to a folder outside":
        out.symlink_to(outside / "keep")
    elif kind == "link to a file outside":
        out.symlink_to(outside / "keep" / "data.bin")
    elif kind == "dangling link":
        out.symlink_to(root / "nowhere")
    elif kind == "below a file":
        (root / "work" / "f").write_bytes(b"x")
        out = root / "work" / "f" / "out"
    elif kind == "empty folder":
        out.mkdir()
    return kind, out


@fuzz_settings(small=8, large=240)
@given(data=st.data())
def test_an_output_that_exists_is_refused_before_anything_is_written(data, tmp_path_factory):
    """``sphri synthesize out=`` (a folder written whole) and ``sphri export out=`` (a file): an existing
    target, a link, a path below a file are named errors and nothing is changed; a new or empty target is
    accepted."""
    from sphri.config import check_output_dir, check_output_file

    root = tmp_path_factory.mktemp("out")
    kind, out = _target(data, root)
    as_file = data.draw(st.booleans(), label="a file (export)")
    before = snapshot(root)
    try:
        if as_file:
            check_output_file(str(out), key="out", overwrite=False)
        else:
            check_output_dir(str(out), key="out", overwrite=False)
        exc = None
    except Exception as e:
        exc = e
    unchanged("outputs", kind, before, snapshot(root), set())
    accepted = {"new", "empty folder"} | ({"dangling link"} if as_file else set())
    if exc is None and kind not in accepted:
        lost("outputs", kind, f"out={out} ({kind}) accepted: it would be written over")
    verdict("outputs", f"{'file' if as_file else 'folder'}: {kind}", exc)


@fuzz_settings(small=8, large=160)
@given(data=st.data())
def test_an_out_inside_the_output_dirs_managed_folders_is_refused(data, tmp_path_factory):
    """``sphri coverage out=`` equal to, holding or inside ``output_dir``'s store, artifacts or cache
    (directly or through a link) is a named error; an ``out`` of its own is accepted."""
    from omegaconf import OmegaConf

    from sphri.config import check_out_apart

    root = tmp_path_factory.mktemp("apart")
    output_dir = root / "o"
    (output_dir / "mlartifacts" / "1").mkdir(parents=True)
    (output_dir / "cache").mkdir()
    (output_dir / "mlflow.db").write_bytes(b"")
    where = data.draw(
        st.sampled_from(
            ["output_dir", "mlartifacts", "inside mlartifacts", "cache", "inside cache", "parent", "link", "apart"]
        ),
        label="out",
    )
    out = {
        "output_dir": output_dir,
        "mlartifacts": output_dir / "mlartifacts",
        "inside mlartifacts": output_dir / "mlartifacts" / "1" / "cov",
        "cache": output_dir / "cache",
        "inside cache": output_dir / "cache" / "x",
        "parent": root,
        "link": root / "linked",
        "apart": root / "coverage",
    }[where]
    if where == "link":
        out.symlink_to(output_dir / "mlartifacts")
    cfg = OmegaConf.create({"output_dir": str(output_dir), "cache": {"dir": str(output_dir / "cache")}})
    try:
        check_out_apart(str(out), cfg)
        exc = None
    except Exception as e:
        exc = e
    if (exc is None) != (where == "apart"):
        lost("outputs", where, f"out={out} ({where}): {'accepted' if exc is None else exc}")
    verdict("outputs", f"out {where}", exc)


@pytest.mark.parametrize("fails", ["while writing", "before renaming"])
def test_a_replacement_that_fails_leaves_the_old_folder_whole(fails, tmp_path, monkeypatch):
    """``overwrite=true`` writes the new folder beside the old one: a full disk midway loses nothing."""
    from sphri.fsutil import replace_dir

    target = tmp_path / "data"
    target.mkdir()
    (target / "p1.parquet").write_bytes(b"old 1")
    (target / "p2.parquet").write_bytes(b"old 2")
    before = snapshot(tmp_path)
    with pytest.raises(OSError) as err:
        with replace_dir(target) as new:
            (new / "p1.parquet").write_bytes(b"new 1")
            if fails == "before renaming":
                monkeypatch.setattr(os, "replace", _no_space)
                monkeypatch.setattr(os, "rename", _no_space)
            else:
                raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.undo()
    unchanged("outputs", f"replace {fails}", before, snapshot(tmp_path), set())
    verdict("outputs", f"replace failing {fails}", err.value)


def _no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


# ------------------------------------------------------------------ links
def _linked_cache(data, root: Path) -> str:
    """A stage cache whose folders, index or entries are links (out of the cache, loops, devices)."""
    from sphri.cache import StageCache

    cache_dir = root / "cache"
    cache = StageCache(cache_dir, key=None)
    cache.get_or_compute("evaluate", "k1", lambda: {"x": 1})
    outside = root / "outside"
    outside.mkdir()
    (outside / "victim.entry").write_bytes(b"not the cache's")
    (outside / "victim.json").write_text("{}")
    stage = cache_dir / "contact"
    kind = data.draw(
        st.sampled_from(
            ["stage folder", "by-path index", "entry", "loop", "two-link loop", "device", "dangling", "lock"]
        ),
        label="link",
    )
    if kind == "stage folder":
        stage.symlink_to(outside)
    elif kind == "by-path index":
        (cache_dir / "evaluate" / "by-path").mkdir(exist_ok=True)
        os.rmdir(cache_dir / "evaluate" / "by-path")
        (cache_dir / "evaluate" / "by-path").symlink_to(outside)
    elif kind == "entry":
        stage.mkdir()
        (stage / "k2.entry").symlink_to(outside / "victim.entry")
    elif kind == "loop":
        stage.mkdir()
        (stage / "k3.entry").symlink_to(stage / "k3.entry")
    elif kind == "two-link loop":
        stage.mkdir()
        (stage / "a.entry").symlink_to(stage / "b.entry")
        (stage / "b.entry").symlink_to(stage / "a.entry")
    elif kind == "device":
        stage.mkdir()
        (stage / "z.entry").symlink_to("/dev/zero")
    elif kind == "dangling":
        stage.symlink_to(root / "nowhere")
    else:
        stage.mkdir()
        (stage / "k4.entry").write_bytes(b"x")
        (stage / "k4.lock").symlink_to(outside / "victim.json")
    return kind


@fuzz_settings(small=6, large=160)
@given(data=st.data())
def test_cache_clear_and_info_never_follow_a_link(data, tmp_path_factory, capsys):
    """``sphri cache info`` and ``sphri cache clear`` (all, or one stage) over links out of the cache,
    loops and devices: done or a named error, nothing outside the cache changed, nothing blocks."""
    from sphri.command import main as sphri_main

    root = tmp_path_factory.mktemp("links")
    kind = _linked_cache(data, root)
    before = snapshot(root / "outside")
    args = data.draw(st.sampled_from([["info"], ["clear"], ["clear", "--stage", "contact"]]), label="command")
    with no_hang(f"cache {' '.join(args)} over {kind}"):
        try:
            code = sphri_main(["cache", *args, f"dir={root / 'cache'}"])
            exc = None
        except SystemExit as e:  # the argument parser's exit 2, one line
            code, exc = e.code, None
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) <= 1, err
    unchanged("links", kind, before, snapshot(root / "outside"), set())
    TALLIES["links"].add(f"links: cache {args[0]} over {kind}", NAMED if code else UNCHANGED)
    assert exc is None


@fuzz_settings(small=5, large=80)
@given(data=st.data())
def test_input_fingerprints_over_link_loops_end_and_name_what_they_skip(data, tmp_path_factory):
    """Fingerprinting ``data.root`` (what every job does) where it holds link loops, links out of the
    folder or to devices: it ends, named or with a warning, and reads nothing outside."""
    from sphri.inputs import _files_below

    root = tmp_path_factory.mktemp("walk")
    d = root / "dataset" / "arm"
    d.mkdir(parents=True)
    (d / "manifest.json").write_text("{}")
    kind = data.draw(st.sampled_from(["self loop", "folder loop", "parent folder", "device", "dangling"]), label="k")
    if kind == "self loop":
        (d / "loop").symlink_to(d / "loop")
    elif kind == "folder loop":
        (d / "sub").mkdir()
        (d / "sub" / "up").symlink_to(d)
    elif kind == "parent folder":
        (d / "up").symlink_to(root)
    elif kind == "device":
        (d / "zeros").symlink_to("/dev/zero")
    else:
        (d / "gone").symlink_to(root / "nowhere")
    with no_hang(f"fingerprint over {kind}"), WarningCatcher() as caught:
        try:
            files = _files_below(root / "dataset")
            exc = None
        except Exception as e:
            exc, files = e, []
    if exc is None:
        assert all(str(f).startswith(str(root / "dataset")) for f in files), files
        assert d / "manifest.json" in files
    verdict("links", f"fingerprint over {kind}", exc, warned=bool(caught.records))


# ------------------------------------------------------------------ FIFOs
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs os.mkfifo")
@pytest.mark.parametrize("where", ["data.root file", "cache entry", "model file", "mlflow.db", "layout file"])
def test_a_fifo_where_a_file_is_read_never_blocks(where, tmp_path, monkeypatch):
    """A FIFO (a named pipe: opening it blocks until a writer comes) where sphri reads a file: skipped or
    a named error within HANG_S seconds."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with no_hang(f"a FIFO as the {where}"), WarningCatcher() as caught:
        try:
            if where == "data.root file":
                from sphri.inputs import _files_below

                assert fifo not in _files_below(tmp_path)
            elif where == "cache entry":
                from sphri.cache import StageCache

                cache = StageCache(tmp_path / "cache", key=None)
                path = cache.path("evaluate", "k1")
                path.parent.mkdir(parents=True)
                fifo.rename(path)
                assert cache.get_or_compute("evaluate", "k1", lambda: {"x": 2}) == {"x": 2}
            elif where == "model file":
                from sphri.export.model_file import load_model

                load_model(fifo)
            elif where == "mlflow.db":
                from sphri.tracking.store import ensure_store

                (tmp_path / "o").mkdir()
                fifo.rename(tmp_path / "o" / "mlflow.db")
                ensure_store(f"sqlite:///{tmp_path / 'o' / 'mlflow.db'}")
            else:
                from sphri.layout.file import read_layout_file

                read_layout_file(fifo)
            exc = None
        except Exception as e:
            exc = e
    if where != "cache entry" and exc is None and not caught.records:
        lost("fifo", where, "a FIFO was taken for a file without a word")
    verdict("fifo", where, exc, warned=bool(caught.records))


# ------------------------------------------------------------------ huge sizes
@fuzz_settings(small=8, large=120)
@given(data=st.data())
def test_work_past_the_memory_limit_is_refused_with_its_estimate(data, monkeypatch, capsys):
    """Participants, a layout's taxels, the report's bootstrap: drawn up to far past the limit
    (``SPHRI_MAX_MEMORY_GIB``); refused with the estimate and the setting before anything is allocated,
    or accepted under it."""
    from sphri.layout.common import check_taxel_count
    from sphri.limits import over_limit

    limit = data.draw(st.sampled_from(["0.01", "0.5", "4"]), label="limit GiB")
    monkeypatch.setenv("SPHRI_MAX_MEMORY_GIB", limit)
    what = data.draw(st.sampled_from(["participants", "taxels", "n_boot"]), label="size")
    n = data.draw(st.integers(1, 10**13) | st.sampled_from([10**6, 10**9, 10**12, 2**62]), label="n")
    exc, h = None, 0
    if what == "participants":
        from sphri.data.schema import SyntheticDataSchema

        try:
            SyntheticDataSchema(participants=min(n, 10**9)).check_size()
        except Exception as e:
            exc = e
    elif what == "taxels":
        h = max(1, int(min(n, 10**7) ** 0.5))
        try:
            check_taxel_count(h, h, h, 1.0)
        except Exception as e:
            exc = e
    else:
        from sphri.command import main as sphri_main

        code = sphri_main(["report", "/nonexistent-sweep", f"n_boot={n}"])
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "Traceback" not in err, err
        if "n_boot" in err:
            assert "SPHRI_MAX_MEMORY_GIB" in err and code == 2, err
            exc = ConfigError(err)
        what = "n_boot"
    if exc is not None:
        assert "SPHRI_MAX_MEMORY_GIB" in str(exc), exc
    elif what != "n_boot":  # accepted: the estimate is under the limit
        need = {"participants": None, "taxels": h * h * 7300.0}[what]
        assert need is None or over_limit("x", need) is None
    verdict("huge", what, exc)


# ------------------------------------------------------------------ crafted codec payloads
IMPORT_BAIT = [
    "sphri.command:main",
    "sphri.__main__:main",
    "sphri.cli:validate_command",
    "os:system",
    "subprocess:Popen",
    "builtins:eval",
    "pickle:loads",
    "numpy:load",
    "antigravity:x",
    "this:x",
    "sphri.types:Link.__init__",
    "sphri.types:CVResult",
]


def _npz(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


@fuzz_settings(small=6, large=160)
@given(data=st.data())
def test_a_crafted_payload_naming_code_imports_nothing_and_is_recomputed(data, tmp_path_factory, monkeypatch):
    """A cache entry sealed with a valid plain checksum whose value names a module or function to build
    (``__dc__``), at the top or nested, with or without a cache key: nothing is imported, nothing exits,
    the entry is discarded with a warning and the stage recomputed."""
    from sphri.cache import StageCache, seal

    name = data.draw(st.sampled_from(IMPORT_BAIT) | st.text(min_size=1, max_size=30), label="class")
    nested = data.draw(st.booleans(), label="nested")
    keyed = data.draw(st.booleans(), label="key configured")
    monkeypatch.setattr(sys, "argv", ["sphri-cache", "--no-such-option"])
    if keyed:
        monkeypatch.setenv("SPHRI_CACHE_KEY", "lab key")
    else:
        monkeypatch.delenv("SPHRI_CACHE_KEY", raising=False)
    value: object = {"__dc__": name, "f": {"x": 1}}
    if nested:
        value = {"__tuple__": [{"__dc__": "sphri.types:RunMeta", "f": {"inner": value}}, 3]}
    meta = {"stage": "evaluate", "key": "k1", "files": {}, "value": value}
    root = tmp_path_factory.mktemp("codec")
    cache = StageCache(root)
    path = cache.path("evaluate", "k1")
    path.parent.mkdir(parents=True)
    path.write_bytes(seal(_npz({"__meta__": np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)})))
    modules = set(sys.modules)
    calls: list[int] = []
    with WarningCatcher() as caught:
        try:
            got = cache.get_or_compute("evaluate", "k1", lambda: calls.append(1) or {"fresh": True})
        except SystemExit as e:  # pragma: no cover - the failure this test guards against
            raise AssertionError(f"reading a crafted entry exited ({e.code!r})") from None
    bait = name.partition(":")[0]
    assert bait in modules or bait not in sys.modules, f"decoding imported {bait}"
    if got != {"fresh": True} or calls != [1]:
        lost("codec", name, f"a crafted entry naming {name!r} was served: {got!r}")
    assert caught.records, "discarded without a warning"
    verdict("codec", "names a module" if ":" in name else "names something else", None, warned=True)


# ------------------------------------------------------------------ URDF mesh paths
@fuzz_settings(small=7, large=160)
@given(data=st.data())
def test_a_mesh_path_out_of_the_robot_folder_is_refused_never_read(data, tmp_path_factory, monkeypatch):
    """URDF mesh paths climbing out (``..`` at any depth, ``file://``, absolute, a link inside leading out,
    a link loop): a named error, and no file outside the robot's folder is opened; a mesh inside loads."""
    import trimesh

    from sphri.robots.urdf_tree import MeshResolver

    root = tmp_path_factory.mktemp("urdf")
    robot = root / "robot"
    (robot / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=[0.3, 0.1, 0.1]).export(robot / "meshes" / "arm.stl")
    (root / "outside").mkdir()
    trimesh.creation.box(extents=[0.3, 0.2, 0.1]).export(root / "outside" / "arm.stl")
    kind = data.draw(
        st.sampled_from(["climb", "climb inside first", "file uri", "absolute", "link out", "loop", "inside"]),
        label="mesh",
    )
    depth = data.draw(st.integers(1, 12), label="depth")
    mesh = {
        "climb": "package://u/" + "../" * depth + "outside/arm.stl",
        "climb inside first": "package://u/meshes/" + "../" * (depth + 1) + "outside/arm.stl",
        "file uri": f"file://{root / 'outside' / 'arm.stl'}",
        "absolute": str(root / "outside" / "arm.stl"),
        "link out": "package://u/meshes/out.stl",
        "loop": "package://u/meshes/loop.stl",
        "inside": "package://u/meshes/arm.stl",
    }[kind]
    if kind == "link out":
        (robot / "meshes" / "out.stl").symlink_to(root / "outside" / "arm.stl")
    elif kind == "loop":
        (robot / "meshes" / "loop.stl").symlink_to(robot / "meshes" / "loop.stl")
    urdf_with(robot, mesh)
    opened: list[str] = []
    real_open = open

    def watched(file, *args, **kwargs):
        opened.append(str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", watched)
    with no_hang(f"mesh {kind}"):
        try:
            path, _, note = MeshResolver(robot).resolve(mesh)
            exc = None if path is not None else FileNotFoundError(f"{mesh}: not found in {robot}")  # the loader's
        except Exception as e:
            exc, path, note = e, None, ""
    monkeypatch.undo()
    if any(str(root / "outside") in f for f in opened):
        lost("urdf", kind, f"opened a file outside the robot's folder: {opened}")
    if exc is None and not Path(path).resolve().is_relative_to(robot.resolve()):
        lost("urdf", kind, f"{mesh!r} resolved to {path}, not a file inside {robot}")
    if kind != "inside" and exc is None and not note:
        lost("urdf", kind, f"{mesh!r} accepted without a word")
    # a path outside whose file name a mesh inside the folder has: that mesh, named in the loader's note
    verdict("urdf", kind, exc, warned=bool(note) and kind != "inside")
