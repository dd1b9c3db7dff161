"""A stand-in for SLURM's ``sbatch``, ``srun``, ``sacct`` and ``scancel`` (tests only).

Enough of SLURM for submitit (and so ``hydra/launcher=slurm``) to run a job
array on this machine: ``sbatch`` keeps a copy of the batch script, answers
``Submitted batch job N`` and runs each array task's script with ``bash``
in a detached process, with the ``SLURM_*`` variables a real allocation sets
(``SLURM_CPUS_PER_TASK`` from ``--cpus-per-task``); ``srun`` runs its command
with the ``--output``/``--error`` files (``%A %a %j %t`` substituted) and
records the thread variables the job started with; ``sacct`` reports the
states that the tasks left behind. Everything lands in ``$FAKE_SLURM_DIR``:

- ``<N>.sbatch``: the submitted script;
- ``state/<N>_<task>``: COMPLETED or FAILED once the task ended;
- ``env/<N>_<task>.json``: the environment ``srun`` saw (thread caps).

:func:`install` writes the four commands into a folder to put first on PATH.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

COMMANDS = ("sbatch", "srun", "sacct", "scancel")
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "SPHRI_THREADS")


def install(bin_dir: Path) -> Path:
    """Write executable ``sbatch``/``srun``/``sacct``/``scancel`` into ``bin_dir``."""
    bin_dir.mkdir(parents=True, exist_ok=True)
    here = Path(__file__).resolve().parent
    for name in COMMANDS:
        path = bin_dir / name
        path.write_text(
            f"#!{sys.executable}\nimport sys\nsys.path.insert(0, {str(here)!r})\n"
            f"import fake_slurm\nsys.exit(fake_slurm.main({name!r}, sys.argv[1:]))\n"
        )
        path.chmod(0o755)
    return bin_dir


def _root() -> Path:
    root = os.environ.get("FAKE_SLURM_DIR")
    if not root:
        sys.exit("fake_slurm: FAKE_SLURM_DIR is not set")
    return Path(root)


def sbatch_options(script: str) -> dict[str, str]:
    """``#SBATCH --key=value`` lines of a batch script (flags without value map to '')."""
    return {k: v for k, v in re.findall(r"^#SBATCH --([\w-]+)=?(.*)$", script, re.M)}


def _next_job_id(root: Path) -> int:
    counter = root / "counter"
    n = int(counter.read_text()) + 1 if counter.exists() else 1000
    counter.write_text(str(n))
    return n


def sbatch(args: list[str]) -> int:
    root = _root()
    root.mkdir(parents=True, exist_ok=True)
    script_path = Path(args[-1])
    text = script_path.read_text()
    job_id = _next_job_id(root)
    (root / f"{job_id}.sbatch").write_text(text)
    subprocess.Popen(
        [sys.executable, __file__, "--run", str(job_id), str(script_path.resolve())],
        start_new_session=True,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent)},
    )
    print(f"Submitted batch job {job_id}")
    return 0


def _run_array(job_id: str, script_path: str) -> None:
    root = _root()
    opts = sbatch_options(Path(script_path).read_text())
    tasks: list[int | None] = [None]
    parallel = 1
    if "array" in opts:
        m = re.fullmatch(r"(\d+)-(\d+)(?:%(\d+))?", opts["array"])
        if m is None:
            raise SystemExit(f"fake sbatch: cannot read --array={opts['array']}")
        tasks = list(range(int(m.group(1)), int(m.group(2)) + 1))
        parallel = int(m.group(3) or len(tasks))
    (root / "state").mkdir(exist_ok=True)

    def run(task: int | None) -> None:
        name = job_id if task is None else f"{job_id}_{task}"
        env = {
            **os.environ,
            "SLURM_JOB_ID": f"{job_id}{'' if task is None else task}",
            "SLURM_NTASKS": "1",
            "SLURM_PROCID": "0",
            "SLURM_LOCALID": "0",
            "SLURM_NODEID": "0",
            "SLURM_JOB_NUM_NODES": "1",
            "SLURM_JOB_NODELIST": "localhost",
            "SLURM_SUBMIT_DIR": os.getcwd(),
        }
        if "cpus-per-task" in opts:
            env["SLURM_CPUS_PER_TASK"] = opts["cpus-per-task"]
        if task is not None:
            env.update(SLURM_ARRAY_JOB_ID=job_id, SLURM_ARRAY_TASK_ID=str(task))
        with open(root / f"{name}.batch.log", "wb") as log:
            rc = subprocess.run(["bash", script_path], env=env, stdout=log, stderr=subprocess.STDOUT).returncode
        (root / "state" / name).write_text("COMPLETED" if rc == 0 else "FAILED")

    with ThreadPoolExecutor(max_workers=parallel) as pool:
        list(pool.map(run, tasks))


def _expand(pattern: str) -> str:
    env = os.environ
    job = env.get("SLURM_ARRAY_JOB_ID", env.get("SLURM_JOB_ID", "0"))
    task = env.get("SLURM_ARRAY_TASK_ID", "0")
    return pattern.replace("%A", job).replace("%a", task).replace("%j", env.get("SLURM_JOB_ID", "0")).replace("%t", "0")


def srun(args: list[str]) -> int:
    files = {"--output": None, "--error": None}
    i = 0
    while i < len(args) and args[i].startswith("-"):
        if args[i] in files:
            files[args[i]] = _expand(args[i + 1])
            i += 2
        else:
            i += 1
    command = args[i:]
    root = _root()
    name = os.environ.get("SLURM_ARRAY_JOB_ID", os.environ.get("SLURM_JOB_ID", "0"))
    if "SLURM_ARRAY_TASK_ID" in os.environ:
        name += "_" + os.environ["SLURM_ARRAY_TASK_ID"]
    (root / "env").mkdir(exist_ok=True)
    seen = {k: os.environ.get(k) for k in (*THREAD_VARS, "SLURM_CPUS_PER_TASK")}
    (root / "env" / f"{name}.json").write_text(json.dumps(seen))
    handles = []
    for key in ("--output", "--error"):
        if files[key]:
            Path(files[key]).parent.mkdir(parents=True, exist_ok=True)
            handles.append(open(files[key], "ab"))
        else:
            handles.append(None)
    try:
        return subprocess.run(command, stdout=handles[0], stderr=handles[1]).returncode
    finally:
        for h in handles:
            if h:
                h.close()


def sacct(args: list[str]) -> int:
    wanted = [args[i + 1] for i, a in enumerate(args[:-1]) if a == "-j"]
    print("JobID|State|NodeList")
    state_dir = _root() / "state"
    for path in sorted(state_dir.glob("*")) if state_dir.exists() else []:
        if path.name.split("_")[0] in wanted:
            print(f"{path.name}|{path.read_text()}|localhost")
    return 0


def main(command: str, args: list[str]) -> int:
    if command == "sbatch":
        return sbatch(args)
    if command == "srun":
        return srun(args)
    if command == "sacct":
        return sacct(args)
    return 0  # scancel: nothing to cancel here


if __name__ == "__main__" and len(sys.argv) == 4 and sys.argv[1] == "--run":
    _run_array(sys.argv[2], sys.argv[3])
