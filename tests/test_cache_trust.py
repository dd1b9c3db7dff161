"""Cache entries authenticated, not only checksummed (issue 29, item 2).

Reproducers of the issue: an entry rebuilt with a valid checksum (accuracy 0.99) was read and reported;
crafted entries (an int8 overflow, a 200,000-deep JSON document, a 3x3 confusion matrix for 8 gestures,
a bad by-path index) raised on every later run instead of being discarded; entries were written 0600.
"""

from __future__ import annotations

import io
import json
import logging
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from sphri.cache import MAGIC, CorruptEntry, StageCache, read_entry, seal, write_entry
from sphri.config import ConfigError
from sphri.types import GESTURES, CVResult, FoldResult, RunMeta

CONTRACT = (CVResult, RunMeta)


def _fold(name: str, correct: int, n: int, g: int = len(GESTURES)) -> FoldResult:
    cm = np.zeros((g, g), dtype=np.int64)
    cm[0, 0] = correct
    cm[0, 1] = n - correct
    recall = np.full(g, np.nan)
    recall[0] = correct / n
    return FoldResult(name, n, correct / n, 0.5, cm, recall)


def _meta() -> RunMeta:
    return RunMeta("synthetic", True, 2, 10, 100, 30.0, {}, "r", "arm", "l", "mesh", 0.0, {}, 10, 0, 20)


def _evaluation(correct: int = 30) -> tuple[CVResult, RunMeta]:
    return CVResult("loso", "rf", [_fold("p1", correct, 100), _fold("p2", correct, 100)]), _meta()


def _payload(path: Path) -> bytes:
    """The npz payload of a format-3 entry."""
    return path.read_bytes()[len(MAGIC) + 64 :]


