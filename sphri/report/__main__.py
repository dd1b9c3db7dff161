"""``python -m sphri.report``: the report of a finished sweep.

::

    python -m sphri.report outputs/sweeps/resolution_rf          # a sweep directory
    python -m sphri.report 3f2a...c9 --output-dir outputs        # a parent run id (store outputs/mlflow.db)
    python -m sphri.report DIR --tolerance 0.02 --n-boot 5000     # a fixed tolerance instead of one SE

Writes ``DIR/report/`` (report.html, PNG figures, summary.txt, CSV/JSON
tables), logs it to the sweep's MLflow parent run and prints the summary.
Exits 2 with a message when the sweep cannot be reported on.
"""

from __future__ import annotations

import argparse
import logging
import sys

from sphri.errors import clean_errors
from sphri.report.analysis import RuleSettings
from sphri.report.build import make_report
from sphri.report.sweep import ReportError


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m sphri.report", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source", help="sweep directory (holding mlflow_parent_run.json) or the parent MLflow run id")
    p.add_argument("--uri", default=None, help="MLflow tracking URI (default: the sweep's, else sqlite:///<output-dir>/mlflow.db)")
    p.add_argument("--output-dir", default="outputs", help="the runs' output_dir, for the default store (default: outputs)")
    p.add_argument("--out", default=None, help="where to write the report (default: <sweep dir>/report)")
    p.add_argument("--n-se", type=float, default=1.0, help="tolerance in standard errors of the best mean (default 1)")
    p.add_argument("--tolerance", type=float, default=None, help="fixed tolerance in accuracy units instead of --n-se")
    p.add_argument("--n-boot", type=int, default=2000, help="participant bootstrap resamples (default 2000)")
    p.add_argument("--ci", type=float, default=0.95, help="interval coverage (default 0.95)")
    p.add_argument("--seed", type=int, default=0, help="bootstrap seed (default 0)")
    p.add_argument("--no-log", action="store_true", help="do not log the report to the MLflow parent run")
    args = p.parse_args(argv)
    for name, ok, expected in (("--n-se", args.n_se >= 0, ">= 0"), ("--n-boot", args.n_boot >= 0, ">= 0"),
                               ("--ci", 0 < args.ci < 1, "in (0, 1)"),
                               ("--tolerance", args.tolerance is None or args.tolerance >= 0, ">= 0")):
        if not ok:
            p.error(f"{name}={getattr(args, name[2:].replace('-', '_'))} is invalid: must be {expected}")
    return args


@clean_errors("sphri.report")
def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    rule = RuleSettings(n_se=args.n_se, tolerance=args.tolerance, n_boot=args.n_boot, ci=args.ci, seed=args.seed)
    try:
        _, files, text = make_report(args.source, uri=args.uri, output_dir=args.output_dir, out_dir=args.out,
                                     rule=rule, log_to_mlflow=not args.no_log)
    except (ReportError, ValueError) as exc:
        print(f"sphri.report: {exc}", file=sys.stderr)
        return 2
    print(text)
    if files.logged_to:
        print(f"logged to MLflow parent run {files.logged_to} (artifacts under report/)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
