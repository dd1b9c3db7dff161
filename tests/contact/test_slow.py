"""Acceptance at full size (slow): the 200,000-capsule hard set against the reference, and
the contact stage over a study-sized dataset (740,000 frames x 19 capsules; its speed is in bench/bench_contact.py)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sphri.contact import capsule_mesh_query, prepare_mesh
from sphri.contact.exact import ExactContact
from sphri.testing.contact_reference import arm_stand_in, compare, random_capsules, reference_query
from sphri.types import TRIAL_COLUMNS, GestureDataset, HandModel, Link, Robot

pytestmark = pytest.mark.slow


def test_hard_set_200k_is_exact(real_arm):
    v, f = real_arm
    p0, p1, r, kind = random_capsules(v, f, 200_000, seed=0)
    q = capsule_mesh_query(v, f, p0, p1, r)
    ref = reference_query(v, f, p0, p1, r, inside=prepare_mesh(v, f).inside_mode)
    c = compare(q, ref, r)
    assert c["contact_disagreements"] == 0 and c["inside_disagreements"] == 0, c
    assert c["missed_inside"] == 0 and c["distance_over_tol"] == 0, c
    assert q.inside[kind == 2].all()


def test_stage_over_a_study_sized_dataset():
    rng = np.random.default_rng(0)
    c = 19
    hand = HandModel(
        names=tuple(f"c{i}" for i in range(c)),
        fingers=("palm",) * c,
        radius_m=rng.uniform(0.007, 0.023, c),
        height_m=rng.uniform(0.03, 0.09, c),
        axis=np.zeros(c, dtype=np.int64),
        center_offset_m=rng.normal(scale=0.02, size=(c, 3)),
    )
    v, f = arm_stand_in()
    robot = Robot("r", {"l_arm": Link("l_arm", v, f, watertight=False)}, {"arm": "l_arm"})
    n = 740_000
    t = np.arange(n)
    centre = np.array([0.0, 0.0, -0.36])
    # a hand circling the arm, a third of the time touching it
    path = centre + np.stack([0.09 * np.sin(t / 97.0), 0.09 * np.cos(t / 131.0), 0.12 * np.sin(t / 173.0)], 1)
    pos = path[:, None, :] + rng.normal(scale=0.03, size=(n, c, 3))
    q = rng.normal(size=(n, c, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    poses = np.concatenate([pos, q], axis=-1).astype(np.float32)
    per = 134
    k = n // per
    trials = pd.DataFrame(
        {
            "participant": "participant_01",
            "region": "arm",
            "trial_ordinal": np.arange(k) + 1,
            "trial_id": [f"{i + 1:04d}_pat" for i in range(k)],
            "gesture": "pat",
            "start": np.arange(k) * per,
            "n_frames": per,
        }
    )[list(TRIAL_COLUMNS)]
    ds = GestureDataset("big", True, hand, trials, poses, 30.0)
    comp = ExactContact()
    comp.compute(GestureDataset("warm", True, hand, trials.iloc[:1], poses, 30.0), robot)  # compile
    con = comp.compute(ds, robot)
    # its speed is measured by bench/bench_contact.py (outputs/bench/), never asserted here
    assert con.n_contacts > 100_000 and con.inside.sum() > 1000
