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


@pytest.fixture(scope="module")
def written(small, tmp_path_factory):
    """The ``small`` sessions written to disk in the session format (a folder per module)."""
    from sphri.sessions.format import write_sessions

    _, _, _, ds = small
    root = tmp_path_factory.mktemp("sessions")
    write_sessions(ds, root)
    return root
