"""``python -m sphri.sessions.synthesize out=DIR [overrides]``: write the synthetic scenario sessions to disk.

Composes ``data=synthetic_sessions robot=reachy_full`` plus the overrides
(``data.participants=4 data.repetitions=1 +debug=fast ...``), generates the
sessions exactly as the scenario study does, and writes them in the session
format (:mod:`sphri.sessions.format`). The folder then loads with
``data=sessions data.root=DIR`` (labelled synthetic), e.g.
``python -m sphri.coverage +experiment=scenario_study data=sessions data.root=DIR``.
"""

from __future__ import annotations

import logging
import sys
import time
from pathlib import Path
from typing import Sequence

from sphri.sessions.format import SessionDataset


def synthesize(out: str | Path, overrides: Sequence[str] = ()) -> SessionDataset:
    """Generate the configured sessions and write them under ``out``; returns them."""
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.sessions.format import write_sessions

    cfg = compose(["data=synthetic_sessions", "robot=reachy_full", *overrides])
    hand = instantiate(cfg.hand).build()
    robot = instantiate(cfg.robot).build()
    ds = instantiate(cfg.data).load(hand=hand, robot=robot)
    write_sessions(ds, out)
    return ds


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if any(a in ("-h", "--help") for a in argv):
        print(__doc__)
        return 0
    outs = [a.split("=", 1)[1] for a in argv if a.startswith("out=")]
    if len(outs) != 1 or not outs[0]:
        print("usage: python -m sphri.sessions.synthesize out=DIR [data.participants=N ...]", file=sys.stderr)
        return 2
    t = time.perf_counter()
    ds = synthesize(outs[0], [a for a in argv if not a.startswith("out=")])
    print(f"wrote {len(ds.sessions)} sessions, {ds.n_frames} frames ({ds.name}, {ds.frame_rate_hz:g} Hz) "
          f"to {Path(outs[0]).resolve()} in {time.perf_counter() - t:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
