"""``sphri synthesize what=sessions out=DIR [overrides]``: write the synthetic scenario sessions to disk.

Composes ``data=synthetic_sessions robot=reachy_full`` plus the overrides
(``data.participants=4 data.repetitions=1 +debug=fast ...``), generates the
sessions exactly as the scenario study does, and writes them in the session
format (:mod:`sphri.sessions.format`). The folder then loads with
``data=sessions data.root=DIR`` (labelled synthetic), e.g.
``sphri coverage +experiment=scenario_study data=sessions data.root=DIR``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from sphri.data.synthesize import SynthesizeArgs, write_dataset
from sphri.sessions.format import SessionDataset


def synthesize(out: str | Path, overrides: Sequence[str] = (), overwrite: bool = False) -> SessionDataset:
    """Generate the configured sessions and write them under ``out``; returns them. An existing, non-empty
    ``out`` is refused unless ``overwrite``, and then replaced whole (:func:`sphri.fsutil.replace_dir`)."""
    from hydra.utils import instantiate

    from sphri.config import check_output_dir, compose
    from sphri.fsutil import replace_dir
    from sphri.sessions.format import write_sessions

    cfg = compose(["data=synthetic_sessions", "robot=reachy_full", *overrides])
    check_output_dir(str(out), key="out", overwrite=overwrite)  # before generating: one line, nothing mixed
    hand = instantiate(cfg.hand).build()
    robot = instantiate(cfg.robot).build()
    ds = instantiate(cfg.data).load(hand=hand, robot=robot)
    with replace_dir(out) as fresh:
        write_sessions(ds, fresh)
    return ds


def write_sessions(args: SynthesizeArgs) -> int:
    """Generate the scenario sessions (data=synthetic_sessions robot=reachy_full plus the overrides) exactly as
    the scenario study does and write them under out=DIR (they load with data=sessions data.root=DIR)."""
    return write_dataset(synthesize, args, "sessions")
