"""The stage cache: atomic writes, corruption detection, process safety."""

from __future__ import annotations

import multiprocessing as mp
import os
from pathlib import Path

import numpy as np
import pytest

from sphri.cache import MAGIC, CorruptEntry, StageCache, read_entry, stage_key, write_entry
from sphri.codec import DecodeError
from sphri.integrity import stable_hash


def test_keys_are_stable_and_order_independent():
    a = stage_key("contact", "1", {"margin_m": 0.0, "k": 5}, {"data": "abc"})
    b = stage_key("contact", "1", {"k": 5, "margin_m": 0.0}, {"data": "abc"})
    assert a == b
    assert a != stage_key("contact", "2", {"k": 5, "margin_m": 0.0}, {"data": "abc"})
    assert a != stage_key("contact", "1", {"k": 5, "margin_m": 0.001}, {"data": "abc"})
    assert a != stage_key("contact", "1", {"k": 5, "margin_m": 0.0}, {"data": "abd"})
    assert stable_hash([1, "x"]) != stable_hash(["x", 1])


def test_round_trip_and_hit(tmp_path: Path):
    cache = StageCache(tmp_path)
    calls = []
    value = {"x": np.arange(10.0), "n": 3}

    def compute():
        calls.append(1)
        return value

    first = cache.get_or_compute("data", "k1", compute)
    second = cache.get_or_compute("data", "k1", compute)
    assert len(calls) == 1
    np.testing.assert_array_equal(first["x"], second["x"])
    assert cache.misses == ["data"] and cache.hits == ["data"]
    # no temporary files are left behind
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == ["k1.entry", "k1.lock"]


@pytest.mark.parametrize("damage", ["truncate", "flip", "header", "empty"])
def test_corrupt_entry_is_detected_and_recomputed(tmp_path: Path, damage: str, caplog):
    cache = StageCache(tmp_path)
    cache.get_or_compute("contact", "k", lambda: np.ones(1000))
    path = cache.path("contact", "k")
    blob = bytearray(path.read_bytes())
    if damage == "truncate":
        blob = blob[: len(blob) // 2]
    elif damage == "flip":
        blob[-10] ^= 0xFF
    elif damage == "header":
        blob[: len(MAGIC)] = b"X" * len(MAGIC)
    else:
        blob = bytearray()
    path.write_bytes(bytes(blob))
    calls = []
    out = StageCache(tmp_path).get_or_compute("contact", "k", lambda: calls.append(1) or np.full(1000, 2.0))
    assert calls == [1], "a corrupt entry must never be used"
    assert out[0] == 2.0
    assert "corrupt" in caplog.text
    # and the recomputed entry is valid again
    found, again = StageCache(tmp_path).read("contact", "k")
    assert found and again[0] == 2.0


def test_disabled_cache_always_computes(tmp_path: Path):
    cache = StageCache(tmp_path, enabled=False)
    calls = []
    cache.get_or_compute("data", "k", lambda: calls.append(1))
    cache.get_or_compute("data", "k", lambda: calls.append(1))
    assert len(calls) == 2
    assert not (tmp_path / "data").exists()


def test_failed_compute_leaves_no_entry(tmp_path: Path):
    cache = StageCache(tmp_path)

    def boom():
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        cache.get_or_compute("data", "k", boom)
    assert not cache.path("data", "k").exists()


def _worker(root: str, counter: str, out: mp.Queue) -> None:
    cache = StageCache(Path(root))

    def compute():
        with open(counter, "a") as fh:  # count real computations across processes
            fh.write("x")
        import time

        time.sleep(0.3)
        return np.arange(100_000)

    value = cache.get_or_compute("contact", "shared", compute)
    out.put(int(value.sum()))


def test_concurrent_processes_compute_once(tmp_path: Path):
    counter = tmp_path / "count.txt"
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    procs = [ctx.Process(target=_worker, args=(str(tmp_path / "cache"), str(counter), q)) for _ in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    sums = [q.get(timeout=5) for _ in procs]
    assert all(p.exitcode == 0 for p in procs)
    assert sums == [sum(range(100_000))] * 4
    assert counter.read_text() == "x", "exactly one process computes a shared entry"
    leftovers = [n for n in os.listdir(tmp_path / "cache" / "contact") if n.endswith(".tmp")]
    assert leftovers == []


def test_an_entry_written_to_any_path_reads_back_and_a_bad_one_names_its_file(tmp_path):
    """write_entry/read_entry: the stage cache's format for one value outside the cache (bench windows)."""
    from sphri.testing.toy_windows import blob_windows
    from sphri.types import TaxelGeometry, WindowedFrames

    win = blob_windows(3, 2, 4, seed=0)
    path = write_entry(tmp_path / "w.entry", win, {"what": "test"})
    meta, back = read_entry(path, WindowedFrames)
    assert meta["what"] == "test" and isinstance(back, WindowedFrames)
    np.testing.assert_array_equal(back.x, win.x)
    np.testing.assert_array_equal(back.groups, win.groups)
    assert [p.name for p in tmp_path.iterdir()] == ["w.entry"]  # no temporary file left
    with pytest.raises(DecodeError, match="w.entry"):
        read_entry(path, TaxelGeometry)
    bad = tmp_path / "bad.entry"
    bad.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(CorruptEntry, match="bad.entry"):
        read_entry(bad)