def _arrays(payload: bytes) -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(payload), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _npz(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _with_meta(payload: bytes, edit) -> bytes:
    arrays = _arrays(payload)
    meta = json.loads(arrays["__meta__"].tobytes().decode())
    edit(meta)
    arrays["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    return _npz(arrays)


def _forge_accuracy(payload: bytes, accuracy: float) -> bytes:
    """Rewrite every fold to ``accuracy`` (confusion matrix to match, so the entry is self-consistent)."""
    arrays = _arrays(payload)
    meta = json.loads(arrays["__meta__"].tobytes().decode())
    folds = meta["value"]["__tuple__"][0]["f"]["folds"]
    for f in folds:
        fields = f["f"]
        n = fields["n_test"]
        ref = fields["confusion"]["__nd__"]
        cm = np.zeros_like(arrays[ref])
        cm[0, 0] = round(accuracy * n)
        cm[0, 1] = n - cm[0, 0]
        arrays[ref] = cm
        fields["accuracy"] = cm[0, 0] / n
    arrays["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    return _npz(arrays)


def _computes(cache: StageCache, key: str = "k1") -> tuple[list[int], tuple]:
    calls: list[int] = []
    value = cache.get_or_compute("evaluate", key, lambda: calls.append(1) or _evaluation(), contract=CONTRACT)
    return calls, value


def test_a_forged_entry_with_a_valid_checksum_is_recomputed_when_a_key_is_configured(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("SPHRI_CACHE_KEY", "team secret")
    cache = StageCache(tmp_path)
    calls, (cv, _) = _computes(cache)
    assert calls == [1] and cv.folds[0].accuracy == 0.3
    path = cache.path("evaluate", "k1")
    assert _computes(StageCache(tmp_path))[0] == []  # signed with the key: read back
    # someone who can write to the cache but has no key rebuilds the entry with accuracy 0.99
    path.write_bytes(seal(_forge_accuracy(_payload(path), 0.99), key=None))
    without_key = StageCache(tmp_path, key=None)
    found, forged = without_key.read("evaluate", "k1", CONTRACT)
    assert found and forged[0].folds[0].accuracy == 0.99  # a valid plain checksum: only a key tells them apart
    path.write_bytes(seal(_forge_accuracy(_payload(path), 0.99), key=None))
    caplog.set_level(logging.WARNING, logger="sphri")
    calls, (cv, _) = _computes(StageCache(tmp_path))
    assert calls == [1] and cv.folds[0].accuracy == 0.3  # recomputed, not read
    assert str(path) in caplog.text and "written without the key" in caplog.text
    # signed with another key: recomputed too
    path.write_bytes(seal(_forge_accuracy(_payload(path), 0.99), key=b"another key"))
    caplog.clear()
    calls, (cv, _) = _computes(StageCache(tmp_path))
    assert calls == [1] and cv.folds[0].accuracy == 0.3 and "does not match the key" in caplog.text


def test_the_key_can_come_from_a_file(tmp_path, monkeypatch):
    key_file = tmp_path / "cache.key"
    key_file.write_text("from a file\n")
    monkeypatch.setenv("SPHRI_CACHE_KEY_FILE", str(key_file))
    cache = StageCache(tmp_path / "c")
    assert cache.key == b"from a file"
    write_entry(tmp_path / "e.entry", np.arange(3))
    with pytest.raises(CorruptEntry, match="not signed with the configured cache key"):
        read_entry(tmp_path / "e.entry", key=b"other")
    assert read_entry(tmp_path / "e.entry")[1].tolist() == [0, 1, 2]
    monkeypatch.setenv("SPHRI_CACHE_KEY_FILE", str(tmp_path / "missing.key"))
    with pytest.raises(ConfigError, match=r"SPHRI_CACHE_KEY_FILE=.*missing\.key"):
        StageCache(tmp_path / "c")
    assert StageCache(tmp_path / "c", enabled=False).key is None  # a disabled cache needs no key


def _deep_json(depth: int) -> str:
    return "[" * depth + "]" * depth


@pytest.mark.parametrize(
    "case", ["int8_overflow", "deep_json", "confusion_3x3", "accuracy_not_the_matrix", "old_format"]
)
def test_a_crafted_entry_is_discarded_and_recomputed_not_raised(tmp_path, case, caplog):
    cache = StageCache(tmp_path, key=None)
    _computes(cache)
    path = cache.path("evaluate", "k1")
    payload = _payload(path)
    if case == "int8_overflow":

        def edit(meta):
            meta["value"]["__tuple__"][0]["f"]["model"] = {"__np__": "|i1", "v": 1000}

        blob = seal(_with_meta(payload, edit))
    elif case == "deep_json":
        doc = json.dumps({"stage": "evaluate", "key": "k1", "files": {}, "value": None})
        doc = doc.replace("null", _deep_json(200_000))
        arrays = _arrays(payload)
        arrays["__meta__"] = np.frombuffer(doc.encode(), dtype=np.uint8)
        blob = seal(_npz(arrays))
    elif case == "confusion_3x3":
        arrays = _arrays(payload)
        meta = json.loads(arrays["__meta__"].tobytes().decode())
        ref = meta["value"]["__tuple__"][0]["f"]["folds"][0]["f"]["confusion"]["__nd__"]
        arrays[ref] = np.array([[30, 70, 0], [0, 0, 0], [0, 0, 0]], dtype=np.int64)
        blob = seal(_npz(arrays))
    elif case == "accuracy_not_the_matrix":

        def edit(meta):
            meta["value"]["__tuple__"][0]["f"]["folds"][0]["f"]["accuracy"] = 0.99

        blob = seal(_with_meta(payload, edit))
    else:  # an entry of the previous format, valid in its day
        import hashlib

        blob = b"SPHRICACHE2\n" + hashlib.blake2b(payload, digest_size=32).digest() + payload
    path.write_bytes(blob)
    caplog.set_level(logging.WARNING, logger="sphri")
    for attempt in range(2):  # discarded once, then the recomputed entry is read
        calls, (cv, _) = _computes(StageCache(tmp_path, key=None))
        assert cv.folds[0].accuracy == 0.3
        if attempt == 0:
            assert calls == [1]
            assert f"discarding corrupt entry for stage evaluate ({path}" in caplog.text
            assert "Traceback" not in caplog.text
        else:
            assert calls == []


def test_a_crafted_entry_read_directly_is_one_named_error(tmp_path):
    write_entry(tmp_path / "e.entry", np.arange(3), key=None)
    payload = _payload(tmp_path / "e.entry")
    arrays = _arrays(payload)
    arrays["__meta__"] = np.frombuffer(('{"value": ' + _deep_json(200_000) + "}").encode(), dtype=np.uint8)
    (tmp_path / "e.entry").write_bytes(seal(_npz(arrays)))
    with pytest.raises(CorruptEntry, match=r"e\.entry"):
        read_entry(tmp_path / "e.entry", key=None)


def test_a_malformed_by_path_index_is_ignored(tmp_path, caplog):
    cache = StageCache(tmp_path, key=None)
    index = cache._index_path("data", "pk")
    index.parent.mkdir(parents=True)
    index.write_text(json.dumps({"key": "old", "files": ["a.parquet", "b.parquet"]}))
    caplog.set_level(logging.WARNING, logger="sphri")
    value = cache.get_or_compute("data", "new", lambda: np.arange(4), files={"a.parquet": "f1"}, path_key="pk")
    assert value.tolist() == [0, 1, 2, 3] and str(index) in caplog.text
    assert json.loads(index.read_text())["key"] == "new"  # rewritten by the run


@pytest.mark.parametrize("umask", [0o022, 0o002])
def test_entries_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        cache = StageCache(tmp_path, key=None)
        cache.get_or_compute("data", "k", lambda: np.arange(3), files={"x": "1"}, path_key="pk")
    finally:
        os.umask(old)
    for p in (cache.path("data", "k"), cache._index_path("data", "pk")):
        assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~umask, p


def test_the_fingerprint_memo_follows_the_umask(tmp_path):
    from sphri.inputs import FingerprintMemo

    (tmp_path / "mesh.stl").write_bytes(b"solid x")
    old = os.umask(0o002)
    try:
        memo = FingerprintMemo(tmp_path / "cache" / "fingerprints.json")
        memo.digest(tmp_path / "mesh.stl")
        memo.save()
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "cache" / "fingerprints.json").stat().st_mode) == 0o664


def test_an_entry_naming_a_module_to_import_is_discarded_not_an_exit(tmp_path, monkeypatch, caplog):
    """An entry with a valid plain digest naming ``sphri.cache.__main__:X`` as its dataclass: importing
    that module ran the cache command (``sys.exit(main())``) while it existed (issue 53 removed it; any
    module that acts on import is the same case). Only sphri's data types are rebuilt; the name is
    refused, the module never imported, and the entry discarded and recomputed."""
    import sys

    monkeypatch.delitem(sys.modules, "sphri.cache.__main__", raising=False)
    monkeypatch.setattr(sys, "argv", ["sphri-cache", "--no-such-option"])  # the command would exit 2
    meta = {"stage": "evaluate", "key": "k1", "files": {}, "value": {"__dc__": "sphri.cache.__main__:X", "f": {}}}
    cache = StageCache(tmp_path, key=None)
    path = cache.path("evaluate", "k1")
    path.parent.mkdir(parents=True)
    path.write_bytes(seal(_npz({"__meta__": np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)})))
    caplog.set_level(logging.WARNING, logger="sphri")
    try:
        calls, (cv, _) = _computes(cache)
    except SystemExit as exc:  # pragma: no cover - the failure this test shows
        pytest.fail(f"reading a cache entry exited ({exc.code!r})")
    assert calls == [1] and cv.folds[0].accuracy == 0.3
    assert "sphri.cache.__main__" not in sys.modules
    assert "not a data type sphri stores" in caplog.text and str(path) in caplog.text


def test_a_value_raising_system_exit_while_decoding_is_a_decode_error(monkeypatch):
    from sphri.codec import DecodeError, decode, encode

    def leave(self):
        raise SystemExit(3)

    tree, arrays = encode(_evaluation())
    monkeypatch.setattr(CVResult, "check_decoded", leave)
    with pytest.raises(DecodeError, match=r"SystemExit\(3\)"):
        decode(tree, arrays)


def test_an_unsigned_fingerprint_memo_cannot_keep_a_replaced_file_from_recomputing(tmp_path, monkeypatch, caplog):
    """With a cache key, whoever can write ``fingerprints.json`` but has no key gives a replaced mesh its
    old digest (the new size, times and inode next to the old hash): the stage keys stay those of the
    signed entries, and the old surface would be served. The memo is signed with the key; one that
    does not verify is ignored with a warning and every file hashed again."""
    from sphri import inputs
    from tests.test_cache_content import make, sources, write_arm

    monkeypatch.setenv("SPHRI_CACHE_KEY", "team secret")
    mesh = tmp_path / "arm.obj"
    write_arm(mesh)
    robot = ["robot=mesh", f"robot.links={{l_arm: {mesh}}}", "robot.regions={arm: l_arm}", "robot.units=m"]
    first, _ = make(tmp_path, *robot)
    assert sources(first, "surface") == {"surface": "computed"}
    assert sources(make(tmp_path, *robot)[0], "surface") == {"surface": "cache"}
    memo_path = tmp_path / "cache" / inputs.MEMO_NAME
    doc = json.loads(memo_path.read_text())
    entries = doc.get("entries", doc)
    old = entries[str(mesh)][4]
    write_arm(mesh, scale=1.1)  # another mesh at the same path
    st = mesh.stat()
    entries[str(mesh)] = [st.st_size, st.st_mtime_ns, st.st_ino, st.st_ctime_ns, old]
    caplog.set_level(logging.WARNING, logger="sphri")
    for forged in (entries, {"entries": entries, "hmac": doc.get("hmac", "0" * 64)}):  # unsigned; signature kept
        memo_path.write_text(json.dumps(forged))
        monkeypatch.setattr(inputs, "_MEMOS", {})  # a new process
        again, _ = make(tmp_path, *robot)
        assert again.key("surface") != first.key("surface"), "the replaced mesh must not be served"
        assert "not signed with the cache key" in caplog.text and str(memo_path) in caplog.text
        caplog.clear()
    monkeypatch.setattr(inputs, "_MEMOS", {})
    memo = inputs.FingerprintMemo(memo_path, b"team secret")  # the memo the run signed is used: no rehash
    assert memo.digest(mesh) != old and memo.hashed == []
