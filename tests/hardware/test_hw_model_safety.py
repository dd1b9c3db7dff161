"""Model files hold no pickle (issue 16, item 3): crafted files run nothing, saved models predict the same."""

from __future__ import annotations

import json
import os
import pickle
import struct

import numpy as np
import pytest

from sphri.export.model_file import (
    MAGIC,
    OLD_MAGIC,
    ModelBundle,
    ModelFileError,
    inspect_model,
    load_model,
    resolve_model_path,
    save_model,
    seal_model,
)


class _Payload:
    """Unpickling this calls os.system, which creates the marker file."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _windows(geo, n=6, length=20, seed=3):
    return (np.random.default_rng(seed).random((n, length, geo.n_taxels)) < 0.15).astype(np.float32)


def test_old_pickle_model_file_runs_nothing(tmp_path, make_geometry):
    marker = tmp_path / "pwned"
    payload = pickle.dumps({"estimator": _Payload(marker), "geometry": None})
    head = json.dumps(
        {"format": "sphri-model/1", "n_taxels": 6, "labels": [], "window_length": 10, "frame_rate_hz": 30}
    ).encode()
    import hashlib

    blob = OLD_MAGIC + struct.pack("<I", len(head)) + head + hashlib.blake2b(payload, digest_size=32).digest() + payload
    crafted = tmp_path / "crafted.sphrimodel"
    crafted.write_bytes(blob)
    with pytest.raises(ModelFileError, match=r"crafted\.sphrimodel.*pickle"):
        load_model(crafted)
    assert not marker.exists()
    # a bare pickle renamed to .sphrimodel, and one behind the new magic with a valid checksum
    bare = tmp_path / "bare.sphrimodel"
    bare.write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(ModelFileError, match="bare.sphrimodel"):
        load_model(bare)
    head2 = json.dumps(
        {
            "format": "sphri-model/2",
            "n_taxels": 6,
            "labels": [],
            "window_length": 10,
            "frame_rate_hz": 30,
            "grid_shape": None,
            "geometry": {"wrap_v": False, "metres_per_u": 0, "metres_per_v": 0, "has_uv": False},
            "estimator": {"kind": "rf", "params": {}},
        }
    ).encode()
    new = tmp_path / "new.sphrimodel"
    new.write_bytes(
        MAGIC + struct.pack("<I", len(head2)) + head2 + hashlib.blake2b(payload, digest_size=32).digest() + payload
    )
    with pytest.raises(ModelFileError, match="new.sphrimodel"):
        load_model(new)
    assert not marker.exists()


def test_untrusted_type_in_the_forest_payload_is_refused(tmp_path, make_geometry):
    """A skops payload holding a type outside the trusted list is refused before loading."""
    import skops.io as sio
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import FunctionTransformer

    from tests.hardware.test_hw_live import small_rf

    geo = make_geometry(3, 2)
    model = small_rf(geo)
    path = save_model(ModelBundle(model, geo, 20, 90.0), tmp_path / "rf.sphrimodel")
    # swap the forest for an estimator calling an arbitrary function, then re-checksum
    import io

    blob = path.read_bytes()
    (n,) = struct.unpack_from("<I", blob, len(MAGIC))
    h0 = len(MAGIC) + 4
    header = blob[h0 : h0 + n]
    with np.load(io.BytesIO(blob[h0 + n + 64 :]), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    evil = Pipeline([("f", FunctionTransformer(os.system))])
    arrays["forest_skops"] = np.frombuffer(sio.dumps(evil), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(seal_model(header, buf.getvalue()))
    with pytest.raises(ModelFileError, match=r"rf\.sphrimodel.*untrusted types"):
        load_model(path)


def test_rf_round_trip_predicts_identically(tmp_path, make_geometry):
    from tests.hardware.test_hw_live import small_rf

    geo = make_geometry(18, 6)
    model = small_rf(geo)
    back = load_model(save_model(ModelBundle(model, geo, 20, 90.0), tmp_path / "rf.sphrimodel"))
    x = _windows(geo)
    np.testing.assert_array_equal(back.predict_proba(x), model.predict_proba(x))
    np.testing.assert_array_equal(back.estimator.predict(x), model.predict(x))
    np.testing.assert_array_equal(back.geometry.position_m, geo.position_m)
    np.testing.assert_array_equal(back.geometry.uv, geo.uv)
    assert back.geometry.grid_shape == geo.grid_shape and back.geometry.wrap_v == geo.wrap_v


@pytest.mark.parametrize("grid", [True, False])
def test_cnn_gru_round_trip_predicts_identically(tmp_path, make_geometry, grid):
    from dataclasses import replace

    from sphri.models.cnn_gru import CnnGru

    geo = make_geometry(4, 3)
    if not grid:
        geo = replace(geo, grid_shape=None, uv=None)
    rng = np.random.default_rng(0)
    x = (rng.random((24, 10, geo.n_taxels)) < 0.2).astype(np.float32)
    y = np.arange(24) % 3
    model = CnnGru(
        max_epochs=2,
        batch_size=8,
        hidden=8,
        channels=(4, 4),
        strides=(1, 1),
        threads=1,
        precision="float32",
        geometry=geo,
    ).fit(x, y)
    path = save_model(ModelBundle(model, geo, 10, 30.0), tmp_path / "cnn.sphrimodel")
    back = load_model(path)
    np.testing.assert_array_equal(back.estimator.predict_proba(x), model.predict_proba(x))
    np.testing.assert_array_equal(back.estimator.classes_, model.classes_)


def test_unsupported_estimator_is_refused_at_save(tmp_path, make_geometry):
    class Other:
        classes_ = np.arange(2)

        def predict_proba(self, x):
            return np.zeros((len(x), 2))

    with pytest.raises(ModelFileError, match="Other cannot be saved in a model file: it lacks NAME, save_state"):
        save_model(ModelBundle(Other(), make_geometry(2, 2), 5, 30.0), tmp_path / "o.sphrimodel")


def _with_estimator_header(path, edit) -> None:
    """Rewrite a model file's ``estimator`` header part and seal it again (a valid plain checksum, as anyone
    without the model key can compute)."""
    blob = path.read_bytes()
    (n,) = struct.unpack_from("<I", blob, len(MAGIC))
    h0 = len(MAGIC) + 4
    header = json.loads(blob[h0 : h0 + n])
    edit(header["estimator"])
    path.write_bytes(seal_model(json.dumps(header).encode(), blob[h0 + n + 64 :], key=None))


def test_a_header_naming_a_module_outside_the_plugins_imports_nothing(tmp_path, make_geometry, monkeypatch):
    """The registry imports a model class only from a package the reader lists: a crafted header naming a
    module whose import would run code is refused before the import (the marker file stays absent)."""
    from tests.hardware.test_hw_live import small_rf

    monkeypatch.delenv("SPHRI_MODEL_KEY", raising=False)
    monkeypatch.delenv("SPHRI_MODEL_KEY_FILE", raising=False)
    marker = tmp_path / "pwned"
    (tmp_path / "evilpkg").mkdir()
    (tmp_path / "evilpkg" / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\nclass M:\n    NAME = 'm'\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    geo = make_geometry(3, 2)
    path = save_model(ModelBundle(small_rf(geo), geo, 20, 90.0), tmp_path / "rf.sphrimodel", key=None)

    def name_evil(est):
        est["kind"], est["class"] = "m", "evilpkg:M"

    _with_estimator_header(path, name_evil)
    with pytest.raises(ModelFileError, match=r"rf\.sphrimodel: .*'evilpkg', which is not listed in plugins"):
        load_model(path)
    with pytest.raises(ModelFileError, match="not listed in plugins"):
        load_model(path, plugins=["sphri", "labext"])
    assert not marker.exists()
    # listed: imported, then refused because it is no exportable model named as the header says
    with pytest.raises(ModelFileError, match=r"evilpkg:M is not an exportable model named 'm'"):
        load_model(path, plugins=["evilpkg"])

    def unknown(est):
        est["kind"] = "nosuch"
        est.pop("class", None)

    _with_estimator_header(path, unknown)
    with pytest.raises(
        ModelFileError, match=r"rf\.sphrimodel: unknown estimator kind 'nosuch' \(this sphri reads rf, cnn_gru"
    ):
        load_model(path)


def test_sphri_models_are_found_by_name_whatever_class_the_header_names(tmp_path, make_geometry, monkeypatch):
    from tests.hardware.test_hw_live import small_rf

    monkeypatch.delenv("SPHRI_MODEL_KEY", raising=False)
    monkeypatch.delenv("SPHRI_MODEL_KEY_FILE", raising=False)
    geo = make_geometry(3, 2)
    model = small_rf(geo)
    path = save_model(ModelBundle(model, geo, 20, 90.0), tmp_path / "rf.sphrimodel", key=None)
    assert "class" not in inspect_model(path)["estimator"]  # sphri's own: the name is enough
    _with_estimator_header(path, lambda est: est.update({"class": "os:system"}))
    x = _windows(geo)
    np.testing.assert_array_equal(load_model(path).predict_proba(x), model.predict_proba(x))


def test_a_registered_model_class_loads_without_plugins(tmp_path, make_geometry):
    """A class registered in this process (sphri.export.registry.register) is trusted by its name; a class
    may not take the name of one of sphri's own models."""
    from sphri.export import registry

    class Mean:
        NAME = "test_mean_model"

        def __init__(self, geometry=None):
            self.geometry = geometry

        def fit(self, x, y):
            self.classes_ = np.unique(y)
            self.w_ = np.stack([np.asarray(x)[y == c].mean(axis=(0, 1)) for c in self.classes_])
            return self

        def predict_proba(self, x):
            s = np.asarray(x, dtype=np.float64).mean(axis=1) @ self.w_.T + 1e-9
            return s / s.sum(axis=1, keepdims=True)

        def save_state(self):
            return {}, {"classes": self.classes_, "w": self.w_}

        @classmethod
        def load_state(cls, head, arrays, geometry):
            m = cls(geometry)
            m.classes_, m.w_ = arrays["classes"], arrays["w"]
            return m

    geo = make_geometry(3, 2)
    x = _windows(geo, n=16)
    model = Mean(geo).fit(x, np.arange(16) % 4)
    path = save_model(ModelBundle(model, geo, 20, 90.0), tmp_path / "mean.sphrimodel", key=None)
    with pytest.raises(ModelFileError, match="not listed in plugins"):  # a local class, not registered yet
        load_model(path, key=None)
    registry.register(Mean)
    try:
        back = load_model(path, key=None)
        np.testing.assert_array_equal(back.estimator.predict_proba(x), model.predict_proba(x))
    finally:
        registry._REGISTERED.pop("test_mean_model", None)
    Mean.NAME = "rf"
    with pytest.raises(registry.NotExportable, match="model name 'rf' of .* is sphri's own"):
        registry.register(Mean)
    del Mean.load_state
    with pytest.raises(registry.NotExportable, match="lacks load_state"):
        registry.register(Mean)


