"""Fuzz campaign, target 2: stage-cache entries and model files (issue 29, item 5).

Cache entries (an evaluation, ``(CVResult, RunMeta)``): raw corruptions (flipped bytes, truncation,
inserted, appended or zeroed bytes, another entry's header, an empty file) and crafted entries (one
node of the JSON document replaced, deleted or wrapped, then sealed again with a valid plain checksum).
``StageCache.get_or_compute`` must return the reference value every time: from the entry when it is
intact, recomputed (with a warning) otherwise; nothing may escape it. With a cache key configured a
crafted entry is always recomputed. Without a key a crafted entry with a valid checksum is read if it
decodes (documented in docs/RELIABILITY.md, 29-7): such cases must not crash and are counted apart.

Model files (a small Random Forest): the same raw corruptions must give a ``ModelFileError`` (one line)
or a model predicting identically; headers edited and signed again with the configured key (valid
digests, malformed fields) must give a ``ModelFileError`` or load, never a traceback.
"""

from __future__ import annotations

import dataclasses
import io
import json
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fuzz_support import (
    NAMED,
    SILENT,
    UNCHANGED,
    WARNED,
    Tally,
    WarningCatcher,
    fuzz_settings,
    mutate_bytes,
    mutate_json,
)
from hypothesis import given
from hypothesis import strategies as st

from sphri.cache import MAGIC, StageCache, seal
from sphri.export.model_file import MAGIC as MODEL_MAGIC
from sphri.export.model_file import ModelBundle, load_model, save_model, seal_model
from sphri.types import GESTURES, CVResult, FoldResult, RunMeta

CONTRACT = (CVResult, RunMeta)
KEY = b"fuzz-campaign-key"
FORGED_NO_KEY = "forged, read without a key (documented)"


def _evaluation(correct: int) -> tuple[CVResult, RunMeta]:
    g = len(GESTURES)

    def fold(name: str, n: int = 100) -> FoldResult:
        cm = np.zeros((g, g), dtype=np.int64)
        cm[0, 0], cm[0, 1] = correct, n - correct
        recall = np.full(g, np.nan)
        recall[0] = correct / n
        return FoldResult(name, n, correct / n, 0.5, cm, recall)

    meta = RunMeta("synthetic", True, 2, 10, 100, 30.0, {}, "r", "arm", "l", "mesh", 0.0, {}, 10, 0, 20)
    return CVResult("loso", "rf", [fold("p1"), fold("p2")]), meta


def equal(a, b) -> bool:
    """Deep equality of decoded values (dataclasses, containers, arrays with NaN)."""
    if type(a) is not type(b):
        return False
    if dataclasses.is_dataclass(a):
        return all(equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind in "fc")
    if isinstance(a, float) and np.isnan(a):
        return np.isnan(b)
    return a == b


@pytest.fixture(scope="module")
def tallies():
    t = {"cache": Tally("cache"), "model": Tally("model")}
    yield t
    for x in t.values():
        x.write()


# ------------------------------------------------------------------ cache entries
REF = _evaluation(30)
OTHER = _evaluation(60)


def _entry_bytes(value, key: bytes | None) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        cache = StageCache(Path(tmp), key=key)
        return (
            cache.path("evaluate", "k").parent.mkdir(parents=True) or cache.write("evaluate", "k", value).read_bytes()
        )


