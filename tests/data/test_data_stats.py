"""Contact statistics: exact values on hand-made contacts, checks and the table."""

from __future__ import annotations

import numpy as np
import pandas as pd
import trimesh

from sphri.data.format import make_trials_frame
from sphri.data.reference_stats import COST_DURATION_MS, VR_MEDIAN_TRIAL_FRAMES
from sphri.data.stats import calibration_checks, format_summary, gesture_summary, trial_statistics
from sphri.types import Contacts, GestureDataset, Link, Robot


def toy(hand):
    box = trimesh.creation.box(extents=[0.1, 0.1, 0.1])
    link = Link(name="box", vertices=np.asarray(box.vertices), faces=np.asarray(box.faces, np.int64), watertight=True)
    robot = Robot(name="toy", links={"box": link}, regions={"arm": "box"})
    # participant 1's arm trials: poke frames 0..29, grab 30..69, hit 70..79
    trials = make_trials_frame(
        [
            dict(
                participant="participant_01",
                region="arm",
                trial_ordinal=i,
                trial_id=f"{i:04d}_{gesture}",
                gesture=gesture,
                start=start,
                n_frames=n,
            )
            for i, (gesture, start, n) in enumerate([("poke", 0, 30), ("grab", 30, 40), ("hit", 70, 10)], start=1)
        ]
    )
    poses = np.zeros((80, hand.n_capsules, 7), np.float32)
    poses[..., 6] = 1.0
    ds = GestureDataset(name="toy", synthetic=True, hand=hand, trials=trials, poses=poses, frame_rate_hz=30.0)
    return ds, robot


def contacts(rows):
    """Contacts on the box's top face (z = 0.05) from (frame, capsule, x, y, patch radius) rows."""
    rows = sorted(rows)
    k = len(rows)
    a = np.array(rows, dtype=np.float64).reshape(k, 5)
    point = np.c_[a[:, 2], a[:, 3], np.full(k, 0.05)]
    return Contacts(
        n_frames=80,
        frame=a[:, 0].astype(np.int64),
        capsule=a[:, 1].astype(np.int16),
        distance_m=np.zeros(k),
        inside=np.zeros(k, bool),
        point_m=point,
        segment_point_m=point,
        triangle=np.zeros(k, np.int64),
        barycentric=np.full((k, 3), 1 / 3),
        normal=np.tile([0.0, 0.0, 1.0], (k, 1)),
        patch_radius_m=a[:, 4],
        depth_m=np.full(k, 0.001),
    )


def test_duration_and_area_are_exact(hand):
    ds, robot = toy(hand)
    # poke: capsule 9 touches frames 5..14 with a 2 cm patch; grab: frames 40..59, two 2.5 cm patches
    # 2.5 cm apart in frames 40..49 and coinciding in 50..59; hit: no contact
    rows = [(f, 9, 0.0, 0.0, 0.02) for f in range(5, 15)]
    rows += [(f, c, x, 0.0, 0.025) for f in range(40, 50) for c, x in ((1, -0.0125), (2, 0.0125))]
    rows += [(f, c, 0.0, 0.0, 0.025) for f in range(50, 60) for c in (1, 2)]
    st = trial_statistics(ds, contacts(rows), robot)
    assert st["contact"].tolist() == [True, True, False]
    assert st["first_contact"].tolist() == [5, 10, -1] and st["last_contact"].tolist() == [14, 29, -1]
    assert np.allclose(st["duration_s"], [10 / 30, 20 / 30, 0.0])
    assert st["n_capsules"].tolist() == [1, 2, 0]
    disk = np.pi * 0.02**2
    assert abs(st["area_m2"][0] / disk - 1) < 0.12
    # union of two disks of radius r whose centres are d apart: two disks minus their lens
    r, d = 0.025, 0.025
    lens = 2 * r * r * np.arccos(d / (2 * r)) - 0.5 * d * np.sqrt(4 * r * r - d * d)
    union = 2 * np.pi * r * r - lens
    expected = 0.5 * union + 0.5 * np.pi * r * r  # half the sampled frames each
    assert abs(st["area_m2"][1] / expected - 1) < 0.1
    assert st["area_m2"][1] > 1.2 * np.pi * r * r  # the overlapping frames count their union once
    assert np.isnan(st["area_m2"][2])


def test_summary_checks_and_table(hand):
    ds, robot = toy(hand)
    rows = [(f, 9, 0.0, 0.0, 0.005) for f in range(5, 25)]
    rows += [(f, c, 0.0, 0.0, 0.03) for f in range(40, 60) for c in (1, 2)]
    stats = trial_statistics(ds, contacts(rows), robot)
    summary = gesture_summary(stats)
    assert summary["gesture"].tolist() == ["hit", "poke", "grab"]  # GESTURES order
    assert (summary["ref_duration_ms"] == [COST_DURATION_MS[g][0] for g in summary["gesture"]]).all()
    assert (summary["ref_median_frames"] == [VR_MEDIAN_TRIAL_FRAMES["arm"][g] for g in summary["gesture"]]).all()
    checks = {n: ok for n, ok, _ in calibration_checks(summary)}
    assert checks["arm/poke duration"] is True  # 667 ms vs 650
    assert checks["arm/poke trial length"] is False  # 30 frames vs 108.5
    assert checks["arm area: grab largest"] is True and checks["arm area: poke smallest"] is True
    text = format_summary(summary, "toy", 30.0)
    assert "poke" in text and "CoST" in text and "toy" in text
    assert isinstance(summary, pd.DataFrame)
