"""The real study's manifests and assets in ../shared (skipped when absent)."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from sphri.data.format import PARTICIPANT_RE, read_manifest
from sphri.data.reference_stats import VR_MEDIAN_TRIAL_FRAMES
from sphri.data.vr_gesture import VRGestureData, find_participants
from sphri.hand.capsules import load_definition
from sphri.robots.validate import read_mesh
from sphri.types import GESTURES

pytestmark = pytest.mark.shared


def test_manifests_validate_and_match_the_reference_numbers(shared_dir):
    root = shared_dir / "vr-gesture-dataset"
    assert find_participants(root, ["arm"]) == [f"participant_{i:02d}" for i in range(1, 19)]
    assert "participant_17" not in find_participants(root, ["torso"])
    lengths: dict[tuple[str, str], list[int]] = defaultdict(list)
    n_trials = n_frames = 0
    for path in sorted(root.glob("*/participant_*/participant_*_manifest.json")):
        m = read_manifest(path)
        assert PARTICIPANT_RE.match(m["participant_id"]) and m["body_region"] == path.parent.parent.name
        for t in m["trials"]:
            assert t["gesture_label"] in GESTURES
            lengths[(m["body_region"], t["gesture_label"])].append(t["frame_count"])
        n_trials += m["num_trials"]
        n_frames += m["num_frames_total"]
    assert (n_trials, n_frames) == (5520, 738974)
    for (region, gesture), v in lengths.items():
        assert np.median(v) == VR_MEDIAN_TRIAL_FRAMES[region][gesture]
    assert sum(np.sum(np.array(v) < 10) for v in lengths.values()) == 3  # the 1-frame trials min_frames drops


def test_assets_load(shared_dir, hand):
    assets = shared_dir / "vr-gesture-dataset" / "assets"
    specs = load_definition(assets / "hand_capsule_definition.json")
    assert tuple(s["name"] for s in specs) == hand.names
    assert np.allclose([s["radius_m"] for s in specs], hand.radius_m)
    arm = read_mesh(assets / "arm_mesh.obj")
    v, f = arm.vertices, arm.faces
    ext = v.max(axis=0) - v.min(axis=0)
    assert len(f) == 197 and np.allclose(ext, [0.0718, 0.0928, 0.2408], atol=5e-4)
    torso = read_mesh(assets / "torso_mesh.obj")
    v, f = torso.vertices, torso.faces
    assert len(f) == 84 and np.allclose(v.max(axis=0) - v.min(axis=0), [0.1484, 0.3465, 0.2764], atol=5e-4)


def test_loader_names_the_missing_pose_files(shared_dir, hand):
    root = shared_dir / "vr-gesture-dataset"
    with pytest.raises(FileNotFoundError, match=r"arm/participant_01/participant_01\.parquet"):
        VRGestureData(root=str(root), regions=["arm"], participants=1).load(hand=hand)
