"""Run every benchmark in bench/ and write outputs/bench/summary.md.

Each ``bench/bench_*.py`` is run in its own process (so one failing or slow
benchmark cannot take the others down) and writes ``outputs/bench/<name>.json``
(and plots). This script then collects the JSON files into one Markdown
table of their headline numbers. Absolute times vary between machines: read
the ratios each benchmark reports against its own baseline, measured in the
same run.

    python bench/run_all.py            # every benchmark, quick sizes where they have them
    python bench/run_all.py --full     # full sizes (slower)
    python bench/run_all.py contact    # only bench_contact.py
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "outputs" / "bench"


def headline(data: dict, prefix: str = "", depth: int = 0) -> list[tuple[str, str]]:
    """Scalar entries of a benchmark's JSON (nested dicts flattened two levels deep)."""
    rows = []
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict) and depth < 2:
            rows += headline(value, name + ".", depth + 1)
        elif isinstance(value, (int, float, str, bool)):
            text = f"{value:.4g}" if isinstance(value, float) else str(value)
            if len(text) <= 80:
                rows.append((name, text))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("only", nargs="*", help="benchmark names (bench_<name>.py) to run")
    parser.add_argument("--full", action="store_true", help="full sizes instead of --quick")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    scripts = sorted(HERE.glob("bench_*.py"))
    if args.only:
        scripts = [s for s in scripts if s.stem.removeprefix("bench_") in args.only]
    status = {}
    for script in scripts:
        cmd = [sys.executable, str(script)] + ([] if args.full else ["--quick"])
        print(f"== {script.name}: {' '.join(cmd[1:])}", flush=True)
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=HERE.parent)
        status[script.stem] = (proc.returncode, time.perf_counter() - t0)
    lines = [
        "# sphri benchmarks",
        "",
        f"Run: {time.strftime('%Y-%m-%d %H:%M')}, mode {'full' if args.full else 'quick'}.",
        "",
    ]
    lines += ["| benchmark | exit | wall s |", "| --- | --- | --- |"]
    lines += [f"| {name} | {rc} | {dt:.1f} |" for name, (rc, dt) in status.items()]
    for path in sorted(OUT.glob("*.json")):
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            lines += ["", f"## {path.stem}", "", f"unreadable: {exc}"]
            continue
        lines += ["", f"## {path.stem}", "", "| metric | value |", "| --- | --- |"]
        lines += [f"| {k} | {v} |" for k, v in headline(data)]
    (OUT / "summary.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT / 'summary.md'}")
    return 0 if all(rc == 0 for rc, _ in status.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
