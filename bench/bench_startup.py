"""What a job costs before and around its work: kernel compilation, imports, composition, MLflow.

Each measurement is a fresh ``python`` process on the ``+debug=fast`` job
(3 participants, seconds of work), in a temporary working directory:

- ``cold_kernels_s``: an empty numba cache (``NUMBA_CACHE_DIR``) and an empty
  stage cache: the first run of sphri on a machine. ``compile_s`` is what the
  run itself reports compiling (``sphri._numba``);
- ``warm_kernels_s``: kernels from numba's cache, empty stage cache: a new
  experiment on a machine that ran sphri before;
- ``cached_rerun_s``: the same command again (only the evaluation entry is
  loaded): pure per-job overhead;
- ``cached_rerun_no_tracking_s``: the same with ``tracking.enabled=false``:
  the difference is what MLflow logging costs per job;
- ``import_s``: ``import sphri.__main__`` and the interpreter start;
- ``validate_s``: ``python -m sphri validate +debug=fast`` (imports, schema
  registration, composition, validation; no stage);
- ``validate_100_jobs_s``: ``python -m sphri validate +experiment=resolution_sweep``
  (its 100 jobs, through the check a sweep runs);
- ``skipped_sweep_s``: a finished 2-job ``+debug=fast`` sweep run again into a
  new sweep folder (every job answered by the launching process);
- ``tab_completion_s``: one TAB through the ``sphri`` console script
  (:mod:`sphri.completion`) in a context asked before; ``tab_completion_first_s``
  the first TAB in that context (Hydra answers it); ``tab_completion_hydra_s``
  Hydra's own completion (``python -m sphri -sc query=bash``), the baseline.

``goals`` holds the targets of issue 28 and ``meets`` whether each was met in
this run. The machine (CPU model, SIMD flags, load) is recorded beside them:
the figures hold for it only.

The baseline for the ratios is ``warm_kernels_s``, measured in the same run.
Quick and full sizes are the same here (the job is the debug job); writes
``outputs/bench/startup.json``.

    python bench/bench_startup.py [--quick] [--repeat N]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, write_json  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
JOB = ["-m", "sphri", "+debug=fast"]


def timed(args: list[str], cwd: Path, env: dict[str, str]) -> tuple[float, str]:
    """Wall seconds of one fresh process, and its output; fails loudly."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{(proc.stdout + proc.stderr)[-3000:]}")
    return dt, proc.stdout + proc.stderr


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="same as the full size (kept for run_all.py)")
    parser.add_argument("--repeat", type=int, default=2, help="repetitions of the warm measurements (best kept)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="sphri-startup-") as tmp:
        tmp = Path(tmp)
        env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(tmp / "numba")}
        out: dict = {"machine": machine(), "job": " ".join(["python", *JOB])}

        cold_dir = tmp / "cold"
        cold_dir.mkdir()
        out["cold_kernels_s"], log = timed(JOB, cold_dir, env)
        m = re.search(r"compiled (\d+) numba kernels in ([\d.]+) s", log)
        out["compile_s"] = float(m.group(2)) if m else 0.0
        out["kernels_compiled"] = int(m.group(1)) if m else 0

        warm, rerun, rerun_nt, imp, val = [], [], [], [], []
        for i in range(args.repeat):
            d = tmp / f"warm{i}"
            d.mkdir()
            warm.append(timed(JOB, d, env)[0])
            rerun.append(timed(JOB, d, env)[0])
            rerun_nt.append(timed([*JOB, "tracking.enabled=false"], d, env)[0])
            imp.append(timed(["-c", "import sphri.__main__"], d, env)[0])
            val.append(timed(["-m", "sphri", "validate", "+debug=fast"], d, env)[0])
        out["warm_kernels_s"] = min(warm)
        out["cached_rerun_s"] = min(rerun)
        out["cached_rerun_no_tracking_s"] = min(rerun_nt)
        out["mlflow_per_job_s"] = out["cached_rerun_s"] - out["cached_rerun_no_tracking_s"]
        out["import_s"] = min(imp)
        out["validate_s"] = min(val)
        out["first_run_over_warm"] = out["cold_kernels_s"] / out["warm_kernels_s"]

        d = tmp / "extra"
        d.mkdir()
        out["validate_100_jobs_s"] = min(
            timed(["-m", "sphri", "validate", "+experiment=resolution_sweep"], d, env)[0] for _ in range(args.repeat)
        )
        sweep = ["-m", "sphri", "-m", "+debug=fast", "layout.res=2,3", "hydra/launcher=serial"]
        timed([*sweep, "hydra.sweep.dir=s0"], d, env)
        out["skipped_sweep_s"] = min(
            timed([*sweep, f"hydra.sweep.dir=s{i + 1}"], d, env)[0] for i in range(args.repeat)
        )
        # the console script (sphri.completion): the first TAB in a context asks Hydra, later ones read its answer
        comp_env = {**env, "COMP_LINE": "sphri encoder.re", "COMP_POINT": "16", "XDG_CACHE_HOME": str(tmp / "xdg")}
        tab = ["-c", "import sys; sys.argv = ['sphri', '-sc', 'query=bash']; from sphri.completion import main; main()"]
        out["tab_completion_first_s"] = timed(tab, d, comp_env)[0]
        out["tab_completion_s"] = min(timed(tab, d, comp_env)[0] for _ in range(args.repeat))
        out["tab_completion_hydra_s"] = min(
            timed(["-m", "sphri", "-sc", "query=bash"], d, comp_env)[0] for _ in range(args.repeat)
        )
        out["goals"] = {
            "compile_s": 20.0,
            "cached_rerun_s": 3.0,
            "validate_100_jobs_s": 10.0,
            "skipped_sweep_s": 5.0,
            "tab_completion_s": 0.5,
        }
        out["meets"] = {k: out[k] <= v for k, v in out["goals"].items()}
    path = write_json("startup", out)
    print({k: (round(v, 2) if isinstance(v, float) else v) for k, v in out.items()})
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
