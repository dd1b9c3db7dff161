"""``python -m sphri.sessions.synthesize out=DIR [overrides]``: write the synthetic scenario sessions to disk.

Composes ``data=synthetic_sessions robot=reachy_full`` plus the overrides
(``data.participants=4 data.repetitions=1 +debug=fast ...``), generates the
sessions exactly as the scenario study does, and writes them in the session
format (:mod:`sphri.sessions.format`). The folder then loads with
``data=sessions data.root=DIR`` (labelled synthetic), e.g.
``python -m sphri.coverage +experiment=scenario_study data=sessions data.root=DIR``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from pathlib import Path

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
    from sphri.data.synthesize import out_and_overrides

    argv = list(sys.argv[1:] if argv is None else argv)
    out, overrides = out_and_overrides(argv, "python -m sphri.sessions.synthesize", __doc__)
    if out is None:
        return 0 if overrides is None else 2
    t = time.perf_counter()
    ds = synthesize(out, overrides)
    print(
        f"wrote {len(ds.sessions)} sessions, {ds.n_frames} frames ({ds.name}, {ds.frame_rate_hz:g} Hz) "
        f"to {Path(out).resolve()} in {time.perf_counter() - t:.1f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
