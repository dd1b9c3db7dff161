"""Profile: where the test suite's CPU time goes, by kind of work, by process and by test.

The suite (``make test``: ``pytest -m "not slow" -n 2 --dist loadscope``) runs under py-spy, sampling
every process it starts (pytest's workers, the processes forked for CLI tests, subprocesses, loky
workers of parallel sweeps) ``--rate`` times a second, without pausing them (``--nonblocking``);
the samples of busy threads are its CPU time. Each sample is then given to:

* a **kind of work** (:data:`KINDS`, the first that matches its stack, in that order): Hydra's
  composition of a config, imports, CNN-GRU training, figure files, and so on;
* a **process kind**: a pytest worker itself, a forked CLI child (``tests/forked_cli.py``), a loky
  worker, any other process (named by its command line);
* the **test** whose call stack it is in (the outermost frame of a ``test_*.py`` or ``conftest.py``;
  work in another process is not traced back to its test);
* an **origin** within its kind and process: the innermost sphri or test frame that leads into the
  kind's work (which sphri call composes, which test imports), and for an import the module imported.

Writes ``outputs/bench/suite_profile.json`` and ``suite_profile.md`` (``--out`` another folder) (CPU model and flags, rate,
samples, wall time, and the four tables). ``--stacks FILE`` analyses a collapsed-stack file that
py-spy wrote before (``--format raw``) instead of running the suite; ``--wall S`` then gives the
run's wall time. Needs py-spy (``pip install py-spy``) only to run the suite.

    python bench/profile_suite.py [--rate 10] [--workers 2] [-- PYTEST_ARGS...]
    python bench/profile_suite.py --stacks prof.txt --wall 929
"""

from __future__ import annotations

import argparse
import collections
import json
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterable
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent

#: Kinds of work: (name, substrings of which one in a frame of the stack makes it that kind). A sample
#: goes to the first kind that matches, in this order (a CNN-GRU fit inside an import is an import).
KINDS: list[tuple[str, tuple[str, ...]]] = [
    (
        "Hydra composition",
        ("ConfigLoaderImpl.load_configuration (", "ConfigLoaderImpl.load_sweep_config ("),
    ),
    ("imports", ("_find_and_load (<frozen importlib._bootstrap>",)),
    ("CNN-GRU training and prediction", ("CnnGru.fit (", "CnnGru.predict_proba (")),
    ("figure files", ("save (sphri/figures.py", "savefig (")),
    ("MLflow tracking", ("(mlflow/",)),
    ("stage computations (pipeline)", ("Pipeline.get (",)),
    ("model fits (other)", (".fit (sklearn/", "run_fold (sphri/evaluate/cv.py")),
    ("reports", ("(sphri/report/",)),
    ("config checks, docs and component building", ("(sphri/config.py", "(hydra/_internal/instantiate/")),
    ("coverage analysis and statistics", ("(sphri/analysis/", "(sphri/coverage.py")),
    ("sessions and the scenario study", ("(sphri/sessions/",)),
    ("hardware simulators and serial I/O", ("(sphri/hardware/",)),
    (
        "geometry, robots, contact, surfaces, layouts",
        ("(sphri/geometry/", "(sphri/robots/", "(sphri/contact/", "(sphri/surface/", "(sphri/layout/"),
    ),
    ("data files and synthesis", ("(sphri/data/",)),
    ("pytest's collection of the tests", ("pytest_collection (",)),
]
OTHER = "other"

_PROCESS = re.compile(r'^process \d+:"(.*?)"?$')
_LINE_NO = re.compile(r":\d+\)$")
_OWN_FRAME = re.compile(r"\((?:sphri/|(?:[\w/]+/)?(?:test_\w+|conftest)\.py)")
_TEST_FRAME = re.compile(r"^(\w+) \(((?:[\w/]+/)?(?:test_\w+|conftest)\.py)(?::\d+)?\)$")


def parse(lines: Iterable[str]) -> Iterable[tuple[list[str], int]]:
    """``(frames outermost first, samples)`` per line of py-spy's raw format (``frame;frame;... N``);
    a line that does not end in a count (an empty one, a truncated last line) is skipped."""
    for line in lines:
        stack, _, count = line.rstrip("\n").rpartition(" ")
        if not stack or not count.isdigit():
            continue
        yield stack.split(";"), int(count)


def kind_of(code: list[str]) -> str:
    """The kind of work of one stack's code frames (:data:`KINDS`, else ``other``)."""
    for name, marks in KINDS:
        if any(mark in frame for frame in code for mark in marks):
            return name
    return OTHER


def process_of(command: str, code: list[str]) -> str:
    """The process kind of a stack, from its innermost process's ``command`` line and its ``code`` frames:
    pytest worker, forked CLI child, loky worker, or that command line (numbers of three or more digits
    written N, so that runs with other temporary folders and ports fall together)."""
    frames = ";".join(code)
    if "popen_loky_posix" in command:
        return "loky worker (parallel sweep or folds)"
    if "_child (forked_cli.py" in frames:
        return "forked CLI child (tests/forked_cli.py)"
    if "(xdist/remote.py" in frames:
        return "pytest worker (tests in process)"
    command = re.sub(r"/tmp/pytest-of-\w+/\S*", "TMP", command)
    return re.sub(r"\d{3,}", "N", command)[:100]


def test_of(code: list[str]) -> str:
    """``file::function`` of the outermost test or conftest frame, else ``(not in a test's own process)``."""
    for frame in code:
        if m := _TEST_FRAME.match(frame):
            return f"{Path(m.group(2)).name}::{m.group(1)}"
    return "(not in a test's own process)"


