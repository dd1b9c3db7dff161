"""What ``hold_contact`` costs: generating synthetic sessions on Reachy 2 with and without it.

Generates the study's first ``--participants`` participants x 5 scenarios x 1 repetition (``robot=reachy2``,
``data=synthetic_sessions``) alternately with ``hold_contact`` and with it replaced by a no-op (the version-3
hands), ``--rounds`` times each; wall and CPU seconds per run.

    python bench/bench_hold_contact_cost.py [--participants 2] [--rounds 2]

Writes ``outputs/bench/hold_contact_cost.json``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import machine, write_json  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.sessions import synthetic as syn

    over = ["+experiment=scenario_study", "robot=reachy2", f"data.participants={args.participants}"]
    cfg = compose([*over, "data.repetitions=1"])
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    real = syn.hold_contact
    runs = []
    for _ in range(args.rounds):
        for mode in ("hold", "no_hold"):
            syn.hold_contact = real if mode == "hold" else (lambda out, *a, **k: (out, 0))
            load0, t0, c0 = os.getloadavg()[0], time.perf_counter(), time.process_time()
            ds = instantiate(cfg.data).load(hand, robot)
            runs.append(
                {
                    "mode": mode,
                    "wall_s": round(time.perf_counter() - t0, 2),
                    "cpu_s": round(time.process_time() - c0, 2),
                    "frames": int(ds.n_frames),
                    "loadavg_1min_at_start": round(load0, 2),
                }
            )
            print(runs[-1], flush=True)
    syn.hold_contact = real
    result = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": "python bench/bench_hold_contact_cost.py " + " ".join(sys.argv[1:]),
        "what": __doc__.splitlines()[0],
        "sessions": args.participants * 5,
        "runs": runs,
    }
    print(write_json("hold_contact_cost", result))


if __name__ == "__main__":
    main()
