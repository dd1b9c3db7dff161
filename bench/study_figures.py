"""Regenerate the whole-body study's figures in the docs from a fresh full run (issue 50: figures regenerated).

    python bench/study_figures.py                 # runs the study (PNG, PDF, SVG; about 4-8 minutes on 2 cores)
    python bench/study_figures.py --from-run DIR  # copies the figures of a run already made with all three formats

The run is ``sphri coverage +experiment=scenario_study robot=reachy2 mlflow=false
'experiment.scenario_study.figure_formats=[png,pdf,svg]' out=DIR``; each of its figures below is copied to
``docs/figures/`` under the name the documentation uses, and ``outputs/bench/study_figures.json`` records the run
(date, machine, sessions version, command).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from _common import machine, write_json  # noqa: E402

#: The study's figure file (stem) -> the docs' name (stem), in docs/figures/.
FIGURES = {
    "maps_views": "scenario_maps_reachy2",
    "placement": "scenario_placement_reachy2",
    "budget_curve": "scenario_budget_curve_reachy2",
    "skin_design": "scenario_skin_reachy2",
    "swd_effects": "scenario_swd_reachy2",
}
FORMATS = ("png", "pdf", "svg")
COMMAND = [
    "-m",
    "sphri",
    "coverage",
    "+experiment=scenario_study",
    "robot=reachy2",
    "mlflow=false",
    "experiment.scenario_study.figure_formats=[png,pdf,svg]",
]


def copy(run: Path, dest: Path) -> list[str]:
    """Copy the run's figures to ``dest`` under the docs' names; refuses a run missing any of them."""
    missing = [f"{s}.{x}" for s in FIGURES for x in FORMATS if not (run / f"{s}.{x}").is_file()]
    if missing:
        raise SystemExit(f"{run}: missing {', '.join(missing)} (run with figure_formats=[png,pdf,svg])")
    written = []
    for stem, name in FIGURES.items():
        for fmt in FORMATS:
            shutil.copyfile(run / f"{stem}.{fmt}", dest / f"{name}.{fmt}")
            written.append(f"{name}.{fmt}")
    return written


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from-run", type=Path, help="a study output directory made with all three figure formats")
    args = ap.parse_args()
    dest = ROOT / "docs" / "figures"
    with tempfile.TemporaryDirectory() as tmp:
        run = args.from_run
        if run is None:
            run = Path(tmp) / "out"
            subprocess.run([sys.executable, *COMMAND, f"out={run}"], cwd=ROOT, check=True)
        summary = json.loads((run / "summary.json").read_text())
        written = copy(run, dest)
    from sphri.sessions.synthetic import SyntheticSessions

    record = {
        "what": "the whole-body study's figures in docs/figures (bench/study_figures.py)",
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": "python " + " ".join(COMMAND) + " out=DIR",
        "sessions_version": SyntheticSessions.VERSION,
        "n_sessions": summary["n_sessions"],
        "n_coded_episodes": summary["n_coded_episodes"],
        "files": written,
    }
    print(f"{len(written)} files -> {dest}; {write_json('study_figures', record)}")


if __name__ == "__main__":
    main()