@pytest.mark.parametrize(
    "spec", ["runs:/abc/model/rf.sphrimodel", "http://example.invalid/rf.sphrimodel", "models:/skin/1"]
)
def test_remote_models_need_an_explicit_opt_in(spec):
    with pytest.raises(ModelFileError, match="allow_remote=true"):
        resolve_model_path(spec)


@pytest.mark.parametrize("grid", [[18], [6, 3, 1], ["6", 3], [6.0, 3], [0, 3], [True, 18], {"h": 6}])
def test_malformed_grid_shape_in_the_header_is_refused(tmp_path, make_geometry, grid):
    """The header's grid_shape must be null or [H, W] of positive integers: anything else is refused with the
    file and field named (a resealed file, so the checksum does not catch it)."""
    from tests.hardware.test_hw_live import small_rf

    geo = make_geometry(6, 3)
    path = save_model(ModelBundle(small_rf(geo), geo, 20, 90.0), tmp_path / "rf.sphrimodel")
    blob = path.read_bytes()
    (n,) = struct.unpack_from("<I", blob, len(MAGIC))
    h0 = len(MAGIC) + 4
    header = json.loads(blob[h0 : h0 + n])
    assert header["grid_shape"] == [6, 3]
    header["grid_shape"] = grid
    path.write_bytes(seal_model(json.dumps(header).encode(), blob[h0 + n + 64 :]))
    with pytest.raises(ModelFileError, match=r"rf\.sphrimodel: header field grid_shape must be null or \[H, W\]"):
        load_model(path)
