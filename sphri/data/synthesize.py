"""``sphri synthesize out=DIR [overrides]``: write a synthetic dataset to disk.

Its arguments are :class:`SynthesizeArgs`; ``sphri synthesize what=sessions`` writes the scenario
sessions (:mod:`sphri.sessions.synthesize`).

Composes the config with the overrides (``data.participants=4
data.repetitions=4 data.regions=[arm,torso] robot=...``), generates the
dataset in memory exactly as ``data=synthetic`` does in a run, and writes it
in the VR gesture dataset's layout (:mod:`sphri.data.writer`): per region and
participant a parquet file and a manifest, plus ``assets/`` with the hand
capsule definition and the meshes of the links touched. The folder then
loads with ``data=vr_gesture data.root=DIR`` (labelled synthetic).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from sphri.args import arg
from sphri.types import GestureDataset


def synthesize(out: str | Path, overrides: Sequence[str] = (), overwrite: bool = False) -> GestureDataset:
    """Generate the configured dataset and write it under ``out``; returns it. An existing, non-empty
    ``out`` is refused unless ``overwrite``, and then replaced whole (:func:`sphri.fsutil.replace_dir`)."""
    from hydra.utils import instantiate
    from omegaconf import OmegaConf

    from sphri.config import check_output_dir, compose
    from sphri.data.writer import write_dataset
    from sphri.fsutil import replace_dir

    cfg = compose(list(overrides))
    check_output_dir(str(out), key="out", overwrite=overwrite)  # before generating: one line, nothing mixed
    hand = instantiate(cfg.hand).build()
    robot = instantiate(cfg.robot).build()
    dataset = instantiate(cfg.data).load(hand=hand, robot=robot)
    meta = {"data": OmegaConf.to_container(cfg.data, resolve=True), "robot": robot.name}
    with replace_dir(out) as fresh:
        write_dataset(dataset, robot, fresh, meta=meta)
    return dataset


def _nonempty(value: str) -> str | None:
    return None if value else "must be a folder"


@dataclasses.dataclass
class SynthesizeArgs:
    out: str = arg(metavar="DIR", check=_nonempty, help="the folder to write")
    overrides: list[str] = arg([], rest=True, help="config overrides, e.g. data.participants=4 data.repetitions=1")
    overwrite: bool = arg(False, help="replace an existing, non-empty out folder whole (refused otherwise)")


def command(args: SynthesizeArgs) -> int:
    """Generate the configured synthetic gesture dataset in memory, exactly as a run does, and write it under
    out=DIR in the VR dataset's layout (it loads with data=vr_gesture data.root=DIR)."""
    return write_dataset(synthesize, args, "trials")


def write_dataset(make: Callable[..., Any], args: SynthesizeArgs, units: str) -> int:
    """Write a dataset with ``make(out, overrides, overwrite=...)`` (a ``synthesize``: it refuses an
    existing folder with :func:`sphri.config.check_output_dir` and writes through
    :func:`sphri.fsutil.replace_dir`) and say what it holds: how many ``units`` (its attribute: trials,
    sessions) and frames, where, and how long it took."""
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    t = time.perf_counter()
    ds = make(args.out, args.overrides, overwrite=args.overwrite)
    print(
        f"wrote {len(getattr(ds, units))} {units}, {ds.n_frames} frames ({ds.name}, {ds.frame_rate_hz:g} Hz) "
        f"to {Path(args.out).resolve()} in {time.perf_counter() - t:.1f} s"
    )
    return 0