def _forge(blob: bytes, data) -> tuple[str, bytes]:
    """One node of the entry's JSON document edited, sealed again with a valid plain checksum (no key)."""
    payload = blob[len(MAGIC) + 64 :]
    with np.load(io.BytesIO(payload), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(arrays["__meta__"].tobytes().decode())
    what = mutate_json(meta, data)
    arrays["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return what, seal(buf.getvalue(), None)


def _cache_case(blob: bytes, key: bytes | None) -> tuple[str, object]:
    """Read ``blob`` as the evaluation entry through ``get_or_compute``: (verdict, value)."""
    with tempfile.TemporaryDirectory(prefix="sphri-fuzz-") as tmp:
        cache = StageCache(Path(tmp), key=key)
        path = cache.path("evaluate", "k")
        path.parent.mkdir(parents=True)
        path.write_bytes(blob)
        computed = []

        def compute():
            computed.append(1)
            return REF

        with WarningCatcher() as warned:
            value = cache.get_or_compute("evaluate", "k", compute, contract=CONTRACT)
        if computed:
            return (WARNED if warned.records else UNCHANGED), value
        return (UNCHANGED if equal(value, REF) else SILENT), value


@fuzz_settings(small=24, large=300)
@given(forged=st.booleans(), keyed=st.booleans(), data=st.data())
def test_corrupted_or_crafted_cache_entries(tallies, forged, keyed, data):
    key = KEY if keyed else None
    blob = _entry_bytes(REF, key)
    if forged:
        what, blob = _forge(blob, data)
        kind = "crafted entry, valid plain checksum" + (", key configured" if keyed else ", no key")
    else:
        what, blob = mutate_bytes(blob, data, header=_entry_bytes(OTHER, key))
        kind = what
    try:
        v, value = _cache_case(blob, key)
    except Exception:
        tallies["cache"].add(kind, "traceback")
        raise
    if v == SILENT and forged and not keyed:
        v = FORGED_NO_KEY  # sphri-without-a-key's documented limit: a valid plain checksum is trusted
    tallies["cache"].add(kind, v)
    assert v != SILENT, f"{kind} ({what}): the cache returned a different value"
    if keyed and forged:
        assert v == WARNED  # never read: recomputed, with a warning naming the file
    if v != FORGED_NO_KEY:
        assert equal(value, REF)


# ------------------------------------------------------------------ model files
@pytest.fixture(scope="module")
def model_files(tmp_path_factory):
    from tests.hardware.conftest import grid_geometry
    from tests.hardware.test_hw_live import small_rf

    root = tmp_path_factory.mktemp("fuzz-model")
    geo = grid_geometry(3, 2)
    plain = save_model(ModelBundle(small_rf(geo), geo, 20, 90.0), root / "plain.sphrimodel", key=None)
    other = save_model(ModelBundle(small_rf(geo, seed=1), geo, 20, 90.0), root / "other.sphrimodel", key=None)
    x = (np.random.default_rng(3).random((16, 20, geo.n_taxels)) < 0.15).astype(np.float32)
    ref = load_model(plain, key=None)
    return plain.read_bytes(), other.read_bytes(), x, ref.predict_proba(x), ref


def _split(blob: bytes) -> tuple[bytes, bytes]:
    (n,) = struct.unpack_from("<I", blob, len(MODEL_MAGIC))
    h0 = len(MODEL_MAGIC) + 4
    return blob[h0 : h0 + n], blob[h0 + n + 64 :]


@fuzz_settings(small=20, large=260)
@given(signed_edit=st.booleans(), data=st.data())
def test_corrupted_or_edited_model_files(model_files, tallies, signed_edit, data):
    blob, other, x, ref_proba, ref = model_files
    key = None
    if signed_edit:
        head, payload = _split(blob)
        header = json.loads(head)
        what = mutate_json(header, data)
        kind = "header edited, signed again with the key"
        key = KEY
        blob = seal_model(json.dumps(header, allow_nan=True).encode(), payload, key)
    else:
        kind, blob = mutate_bytes(blob, data, header=other[: len(MODEL_MAGIC) + 4 + 200])
        what = kind
    with tempfile.TemporaryDirectory(prefix="sphri-fuzz-") as tmp:
        path = Path(tmp) / "m.sphrimodel"
        path.write_bytes(blob)
        try:
            bundle = load_model(path, key=key)
            same = (
                bundle.labels == ref.labels
                and bundle.window_length == ref.window_length
                and bundle.frame_rate_hz == ref.frame_rate_hz
                and bundle.n_taxels == ref.n_taxels
                and np.array_equal(bundle.predict_proba(x), ref_proba)
            )
            v = UNCHANGED if same else ("signed edit accepted" if signed_edit else SILENT)
        except Exception as exc:  # noqa: BLE001 - judged: named, or re-raised as a traceback
            v = tallies["model"].named(kind, exc)
    tallies["model"].add(kind, v)
    assert v != SILENT, f"{what}: a corrupted model file loaded and predicts differently"
    assert v in (NAMED, UNCHANGED, "signed edit accepted")


@pytest.mark.parametrize("grid", [[0, 2], [2], [False, 2], [6, 6]])
def test_a_signed_header_whose_grid_does_not_hold_the_taxels_is_named(model_files, tmp_path, grid):
    """Found by this campaign: a header (signed with the key) with ``grid_shape=[0, 2]`` or ``[2]`` loaded,
    then the first prediction raised ValueError/IndexError from the feature code (a traceback in
    ``skin live``). ``load_model`` now checks the geometry: one ``model file error`` line."""
    from sphri.export.model_file import ModelFileError

    blob, _, x, _, _ = model_files
    head, payload = _split(blob)
    header = json.loads(head)
    header["grid_shape"] = grid
    path = tmp_path / "m.sphrimodel"
    path.write_bytes(seal_model(json.dumps(header).encode(), payload, KEY))
    # a grid that is not [H, W] of positive integers is refused by its field; [6, 6] holds the wrong taxel count
    with pytest.raises(ModelFileError, match=r"m\.sphrimodel: (header field grid_shape must be|malformed model file)"):
        load_model(path, key=KEY)


@pytest.mark.parametrize("edit", ["threshold_empty", "threshold_none", "meta_list"])
def test_a_signed_header_with_malformed_parameters_is_named_at_load(model_files, tmp_path, edit):
    """Found by this campaign: a header signed with the key whose ``estimator.params.active_threshold`` is
    ``""`` or ``null`` loaded, then every prediction raised (numpy's UFuncNoLoopError, TypeError); ``meta``
    as a list raised ValueError from ``load_model``. Now one ``model file error`` line when loading."""
    from sphri.export.model_file import ModelFileError

    blob, _, x, _, _ = model_files
    head, payload = _split(blob)
    header = json.loads(head)
    if edit == "meta_list":
        header["meta"] = [header.get("meta") or {"a": 1}]
    else:
        header["estimator"]["params"]["active_threshold"] = "" if edit == "threshold_empty" else None
    path = tmp_path / "m.sphrimodel"
    path.write_bytes(seal_model(json.dumps(header).encode(), payload, KEY))
    with pytest.raises(ModelFileError, match=r"m\.sphrimodel: (the model does not predict|header field meta)"):
        load_model(path, key=KEY)
