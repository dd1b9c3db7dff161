"""Hand model: capsule specs, Unity conventions, kinematics, definition files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf
from scipy.spatial.transform import Rotation

import sphri.hand.schema  # noqa: F401  (registers the schema)
from sphri.config import CONF_DIR, ConfigError
from sphri.hand.capsules import HandCapsules, HandDefinitionError, finger_of, load_definition
from sphri.hand.kinematics import (
    capsule_segments,
    invalid_quaternions,
    quat_to_matrix,
    repair_quaternions,
    rotate_vectors,
    validate_quaternions,
)

EXPECTED_NAMES = (
    "wrist1 wrist2 wrist3 wrist4 thumb1 thumb2 thumb3 index1 index2 index3 "
    "middle1 middle2 middle3 ring1 ring2 ring3 pinky1 pinky2 pinky3"
).split()


@pytest.fixture(scope="module")
def hand():
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="hand/quest_capsules")
    OmegaConf.to_object(cfg.hand)  # runs the schema's range checks
    return instantiate(cfg.hand).build()


def _spec(name="index1", finger="index", radius_m=0.01, height_m=0.06, axis=0, off=(0.02, 0.0, 0.0)):
    return dict(name=name, finger=finger, radius_m=radius_m, height_m=height_m, axis=axis, center_offset_m=list(off))


def test_quest_hand_names_fingers_and_types(hand):
    assert hand.names == tuple(EXPECTED_NAMES)
    assert hand.n_capsules == 19
    for name, finger in zip(hand.names, hand.fingers):
        expected = "palm" if name.startswith("wrist") else name.rstrip("0123456789")
        assert finger == expected
    assert hand.radius_m.dtype == np.float64 and hand.center_offset_m.shape == (19, 3)
    assert hand.axis.dtype == np.int64


def test_yaml_matches_shared_definition(hand, shared_dir):
    """The shipped YAML holds the study's sizes exactly."""
    path = shared_dir / "vr-gesture-dataset" / "assets" / "hand_capsule_definition.json"
    from_file = HandCapsules(definition_path=str(path)).build()
    assert from_file.names == hand.names and from_file.fingers == hand.fingers
    for f in ("radius_m", "height_m", "axis", "center_offset_m"):
        np.testing.assert_array_equal(getattr(from_file, f), getattr(hand, f))


def test_segment_length_unity_convention(hand):
    """height is tip to tip: the core segment is height - 2 r (clamped at 0)."""
    f = 3
    poses = np.zeros((f, 19, 7), np.float32)
    poses[..., 6] = 1.0
    p0, p1 = capsule_segments(poses, hand)
    assert p0.shape == (f, 19, 3) and p0.dtype == np.float64
    length = np.linalg.norm(p1 - p0, axis=-1)
    np.testing.assert_allclose(length, np.broadcast_to(hand.height_m - 2 * hand.radius_m, (f, 19)), atol=1e-12)
    # wrist1: height 8.732 cm, radius 1.823 cm -> segment 5.086 cm
    assert length[0, 0] == pytest.approx(0.08732089 - 2 * 0.01822828, abs=1e-9)
    # tip to tip along the axis equals height_m
    tip = length + 2 * hand.radius_m
    np.testing.assert_allclose(tip[0], hand.height_m, atol=1e-12)


def test_sphere_capsule_has_zero_segment():
    h = HandCapsules(capsules=[_spec(radius_m=0.02, height_m=0.03)]).build()
    assert h.segment_length_m[0] == 0.0
    p0, p1 = capsule_segments(np.array([[[0.1, 0.2, 0.3, 0, 0, 0, 1]]]), h)
    np.testing.assert_allclose(p0, p1)
    np.testing.assert_allclose(p0[0, 0], [0.12, 0.2, 0.3])


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_axis_names_local_axis(axis):
    h = HandCapsules(capsules=[_spec(axis=axis, off=(0, 0, 0), radius_m=0.01, height_m=0.06)]).build()
    p0, p1 = capsule_segments(np.array([[[0, 0, 0, 0, 0, 0, 1.0]]]), h)
    d = (p1 - p0)[0, 0]
    expected = np.zeros(3)
    expected[axis] = 0.04
    np.testing.assert_allclose(d, expected, atol=1e-15)


