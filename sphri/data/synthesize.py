"""``python -m sphri.data.synthesize out=DIR [overrides]``: write a synthetic dataset to disk.

Composes the config with the overrides (``data.participants=4
data.repetitions=4 data.regions=[arm,torso] robot=...``), generates the
dataset in memory exactly as ``data=synthetic`` does in a run, and writes it
in the VR gesture dataset's layout (:mod:`sphri.data.writer`): per region and
participant a parquet file and a manifest, plus ``assets/`` with the hand
capsule definition and the meshes of the links touched. The folder then
loads with ``data=vr_gesture data.root=DIR`` (labelled synthetic).
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from sphri.errors import clean_errors
from sphri.types import GestureDataset


def synthesize(out: str | Path, overrides: Sequence[str] = ()) -> GestureDataset:
    """Generate the configured dataset and write it under ``out``; returns it."""
    from hydra.utils import instantiate
    from omegaconf import OmegaConf

    from sphri.config import compose
    from sphri.data.writer import write_dataset

    cfg = compose(list(overrides))
    hand = instantiate(cfg.hand).build()
    robot = instantiate(cfg.robot).build()
    dataset = instantiate(cfg.data).load(hand=hand, robot=robot)
    meta = {"data": OmegaConf.to_container(cfg.data, resolve=True), "robot": robot.name}
    write_dataset(dataset, robot, out, meta=meta)
    return dataset


def out_and_overrides(argv: list[str], prog: str, doc: str | None) -> tuple[str | None, list[str] | None]:
    """``out=DIR`` and the config overrides of a synthesize command (also ``python -m sphri.sessions.synthesize``).

    Prints the help (returns ``(None, None)``) or a usage line (``(None, [])``)."""
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if any(a in ("-h", "--help") for a in argv):
        print(doc)
        return None, None
    outs = [a.split("=", 1)[1] for a in argv if a.startswith("out=")]
    if len(outs) != 1 or not outs[0]:
        print(f"usage: {prog} out=DIR [data.participants=N ...]", file=sys.stderr)
        return None, []
    return outs[0], [a for a in argv if not a.startswith("out=")]


@clean_errors("sphri.data.synthesize")
def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    out, overrides = out_and_overrides(argv, "python -m sphri.data.synthesize", __doc__)
    if out is None:
        return 0 if overrides is None else 2
    t = time.perf_counter()
    ds = synthesize(out, overrides)
    print(
        f"wrote {len(ds.trials)} trials, {ds.n_frames} frames ({ds.name}, {ds.frame_rate_hz:g} Hz) "
        f"to {Path(out).resolve()} in {time.perf_counter() - t:.1f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
