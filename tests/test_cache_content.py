"""The stage cache is keyed by the contents of the files a stage reads, and its
entries are arrays + JSON that decode into the stage's contract or are recomputed."""

from __future__ import annotations

import io
import json
import logging
import os
import pickle
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from sphri import pipeline
from sphri.cache import StageCache, seal
from sphri.config import compose
from sphri.types import Contacts, CVResult, FoldResult, GestureDataset, Layout, SurfaceMap

FAST = ["+debug=fast", "tracking.enabled=false"]
REPO = Path(__file__).resolve().parent.parent


def make(tmp_path: Path, *overrides: str) -> tuple[pipeline.Pipeline, object]:
    cfg = compose([*FAST, f"cache.dir={tmp_path / 'cache'}", *overrides])
    return pipeline.make_pipeline(cfg, StageCache(tmp_path / "cache")), cfg


def sources(p: pipeline.Pipeline, *stages: str) -> dict[str, str]:
    for s in stages:
        p.get(s)
    return {s: p.records[s].source for s in stages}


def write_arm(path: Path, scale: float = 1.0) -> None:
    cfg = compose(FAST)
    link = pipeline.build(cfg.robot).build().link_for("arm")
    trimesh.Trimesh(link.vertices * scale, link.faces, process=False).export(path)


# ---------------------------------------------------------------- content keys
def test_replaced_mesh_recomputes_robot_stages_and_log_names_it(tmp_path: Path, caplog):
    mesh = tmp_path / "arm.obj"
    write_arm(mesh)
    robot = [
        "robot=mesh",
        f"robot.links={{l_arm: {mesh}}}",
        "robot.regions={arm: l_arm}",
        "robot.units=m",
        "layout.res=3",
    ]
    first, cfg = make(tmp_path, *robot)
    assert set(sources(first, "contact", "surface").values()) == {"computed"}
    again, _ = make(tmp_path, *robot)
    assert sources(again, "contact", "surface") == {"contact": "cache", "surface": "cache"}, "unchanged file: cached"
    hash_before = pipeline.config_hash(cfg)

    write_arm(mesh, scale=1.1)  # another mesh at the same path
    caplog.set_level(logging.INFO, logger="sphri")
    changed, cfg2 = make(tmp_path, *robot)
    assert sources(changed, "data", "contact", "surface", "layout") == {
        "data": "computed",
        "contact": "computed",
        "surface": "computed",
        "layout": "computed",
    }
    assert re.search(r"stage contact: input file\(s\) changed since the cached entry: .*arm\.obj", caplog.text)
    assert pipeline.config_hash(cfg2) != hash_before, "sweep resume must not skip a job whose mesh changed"
    surf = changed.get("surface")
    assert surf.params["radius"] > again.get("surface").params["radius"] * 1.05


def test_replaced_parquet_recomputes_data_and_log_names_it(tmp_path: Path, caplog):
    from sphri.data.synthesize import synthesize

    ds = tmp_path / "ds"
    small = ["+debug=fast", "data.participants=2", "data.repetitions=1"]
    synthesize(ds, small)
    data = ["data=vr_gesture", f"data.root={ds}", "data.participants=2"]
    first, cfg = make(tmp_path, *data)
    assert sources(first, "data") == {"data": "computed"}
    again, _ = make(tmp_path, *data)
    assert sources(again, "data") == {"data": "cache"}
    n_before = again.get("data").n_frames
    hash_before = pipeline.config_hash(cfg)

    parquet = sorted(ds.glob("arm/participant_02/*.parquet"))
    assert parquet, "the synthesized dataset has a parquet file per participant"
    before = {p: p.read_bytes() for p in ds.rglob("*") if p.is_file()}
    synthesize(ds, [*small, "data.seed=5"], overwrite=True)  # other trials written over the same paths
    assert parquet[0].read_bytes() != before[parquet[0]]
    caplog.set_level(logging.INFO, logger="sphri")
    changed, cfg2 = make(tmp_path, *data)
    assert sources(changed, "data") == {"data": "computed"}
    assert "participant_02" in caplog.text and "changed since the cached entry" in caplog.text
    assert changed.get("data").n_frames != n_before
    assert pipeline.config_hash(cfg2) != hash_before


def test_fingerprints_are_memoized_and_follow_content(tmp_path: Path):
    from sphri.inputs import FingerprintMemo

    f = tmp_path / "x.bin"
    f.write_bytes(b"a" * 1000)
    memo = FingerprintMemo(tmp_path / "memo.json")
    d1 = memo.digest(f)
    memo.save()
    again = FingerprintMemo(tmp_path / "memo.json")
    assert again.digest(f) == d1 and again.hashed == [], "unchanged size/mtime: no rehash"
    f.write_bytes(b"b" * 1000)  # same size, new content
    assert again.digest(f) != d1
    assert again.digest(tmp_path / "nope") == "missing"