def test_rotated_joint():
    """A joint yawed 90 deg about z: local X (axis 0) maps to world +Y; offset follows."""
    h = HandCapsules(capsules=[_spec(off=(0.02, 0.0, 0.0), radius_m=0.01, height_m=0.06)]).build()
    q = Rotation.from_euler("z", 90, degrees=True).as_quat()  # xyzw
    pose = np.concatenate([[1.0, 2.0, 3.0], q])[None, None, :]
    p0, p1 = capsule_segments(pose, h)
    np.testing.assert_allclose((p0 + p1)[0, 0] / 2, [1.0, 2.02, 3.0], atol=1e-12)
    np.testing.assert_allclose(p0[0, 0], [1.0, 2.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(p1[0, 0], [1.0, 2.04, 3.0], atol=1e-12)


def test_unnormalized_quaternion_is_normalized():
    h = HandCapsules(capsules=[_spec()]).build()
    q = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_quat()
    a = capsule_segments(np.concatenate([[0, 0, 0], q])[None, None], h)
    b = capsule_segments(np.concatenate([[0, 0, 0], 3.7 * q])[None, None], h)
    np.testing.assert_allclose(a[0], b[0], atol=1e-15)
    np.testing.assert_allclose(a[1], b[1], atol=1e-15)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_segments_match_scipy(seed):
    """Vectorized segments equal a per-capsule reference built with scipy."""
    rng = np.random.default_rng(seed)
    c = 4
    specs = [
        _spec(
            name=f"c{i}",
            axis=int(rng.integers(3)),
            off=rng.normal(0, 0.02, 3),
            radius_m=0.01,
            height_m=float(rng.uniform(0.0, 0.08)),
        )
        for i in range(c)
    ]
    h = HandCapsules(capsules=specs).build()
    poses = np.concatenate([rng.normal(0, 0.3, (5, c, 3)), rng.normal(size=(5, c, 4))], axis=-1)
    p0, p1 = capsule_segments(poses, h)
    for f in range(5):
        for k in range(c):
            r = Rotation.from_quat(poses[f, k, 3:]).as_matrix()
            centre = poses[f, k, :3] + r @ h.center_offset_m[k]
            half = r[:, h.axis[k]] * h.segment_length_m[k] / 2
            np.testing.assert_allclose(p0[f, k], centre - half, atol=1e-12)
            np.testing.assert_allclose(p1[f, k], centre + half, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_quat_to_matrix_matches_scipy(seed):
    q = np.random.default_rng(seed).normal(size=(7, 4)) * 5
    np.testing.assert_allclose(quat_to_matrix(q), Rotation.from_quat(q).as_matrix(), atol=1e-12)
    v = np.random.default_rng(seed + 1).normal(size=(7, 3))
    np.testing.assert_allclose(rotate_vectors(q, v), np.einsum("nij,nj->ni", quat_to_matrix(q), v), atol=1e-12)


def test_invalid_quaternions_raise_with_indices(hand):
    poses = np.zeros((4, 19, 7), np.float32)
    poses[..., 6] = 1
    poses[2, 5, 3:] = np.nan
    poses[3, 0, 3:] = 0.0
    with pytest.raises(ValueError, match=r"2 of 76 .*\(2, 5\), \(3, 0\)"):
        capsule_segments(poses, hand)
    with pytest.raises(ValueError, match="NaN"):
        quat_to_matrix(np.array([0.0, 0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        validate_quaternions(np.zeros((3, 3)))
    assert invalid_quaternions(np.array([[0, 0, 0, 1.0], [np.inf, 0, 0, 1]])).tolist() == [False, True]


def test_wrong_pose_shape(hand):
    with pytest.raises(ValueError, match=r"\(F, 19, 7\)"):
        capsule_segments(np.zeros((2, 18, 7)), hand)


def test_repair_quaternions_holds_last_valid_within_segment():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(6, 2, 4))
    q[1, 0] = np.nan  # held from frame 0
    q[3, 0] = 0.0  # first frame of trial 2: takes frame 4 (next valid in its trial)
    q[3:, 1] = np.nan  # capsule 1 invalid for the whole second trial: identity
    fixed, bad = repair_quaternions(q, starts=np.array([0, 3]))
    with np.errstate(invalid="ignore"):
        unit = q / np.linalg.norm(q, axis=-1, keepdims=True)
    assert bad.sum() == 5
    np.testing.assert_allclose(fixed[1, 0], unit[0, 0])
    np.testing.assert_allclose(fixed[3, 0], unit[4, 0])
    np.testing.assert_allclose(fixed[3:, 1], np.tile([0, 0, 0, 1.0], (3, 1)))
    np.testing.assert_allclose(fixed[~bad], unit[~bad])
    validate_quaternions(fixed)
    # without segment starts the last valid quaternion crosses into the next trial
    fixed2, _ = repair_quaternions(q)
    np.testing.assert_allclose(fixed2[3:, 1], np.tile(unit[2, 1], (3, 1)))


def test_finger_of():
    assert finger_of("wrist3") == "palm"
    assert finger_of("b_r_index2") == "index"
    assert finger_of("Pinky1") == "pinky"
    assert finger_of("elbow") is None


def test_scale():
    h = HandCapsules(capsules=[_spec()], scale=2.0).build()
    assert h.radius_m[0] == pytest.approx(0.02) and h.height_m[0] == pytest.approx(0.12)
    np.testing.assert_allclose(h.center_offset_m[0], [0.04, 0, 0])


@pytest.mark.parametrize(
    "change, key",
    [
        (dict(radius_m=0.0), r"capsules\[1\]\.radius_m"),
        (dict(height_m=-0.01), r"capsules\[1\]\.height_m"),
        (dict(axis=3), r"capsules\[1\]\.axis"),
        (dict(finger="toe"), r"capsules\[1\]\.finger"),
        (dict(name="index1"), r"capsules\[1\]\.name.*unique"),
        (dict(off=(0.0, 0.0)), r"capsules\[1\]\.center_offset_m"),
    ],
)
def test_bad_capsule_config(change, key):
    with pytest.raises(ConfigError, match=key):
        HandCapsules(capsules=[_spec(), _spec(**{"name": "index2", **change})])


def test_schema_checks_on_composition():
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="hand/quest_capsules", overrides=["hand.capsules.3.radius_m=-1", "hand.scale=2"])
    with pytest.raises(ConfigError, match=r"hand\.capsules\[3\]\.radius_m"):
        OmegaConf.to_object(cfg.hand)
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="hand/quest_capsules", overrides=["hand.scale=0"])
    with pytest.raises(ConfigError, match=r"hand\.scale"):
        OmegaConf.to_object(cfg.hand)


def _write(tmp_path: Path, entries) -> str:
    p = tmp_path / "hand_capsule_definition.json"
    p.write_text(json.dumps(entries) if not isinstance(entries, str) else entries)
    return str(p)


def _entry(i=1, name="index1", **kw):
    e = {
        "capsule_index": i,
        "column_prefix": name,
        "height_m": 0.05,
        "radius_m": 0.01,
        "orientation": 0.0,
        "center_offset_m": {"x": 0.01, "y": 0.0, "z": 0.0},
    }
    e.update(kw)
    return e


def test_definition_any_count_and_order(tmp_path):
    path = _write(tmp_path, [_entry(2, "thumb1", orientation=2.0), _entry(1, "wrist1")])
    h = HandCapsules(definition_path=path).build()
    assert h.names == ("wrist1", "thumb1") and h.fingers == ("palm", "thumb")
    assert h.axis.tolist() == [0, 2]


@pytest.mark.parametrize(
    "entries, match",
    [
        ("{not json", "not valid JSON"),
        ({"a": 1}, "non-empty JSON list"),
        ([_entry(1), _entry(2, "index1")], r"entry 1 \('index1'\): duplicate name"),
        ([_entry(1, radius_m=0.0)], r"entry 0 \('index1'\): radius_m=0.0 must be > 0"),
        ([_entry(1, height_m=-0.1)], r"entry 0 .*height_m"),
        ([_entry(1, orientation=3)], r"entry 0 .*orientation=3"),
        ([_entry(1, radius_m="big")], r"entry 0 .*radius_m='big' is not a finite number"),
        ([{k: v for k, v in _entry(1).items() if k != "height_m"}], r"entry 0 .*missing 'height_m'"),
        ([_entry(1, center_offset_m={"x": 0.0})], r"entry 0 .*center_offset_m"),
        ([_entry(1, name="elbow")], r"entry 0 \('elbow'\): cannot tell the finger"),
        ([_entry(1), _entry(1, "index2")], "capsule_index values are not unique"),
    ],
)
def test_bad_definition_files(tmp_path, entries, match):
    path = _write(tmp_path, entries)
    with pytest.raises(HandDefinitionError, match=match) as err:
        load_definition(path)
    assert path in str(err.value)


def test_missing_definition_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.json"):
        HandCapsules(definition_path=str(tmp_path / "nope.json")).build()


def test_finger_override_in_definition(tmp_path):
    path = _write(tmp_path, [_entry(1, "elbow", finger="palm")])
    assert HandCapsules(definition_path=path).build().fingers == ("palm",)
