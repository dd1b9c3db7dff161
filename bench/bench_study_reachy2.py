"""Time the full built-in scenario study on robot=reachy2 from an empty stage cache (issue 27, item 7).

    python bench/bench_study_reachy2.py --label after              # runs the study (about 2-4 minutes)
    python bench/bench_study_reachy2.py --label after --cold-numba  # ... after deleting this checkout's numba cache
    python bench/bench_study_reachy2.py --label after --out DIR     # ... keeping the study's outputs in DIR
    python bench/bench_study_reachy2.py --label before --import-run DIR   # a run made by hand: DIR/log.txt from
                                                                          # /usr/bin/time -v, DIR/out/timing.json

The command is ``python -m sphri coverage +experiment=scenario_study robot=reachy2 out=... cache.dir=<empty>
mlflow=false``. Each label's entry holds the wall and CPU seconds (user + system of the study's process and
its children: on 2 idle cores the wall time is at most about this when the run is mostly serial), the
study's own phase times (``timing.json``), the load average before and after, and the machine
(``_common.machine()``). Entries of other labels are kept, so ``before`` and ``after`` sit in one file:
``outputs/bench/scenario_study_reachy2.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import OUT, machine, write_json  # noqa: E402

NAME = "scenario_study_reachy2"
COMMAND = ["-m", "sphri", "coverage", "+experiment=scenario_study", "robot=reachy2", "mlflow=false"]
SHARED = (
    "The machine (2 cores) was shared with other agents' jobs while this ran: see loadavg_before/after "
    "(1, 5, 15 min); wall times are inflated by that load, CPU seconds much less."
)


def clear_numba_cache(root: Path) -> int:
    n = 0
    for p in root.rglob("__pycache__/*.nb[ic]"):
        p.unlink()
        n += 1
    return n


def run(cold_numba: bool, keep: Path | None = None) -> dict:
    root = HERE.parent
    cleared = clear_numba_cache(root / "sphri") if cold_numba else 0
    with tempfile.TemporaryDirectory() as tmp:
        out = keep.resolve() if keep is not None else Path(tmp) / "out"
        load0 = os.getloadavg()
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, *COMMAND, f"out={out}", f"cache.dir={tmp}/cache"],
            cwd=root,
            capture_output=True,
            text=True,
        )
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if proc.returncode:
            raise SystemExit(f"the study failed (rc {proc.returncode}): {proc.stderr[-2000:]}")
        phases = json.loads((out / "timing.json").read_text())
        summary = json.loads((out / "summary.json").read_text())
    return {
        "wall_s": wall,
        "cpu_s": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
        "phases_s": phases,
        "numba_cache": "cleared first" if cold_numba else "as left by earlier runs",
        "numba_files_cleared": cleared,
        "loadavg_before": list(load0),
        "loadavg_after": list(os.getloadavg()),
        "figure_formats": summary["settings"]["figure_formats"],
        "n_sessions": summary["n_sessions"],
    }


def imported(run_dir: Path) -> dict:
    log = (run_dir / "log.txt").read_text()
    grab = lambda pat: float(re.search(pat, log).group(1))  # noqa: E731
    m = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (?:(\d+):)?(\d+):([\d.]+)", log)
    wall = float(m.group(1) or 0) * 3600 + float(m.group(2)) * 60 + float(m.group(3))
    return {
        "wall_s": wall,
        "cpu_s": grab(r"User time \(seconds\): ([\d.]+)") + grab(r"System time \(seconds\): ([\d.]+)"),
        "phases_s": json.loads((run_dir / "out" / "timing.json").read_text()),
        "source": str(run_dir),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--label", required=True)
    ap.add_argument("--cold-numba", action="store_true", help="delete this checkout's numba cache first")
    ap.add_argument("--import-run", type=Path, help="record a run made by hand instead of running one")
    ap.add_argument("--note", default="", help="what else to say about this entry")
    ap.add_argument("--out", type=Path, help="keep the study's outputs in this directory (default: a temporary one)")
    args = ap.parse_args()
    entry = imported(args.import_run) if args.import_run else run(args.cold_numba, args.out)
    entry.update(
        {
            "machine": machine(),
            "note": " ".join(x for x in (args.note, SHARED) if x),
            "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
            "command": "python " + " ".join(COMMAND) + " out=DIR cache.dir=<empty>",
        }
    )
    path = OUT / f"{NAME}.json"
    data = json.loads(path.read_text()) if path.is_file() else {}
    data[args.label] = entry
    print(write_json(NAME, data))
    print(json.dumps({k: entry[k] for k in ("wall_s", "cpu_s")}))


if __name__ == "__main__":
    main()
