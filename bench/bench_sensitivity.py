"""How long +experiment=requirement_sensitivity takes: one sweep per assumption variant, timed.

Runs ``python -m sphri -m +experiment=requirement_sensitivity
sensitivity=<variant>`` through the default launcher (joblib, 2 parallel jobs)
for each measured variant in turn, sharing one stage cache and MLflow store in
a temporary directory (as the whole study does: data and contact are computed
by the first variant's first job and loaded by every other job), and reads
each job's wall seconds from MLflow.

Full size (the default): the reference variant (ellipse encoder, 2 % noise,
no filter) and the coverage variant (the other encoder; its cost differs at
fine grids), each over the study's whole resolution list, on the full
synthetic study. The other variants change only noise and filter, which cost
about the same as the reference; the estimate of the whole study is therefore
``sum(measured) + reference_wall * (variants not measured)``, labelled
``estimated`` (it counts data and contact once more than needed, so it errs
long). ``--quick`` (what ``make bench`` runs) times the quick preset
(``requirement_sensitivity_quick``: debug sizes, 3 variants x 3 resolutions)
as one multirun. Writes ``outputs/bench/sensitivity.json``
(``sensitivity_quick.json``).

    python bench/bench_sensitivity.py [--quick] [--keep DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, write_json  # noqa: E402
from bench_sweep import ROOT, job_runs, timed  # noqa: E402

EXPERIMENT = ROOT / "conf" / "experiment" / "requirement_sensitivity.yaml"


def study_grid() -> tuple[list[str], str]:
    """(variants, resolution list) of the full study, as its YAML sweeps them."""
    params = yaml.safe_load(EXPERIMENT.read_text())["hydra"]["sweeper"]["params"]
    return str(params["sensitivity"]).split(","), str(params["layout.res"])


def run_variant(work: Path, experiment: str, variant: str | None, tag: str, timeout_s: float) -> dict[str, Any]:
    sweep = work / f"sweep_{tag}"
    cmd = [
        sys.executable,
        "-m",
        "sphri",
        "-m",
        f"+experiment={experiment}",
        f"output_dir={work}",
        f"hydra.sweep.dir={sweep}",
    ] + ([f"sensitivity={variant}"] if variant else [])
    wall = timed(cmd, work / f"{tag}.log", timeout_s)
    runs = job_runs(sweep)
    failed = [r["res"] for r in runs if r["status"] != "FINISHED"]
    if failed:
        raise RuntimeError(f"{tag}: jobs at res {failed} did not finish (log {work / f'{tag}.log'})")
    return {
        "wall_s": wall,
        "n_jobs": len(runs),
        "job_s": {str(r["res"]): r["job_s"] for r in runs},
        "accuracy": {str(r["res"]): r["accuracy_mean"] for r in runs},
        "slowest_job": max(runs, key=lambda r: r["job_s"] or 0)["res"],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the quick preset instead of full-size variants")
    parser.add_argument("--keep", default=None, help="work directory to keep (default: a temporary one)")
    args = parser.parse_args(argv)
    variants, resolutions = study_grid()
    with tempfile.TemporaryDirectory(prefix="sphri-bench-sens-") as tmp:
        work = Path(args.keep or tmp)
        work.mkdir(parents=True, exist_ok=True)
        result: dict[str, Any] = {"machine": machine(), "variants_in_study": variants, "resolutions": resolutions}
        if args.quick:
            result["quick_preset"] = run_variant(work, "requirement_sensitivity_quick", None, "quick", 1800)
            name = "sensitivity_quick"
        else:
            measured = {}
            for v in ("reference", "coverage"):
                print(f"== variant {v}: {resolutions}", flush=True)
                measured[v] = run_variant(work, "requirement_sensitivity", v, v, 4 * 3600)
                print(f"   {measured[v]['wall_s']:.0f} s for {measured[v]['n_jobs']} jobs", flush=True)
            rest = [v for v in variants if v not in measured]
            result["measured"] = measured
            result["estimated_study_s"] = sum(m["wall_s"] for m in measured.values()) + measured["reference"][
                "wall_s"
            ] * len(rest)
            result["estimate_note"] = (
                f"estimated: measured {sorted(measured)} + the reference's wall time for each of "
                f"{rest} (noise and filter variants cost about what the reference does)"
            )
            name = "sensitivity"
        result["machine_after"] = machine()
        path = write_json(name, result)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
