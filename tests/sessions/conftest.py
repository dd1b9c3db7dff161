"""Small sessions shared by the scenario-study tests (2 participants x 5 scenarios x 1 repetition)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from hydra.utils import instantiate

from sphri.config import compose

SMALL = ["data=synthetic_sessions", "robot=reachy_full", "data.participants=2", "data.repetitions=1"]


def study_touches(keep, n: int):
    """The full study's generator, hand, robot, priors table and its first ``n`` sessions (participant k,
    repetition, scenario index, scenario) whose session draw satisfies ``keep(draw)``, in the study's order."""
    import numpy as np

    from sphri.sessions import synthetic as syn

    cfg = compose(["+experiment=scenario_study", "robot=reachy2"])
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    gen = instantiate(cfg.data)
    table = syn.load_priors(gen.priors, [p.name for p in robot.parts], list(robot.tree.joint_names))
    picks = []
    names = list(table["scenarios"])
    for k in range(1, gen.participants + 1):
        for rep in range(1, gen.repetitions + 1):
            for si, scen in enumerate(names):
                dr = syn._draw_session(np.random.default_rng([gen.seed, k, si + 1, rep]), table["scenarios"][scen], k)
                if keep(dr):
                    picks.append((k, rep, si, scen))
    return gen, hand, robot, table, picks[:n]


def generated(study):
    """Yield (hand poses, truth row) of each session picked by :func:`study_touches`, generated one at a time with
    the study's random streams (a spy set on the generator sees each in turn)."""
    import numpy as np

    from sphri.data.gestures import Style
    from sphri.data.handfk import HandRig

    gen, hand, robot, table, picks = study
    rig = HandRig.from_hand(hand)
    for k, rep, si, scen in picks:
        style = Style.draw(np.random.default_rng([gen.seed, k, 0]), gen.spread)
        out, _, info = gen._session(
            np.random.default_rng([gen.seed, k, si + 1, rep]), style, rig, robot, {}, table, scen, k
        )
        yield out, info


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
