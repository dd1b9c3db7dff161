"""Fixtures of the importer tests: the study's hand, the parametric Reachy, a small synthetic dataset, logs."""

from __future__ import annotations

import numpy as np
import pytest
from hydra.utils import instantiate

from sphri.config import component_node


def load_component(group: str, name: str):
    return instantiate(component_node(group, name), _convert_="all")


@pytest.fixture(scope="session")
def hand():
    return load_component("hand", "quest_capsules").build()


@pytest.fixture(scope="session")
def robot():
    return load_component("robot", "reachy").build()


@pytest.fixture(scope="session")
def synthetic(hand, robot):
    """One participant's 8 gestures on the arm from sphri's synthetic generator (30 Hz)."""
    from sphri.data.synthetic import SyntheticData

    return SyntheticData(seed=11, participants=1, repetitions=1, regions=["arm"]).load(hand=hand, robot=robot)


@pytest.fixture(scope="session")
def rig_poses(hand):
    """(T, 19, 7) poses of the synthetic hand's kinematics (no tracking noise): bones chained, hand scale 1.07."""
    from sphri.data.handfk import HandRig

    rng = np.random.default_rng(5)
    t = 40
    fingers = np.cumsum(rng.normal(0, 0.05, (t, 5, 4)), axis=0) + np.array([0.0, 0.3, 0.3, 0.2])
    ang = np.cumsum(rng.normal(0, 0.03, (t, 3)), axis=0)
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_rotvec(ang + [0.3, -0.2, 1.0]).as_matrix()
    pos = np.array([0.05, -0.02, -0.35]) + np.cumsum(rng.normal(0, 0.002, (t, 3)), axis=0)
    return HandRig.from_hand(hand).poses(fingers, rot, pos, 1.07)
