"""Model files authenticated, not only checksummed (issue 29, item 2).

Reproducers of the issue: the checksum covered the payload, not the JSON header, so reversed ``labels``
renamed every prediction and ``window_length=20`` was accepted; a skops payload of a type skops trusts
by default but sphri's list does not (LogisticRegression) loaded; model files were written 0600.
"""

from __future__ import annotations

import io
import json
import os
import stat
import struct

import numpy as np
import pytest

from sphri.export.model_file import MAGIC, ModelBundle, ModelFileError, load_model, save_model, seal_model
from sphri.hardware.skin import main as skin_main
from sphri.types import GESTURES
from tests.hardware.test_hw_live import small_rf


def _parts(blob: bytes) -> tuple[dict, bytes]:
    """(header, everything after it) of a model file, whatever its digest layout."""
    (n,) = struct.unpack_from("<I", blob, len(MAGIC))
    h0 = len(MAGIC) + 4
    return json.loads(blob[h0 : h0 + n]), blob[h0 + n :]


def _edit_header(path, edit) -> None:
    """Rewrite the JSON header in place, keeping the digests and payload bytes as they were."""
    blob = path.read_bytes()
    header, rest = _parts(blob)
    edit(header)
    head = json.dumps(header).encode()
    path.write_bytes(blob[: len(MAGIC)] + struct.pack("<I", len(head)) + head + rest)


@pytest.fixture
def rf_file(tmp_path, make_geometry, monkeypatch):
    monkeypatch.delenv("SPHRI_MODEL_KEY", raising=False)
    monkeypatch.delenv("SPHRI_MODEL_KEY_FILE", raising=False)
    geo = make_geometry(3, 2)
    model = small_rf(geo)
    return save_model(ModelBundle(model, geo, 20, 90.0), tmp_path / "rf.sphrimodel"), model, geo


@pytest.mark.parametrize("edit", ["reversed_labels", "window_length"])
def test_an_edited_header_is_a_checksum_mismatch(rf_file, edit):
    path, model, geo = rf_file
    assert load_model(path).labels == GESTURES

    def change(h):
        if edit == "reversed_labels":
            h["labels"] = h["labels"][::-1]
        else:
            h["window_length"] = 30

    _edit_header(path, change)
    with pytest.raises(ModelFileError, match=r"rf\.sphrimodel: checksum mismatch over its header"):
        load_model(path)