def test_file_fields_are_declared_by_the_schemas(tmp_path: Path):
    """Every config field naming a file is found through its schema (no hand list in the pipeline)."""
    from sphri.inputs import declared_files

    cfg = compose(
        [
            "layout=density",
            f"layout.density_path={tmp_path / 'd.npz'}",
            "encoder=coverage",
            "robot=mesh",
            "robot.links={l_arm: a.obj}",
            "robot.regions={arm: l_arm}",
            f"robot.root={tmp_path}",
            f"hand.definition_path={tmp_path / 'hand.json'}",
        ]
    )
    assert [p for _, p in declared_files(cfg.layout)] == [tmp_path / "d.npz"]
    assert [p for _, p in declared_files(cfg.robot)] == [tmp_path / "a.obj"]
    assert [p for _, p in declared_files(cfg.hand)] == [tmp_path / "hand.json"]
    urdf = compose(["robot=urdf", f"robot.path={tmp_path / 'r.urdf'}", "robot.links=[arm]", "robot.regions={arm: arm}"])
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "arm.stl").write_bytes(b"solid")
    (tmp_path / "r.urdf").write_text(
        '<robot name="r"><link name="arm"><collision><geometry>'
        '<mesh filename="package://r/meshes/arm.stl"/></geometry></collision></link></robot>'
    )
    assert [p for _, p in declared_files(urdf.robot)] == [tmp_path / "r.urdf", tmp_path / "meshes" / "arm.stl"]


# ------------------------------------------------------------ no pickle, contracts
def plant(cache: StageCache, stage: str, key: str, payload: bytes) -> Path:
    """An entry with a valid header and checksum around ``payload``."""
    path = cache.path(stage, key)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(seal(payload))
    return path


class _Payload:
    def __init__(self, marker: str):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _npz(arrays: dict) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # savez pickles object arrays
    return buf.getvalue()


@pytest.mark.parametrize("kind", ["pickle", "npz_object_array", "foreign_class"])
def test_crafted_entry_executes_nothing_and_is_recomputed(tmp_path: Path, kind: str, caplog):
    marker = tmp_path / "PWNED"
    p, _ = make(tmp_path, "layout.res=3")
    key = p.key("data")
    if kind == "pickle":
        payload = pickle.dumps(_Payload(str(marker)))
    elif kind == "npz_object_array":
        meta = {"stage": "data", "key": key, "files": {}, "value": {"__nd__": "a0"}}
        payload = _npz(
            {
                "a0": np.array([_Payload(str(marker))], dtype=object),
                "__meta__": np.frombuffer(json.dumps(meta).encode(), np.uint8),
            }
        )
    else:  # a class outside sphri named in the JSON
        meta = {
            "stage": "data",
            "key": key,
            "files": {},
            "value": {"__dc__": "os:system", "f": {"command": f"touch {marker}"}},
        }
        payload = _npz({"__meta__": np.frombuffer(json.dumps(meta).encode(), np.uint8)})
    plant(p.cache, "data", key, payload)
    dataset = p.get("data")
    assert not marker.exists(), "reading a cache entry must never execute code"
    assert isinstance(dataset, GestureDataset)
    assert p.records["data"].source == "computed"
    assert "discarding corrupt entry for stage data" in caplog.text


def test_entry_of_the_wrong_contract_is_recomputed_not_a_crash(tmp_path: Path, caplog):
    """A valid entry holding another stage's object (here contacts where data is expected)."""
    p, _ = make(tmp_path, "layout.res=3")
    contacts = p.get("contact")
    other, _ = make(tmp_path, "layout.res=3", "data.seed=9")
    key = other.key("data")
    other.cache.write("data", key, contacts)
    dataset = other.get("data")
    assert isinstance(dataset, GestureDataset) and other.records["data"].source == "computed"
    assert "expected GestureDataset, got Contacts" in caplog.text


def test_contracts_round_trip_through_arrays_and_json(tmp_path: Path):
    from sphri.codec import decode, encode

    p, _ = make(tmp_path, "layout.res=3")
    values = {s: p.get(s) for s in ("data", "contact", "surface", "layout", "plan")}
    values["evaluate"] = p.get("evaluate")
    for stage, value in values.items():
        tree, arrays = encode(value)
        json.dumps(tree)  # the structure is plain JSON
        back = decode(json.loads(json.dumps(tree)), arrays)
        assert type(back) is type(value), stage
    ds, back = values["data"], decode(*encode(values["data"]))
    assert back.trials.equals(ds.trials) and back.trials["participant"].dtype == object
    np.testing.assert_array_equal(back.poses, ds.poses)
    assert back.hand.names == ds.hand.names and isinstance(back.hand.names, tuple)
    lay = decode(*encode(values["layout"]))
    assert isinstance(lay, Layout) and lay.grid_shape == values["layout"].grid_shape
    cv, meta = decode(*encode(values["evaluate"]))
    assert isinstance(cv, CVResult) and isinstance(cv.folds[0], FoldResult) and meta == values["evaluate"][1]


def test_decoder_refuses_other_fields(tmp_path: Path):
    from sphri.codec import DecodeError, decode, encode

    tree, arrays = encode(SurfaceMap("mesh", False, 0.0, 0.0, False, 0.0, {}))
    tree["f"]["extra"] = 1
    with pytest.raises(DecodeError, match="fields differ"):
        decode(tree, arrays)
    tree, arrays = encode(Contacts(0, *[np.zeros(0)] * 11))
    tree["f"]["frame"] = "not an array"
    with pytest.raises(DecodeError, match="Contacts.frame"):
        decode(tree, arrays)


def test_no_pickle_loads_in_the_pipeline_code():
    """The stage cache and everything it reads decode without pickle (model files: sphri/models, sphri/hardware)."""
    offenders = []
    for path in (REPO / "sphri").rglob("*.py"):
        rel = path.relative_to(REPO / "sphri").parts
        if rel[0] in ("hardware", "models"):
            continue
        text = path.read_text()
        if re.search(r"pickle\.loads?\(|allow_pickle=True|torch\.load\(|joblib\.load\(", text):
            offenders.append(str(path))
    assert offenders == []