def origin_of(kind: str, code: list[str]) -> str:
    """Where a sample of ``kind`` comes from: the innermost sphri or test frame before the first frame that
    made it that kind (``?`` where none), and for an import ``-> <module> (the file imported)``."""
    marks = dict(KINDS).get(kind, ())
    at = next((i for i, f in enumerate(code) if any(m in f for m in marks)), len(code))
    caller = next((f for f in reversed(code[:at]) if _OWN_FRAME.search(f)), "?")
    if kind == "imports":
        return f"{caller} -> {next((f for f in code[at:] if f.startswith('<module> (')), '?')}"
    return caller


def profile(lines: Iterable[str], rate_hz: float) -> dict:
    """Samples and CPU seconds (samples / rate) per kind, per process kind and per test. py-spy names each
    process of a stack as a pseudo-frame (``process N:"command line"``); only the innermost one's command
    line says what a stack is, and only the code frames are matched (an outer command may name anything,
    a test file ``test_forked_cli.py`` for one)."""
    kinds: collections.Counter[str] = collections.Counter()
    procs: collections.Counter[str] = collections.Counter()
    tests: collections.Counter[str] = collections.Counter()
    origins: collections.Counter[str] = collections.Counter()
    total = 0
    for frames, n in parse(lines):
        commands = [m.group(1) for f in frames if (m := _PROCESS.match(f))]
        code = [_LINE_NO.sub(")", f) for f in frames if not f.startswith("process ")]
        total += n
        kind, process = kind_of(code), process_of(commands[-1] if commands else "?", code)
        kinds[kind] += n
        procs[process] += n
        tests[test_of(code)] += n
        origins[f"{kind} · {process} · {origin_of(kind, code)}"] += n

    def table(counter: collections.Counter[str], top: int) -> list[dict]:
        return [
            {"name": k, "samples": v, "cpu_s": v / rate_hz, "share": v / total if total else 0.0}
            for k, v in counter.most_common(top)
        ]

    return {
        "samples": total,
        "rate_hz": rate_hz,
        "cpu_s": total / rate_hz,
        "kinds": table(kinds, len(kinds)),
        "processes": table(procs, 15),
        "tests": table(tests, 25),
        "origins": table(origins, 50),
    }


def markdown(result: dict) -> str:
    m = result.get("machine", {})
    lines = [
        "# Where the test suite's CPU time goes",
        "",
        f"Machine: {m.get('cpu_model', '?')}, {m.get('cpu_count', '?')} cores; SIMD flags: {m.get('cpu_flags', '?')}.",
        f"Command: `{result.get('command', '?')}`; wall {result.get('wall_s', float('nan')):.0f} s.",
        f"py-spy at {result['rate_hz']:g} Hz: {result['samples']} samples = {result['cpu_s']:.0f} CPU s.",
        "",
    ]
    for key, title in (
        ("kinds", "Kind of work (each sample in the first kind that matches, in this order)"),
        ("processes", "Process"),
        ("tests", "Test (work in its own process)"),
        ("origins", "Origin (kind · process · the innermost sphri or test frame leading into it; an import's module)"),
    ):
        lines += [f"## {title}", "", "| | CPU s | share |", "|---|---:|---:|"]
        lines += [f"| {r['name']} | {r['cpu_s']:.0f} | {100 * r['share']:.1f} % |" for r in result[key]]
        lines.append("")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rate", type=float, default=10.0, help="samples per second (default 10)")
    parser.add_argument("--workers", default="2", help="pytest-xdist workers (default 2, as on CI's 2 cores)")
    parser.add_argument("--stacks", type=Path, help="analyse this py-spy raw file instead of running the suite")
    parser.add_argument("--wall", type=float, default=float("nan"), help="with --stacks: the run's wall seconds")
    parser.add_argument("--out", type=Path, default=REPO / "outputs" / "bench", help="folder of the results")
    parser.add_argument("pytest_args", nargs="*", help="after --: more pytest arguments")
    args = parser.parse_args()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    pytest_cmd = [sys.executable, "-m", "pytest", "-m", "not slow", "-q", "-n", args.workers]
    pytest_cmd += ["--dist", "loadscope", "--no-loadscope-reorder", *args.pytest_args]
    if args.stacks is not None:
        if not args.stacks.is_file():
            print(f"profile_suite: --stacks {args.stacks}: no such file", file=sys.stderr)
            return 2
        stacks, wall, command = args.stacks, args.wall, f"(from {args.stacks})"
    else:
        spy = shutil.which("py-spy") or shutil.which("py-spy", path=str(Path(sys.executable).parent))
        if spy is None:
            print("profile_suite: needs py-spy on PATH (pip install py-spy)", file=sys.stderr)
            return 2
        # written under another name first: an earlier run's stacks are replaced only by a complete file
        partial, stacks = out / "suite_profile.stacks.partial.txt", out / "suite_profile.stacks.txt"
        partial.unlink(missing_ok=True)
        cmd = [spy, "record", "--nonblocking", "--subprocesses", "--format", "raw", "-r", f"{args.rate:g}"]
        cmd += ["-o", str(partial), "--", *pytest_cmd]
        t0 = time.perf_counter()
        code = subprocess.run(cmd, cwd=REPO).returncode
        wall, command = time.perf_counter() - t0, " ".join(pytest_cmd[1:])
        if not partial.is_file():
            print(f"profile_suite: py-spy wrote no samples (exit {code}); see its message above", file=sys.stderr)
            return 1
        partial.replace(stacks)
    sys.path.insert(0, str(HERE))
    from _common import machine

    with stacks.open() as f:
        result = profile(f, args.rate)
    result.update(machine=machine(), wall_s=wall, command=command)
    (out / "suite_profile.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "suite_profile.md").write_text(markdown(result) + "\n")
    print(markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