def _payload_with_forest(path, forest) -> tuple[bytes, bytes]:
    import skops.io as sio

    blob = path.read_bytes()
    (n,) = struct.unpack_from("<I", blob, len(MAGIC))
    h0 = len(MAGIC) + 4
    with np.load(io.BytesIO(blob[h0 + n + 64 :]), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["forest_skops"] = np.frombuffer(sio.dumps(forest), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return blob[h0 : h0 + n], buf.getvalue()


def test_a_type_skops_trusts_but_sphri_does_not_is_refused_in_one_line(rf_file, capsys):
    from sklearn.linear_model import LogisticRegression

    path, model, geo = rf_file
    x = np.random.default_rng(0).random((40, 32))
    other = LogisticRegression(max_iter=50).fit(x, np.arange(40) % 8)
    head, payload = _payload_with_forest(path, other)
    path.write_bytes(seal_model(head, payload))
    with pytest.raises(ModelFileError, match=r"rf\.sphrimodel.*untrusted types.*LogisticRegression"):
        load_model(path)
    assert skin_main(["live", "port=socket://127.0.0.1:9", f"model={path}"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "LogisticRegression" in err[0]


def test_a_keyed_model_file_refuses_files_without_the_key(rf_file, monkeypatch):
    path, model, geo = rf_file
    monkeypatch.setenv("SPHRI_MODEL_KEY", "lab key")
    with pytest.raises(
        ModelFileError, match=r"rf\.sphrimodel: not signed with the configured model key.*without the key"
    ):
        load_model(path)  # saved before the key was set
    signed = save_model(ModelBundle(model, geo, 20, 90.0), path.with_name("signed.sphrimodel"))
    x = (np.random.default_rng(1).random((4, 20, geo.n_taxels)) < 0.2).astype(np.float32)
    np.testing.assert_array_equal(load_model(signed).predict_proba(x), model.predict_proba(x))
    # someone without the key rewrites the header and recomputes the plain digest: refused
    blob = signed.read_bytes()
    header, rest = _parts(blob)
    header["labels"] = header["labels"][::-1]
    head = json.dumps(header).encode()
    forged = signed.with_name("forged.sphrimodel")
    forged.write_bytes(seal_model(head, rest[64:], key=None))
    with pytest.raises(ModelFileError, match="not signed with the configured model key"):
        load_model(forged)
    forged.write_bytes(seal_model(head, rest[64:], key=b"another key"))
    with pytest.raises(ModelFileError, match="does not match the key"):
        load_model(forged)
    monkeypatch.delenv("SPHRI_MODEL_KEY")
    assert load_model(path).labels == GESTURES  # without a key, a file saved without one loads


def test_a_signed_model_file_without_a_key_configured_is_refused_unless_allowed(rf_file, monkeypatch):
    """A file signed with a key, read where no key is set: its signature cannot be checked, so it is
    refused, naming the setting that loads it anyway (a forged header signed with another key likewise)."""
    path, model, geo = rf_file
    signed = save_model(ModelBundle(model, geo, 20, 90.0), path.with_name("signed.sphrimodel"), key=b"lab key")
    header, rest = _parts(signed.read_bytes())
    header["labels"] = header["labels"][::-1]
    forged = signed.with_name("forged.sphrimodel")
    forged.write_bytes(seal_model(json.dumps(header).encode(), rest[64:], key=b"another key"))
    monkeypatch.delenv("SPHRI_MODEL_KEY", raising=False)
    monkeypatch.delenv("SPHRI_MODEL_KEY_FILE", raising=False)
    for p in (signed, forged):
        with pytest.raises(ModelFileError, match=rf"{p.name}: signed with a model key, but no key .*allow_unverified"):
            load_model(p)
    assert load_model(signed, allow_unverified=True).labels == GESTURES
    assert load_model(forged, allow_unverified=True).labels == GESTURES[::-1]  # unchecked, as asked


def test_a_previous_format_file_is_refused_with_the_command_to_export_it_again(rf_file):
    path, _, _ = rf_file
    blob = path.read_bytes()
    path.write_bytes(b"SPHRIMODEL2\n" + blob[len(MAGIC) :])
    with pytest.raises(
        ModelFileError, match=r"rf\.sphrimodel: a sphri-model/2 file.*export it again with sphri export"
    ):
        load_model(path)


@pytest.mark.parametrize(
    "case", ["labels_not_a_list", "duplicate_labels", "window_length_text", "too_few_labels", "deep_header"]
)
def test_malformed_headers_are_one_named_error(rf_file, case):
    path, _, _ = rf_file
    blob = path.read_bytes()
    header, rest = _parts(blob)
    if case == "labels_not_a_list":
        header["labels"] = "hit"
    elif case == "duplicate_labels":
        header["labels"] = ["hit"] * 8
    elif case == "window_length_text":
        header["window_length"] = "20"
    elif case == "too_few_labels":
        header["labels"] = ["hit", "tap"]
    head = ("[" * 100_000 + "]" * 100_000).encode() if case == "deep_header" else json.dumps(header).encode()
    path.write_bytes(seal_model(head, rest[64:]))
    field = {
        "labels_not_a_list": "labels",
        "duplicate_labels": "labels",
        "window_length_text": "window_length",
        "too_few_labels": "labels",
        "deep_header": "header",
    }[case]
    with pytest.raises(ModelFileError, match=rf"rf\.sphrimodel.*{field}"):
        load_model(path)


@pytest.mark.parametrize("umask", [0o022, 0o002])
def test_model_files_follow_the_umask(tmp_path, make_geometry, umask):
    geo = make_geometry(3, 2)
    old = os.umask(umask)
    try:
        path = save_model(ModelBundle(small_rf(geo), geo, 20, 90.0), tmp_path / "rf.sphrimodel", key=None)
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask
