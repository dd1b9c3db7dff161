"""Small sessions shared by the scenario-study tests (2 participants x 5 scenarios x 1 repetition)."""

from __future__ import annotations

import pytest
from hydra.utils import instantiate

from sphri.config import compose

SMALL = ["data=synthetic_sessions", "robot=reachy_full", "data.participants=2", "data.repetitions=1"]


@pytest.fixture(scope="module")
def small():
    cfg = compose(SMALL)
    hand = instantiate(cfg.hand).build()
    robot = instantiate(cfg.robot).build()
    ds = instantiate(cfg.data).load(hand, robot)
    return cfg, hand, robot, ds
