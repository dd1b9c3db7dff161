"""Issue 29, "Tracebacks instead of one line": each reproducer from the issue ends in one line naming the
value, with exit 2 (config) or 1 (runtime), before anything is computed or recorded."""

from __future__ import annotations

import sqlite3
import subprocess
from pathlib import Path

import forked_cli
import pytest


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return forked_cli.run(["-m", *args], cwd, None, 300)


_one_line = forked_cli.one_line


@pytest.mark.parametrize(
    "override, words",
    [
        ("output_dir=afile", ("output_dir=afile", "is a file")),  # was NotADirectoryError from Hydra's run folder
        ("output_dir=" + "a" * 5000, ("output_dir", "5000 bytes")),  # was OSError: File name too long
        ("output_dir=", ("output_dir=''",)),  # composed cache.dir=/cache
        ("seed=123456789012345678901234567890", ("seed=", "2**63")),  # was OverflowError after stages computed
    ],
)
def test_bad_run_settings_stop_in_one_line_before_any_stage(tmp_path: Path, override: str, words: tuple[str, ...]):
    (tmp_path / "afile").write_text("not a folder")
    proc = _run(["sphri", "+debug=fast", override], tmp_path)
    _one_line(proc, 2, "invalid config", *words)
    assert "computing" not in proc.stdout + proc.stderr


def test_glob_sweep_expands_to_components_only(tmp_path: Path):
    """`noise=glob(*)` raised "ConfigLoader is not set"; then it swept the internal *_schema entries too."""
    ok = _run(["sphri", "validate", "-m", "+debug=fast", "noise=glob(*)"], tmp_path)
    assert ok.returncode == 0, ok.stderr[-2000:]
    components = len(list((Path(__file__).resolve().parents[1] / "conf" / "noise").glob("*.yaml")))
    assert f"all {components} jobs compose" in ok.stdout and "_schema" not in ok.stdout, ok.stdout
    none = _run(["sphri", "-m", "+debug=fast", "noise=glob(zz*)", f"output_dir={tmp_path / 'o'}"], tmp_path)
    _one_line(none, 2, "noise=glob(zz*)", "matches no noise option", "salt_pepper")


def test_an_empty_sweep_is_refused_without_a_parent_run(tmp_path: Path):
    """`layout.res=range(5,5)` exited 0 with an empty MLflow parent run."""
    out = tmp_path / "o"
    proc = _run(
        ["sphri", "-m", "+debug=fast", "layout.res=range(5,5)", f"output_dir={out}", "hydra/launcher=serial"], tmp_path
    )
    _one_line(proc, 2, "layout.res=range(5,5)", "no job was started")
    assert not (out / "mlflow.db").exists()


def test_cache_clear_leaves_a_folder_named_like_an_entry(tmp_path: Path):
    """`cache clear` on a folder named *.entry raised IsADirectoryError."""
    folder = tmp_path / "cache" / "contact" / "x.entry"
    folder.mkdir(parents=True)
    proc = _run(["sphri", "cache", "clear", f"dir={tmp_path / 'cache'}"], tmp_path)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert "removed 0 entries" in proc.stdout and folder.is_dir()


def test_store_repair_on_a_revision_mlflow_does_not_know(tmp_path: Path):
    """`store repair` on a store whose alembic revision is unknown ended in alembic's CommandError traceback."""
    db = tmp_path / "mlflow.db"
    made = _run(["sphri", "store", "repair", str(db)], tmp_path)  # no file: a new, healthy store
    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking_uri=f"sqlite:///{db}")
    client.create_run(client.create_experiment("e"))  # a run to keep: repair migrates instead of replacing
    client._tracking_client.store.engine.dispose()  # this process closes the store: repair refuses one held open
    con = sqlite3.connect(db)
    con.execute("UPDATE alembic_version SET version_num = 'deadbeef'")
    con.commit()
    con.close()
    proc = _run(["sphri", "store", "repair", str(db)], tmp_path)
    line = [ln for ln in proc.stderr.strip().splitlines() if ln.startswith("sphri:")]
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, (made.stderr + proc.stderr)[-2000:]
    assert len(line) == 1 and "deadbeef" in line[0] and "the original is at" in line[0], proc.stderr


def test_a_read_only_output_dir_and_store_are_refused_before_computing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """Issue 29: a read-only output_dir or mlflow.db ended in a traceback. Permissions are simulated through
    os.access (the suite may run as root, for whom chmod changes nothing)."""
    import os

    from sphri.config import ConfigError, check_output_dir
    from sphri.tracking.store import BrokenStore, ensure_store

    locked = tmp_path / "locked"
    locked.mkdir()
    db = locked / "mlflow.db"
    db.write_bytes(b"")
    real = os.access
    monkeypatch.setattr(
        os, "access", lambda p, mode, **kw: False if Path(p).is_relative_to(locked) else real(p, mode, **kw)
    )
    with pytest.raises(ConfigError, match="read-only"):
        check_output_dir(str(locked / "out"))
    check_output_dir(str(tmp_path / "elsewhere"))  # a writable parent: fine
    with pytest.raises(BrokenStore, match="read-only"):
        ensure_store(f"sqlite:///{db}")
