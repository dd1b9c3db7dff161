"""Small sessions shared by the scenario-study tests (2 participants x 5 scenarios x 1 repetition)."""

from __future__ import annotations

import shutil
from pathlib import Path

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


@pytest.fixture()
def copy_written(written, tmp_path):
    """``copy(name)``: a fresh copy of the ``written`` sessions in ``tmp_path / name``, to break."""
    return lambda name: Path(shutil.copytree(written, tmp_path / name))


@pytest.fixture(scope="module")
def load_refused(small):
    """``check(root, match)``: loading the sessions in ``root`` raises SessionFormatError matching ``match``."""
    from sphri.sessions.format import SessionData, SessionFormatError

    _, hand, robot, _ = small

    def check(root: Path, match: str) -> None:
        with pytest.raises(SessionFormatError, match=match):
            SessionData(root=str(root)).load(hand, robot)

    return check
