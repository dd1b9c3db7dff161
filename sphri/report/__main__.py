"""``python -m sphri.report``: the report of a finished sweep.

::

    python -m sphri.report outputs/sweeps/resolution_rf          # a sweep directory
    python -m sphri.report 3f2a...c9 output_dir=outputs          # a parent run id (store outputs/mlflow.db)
    python -m sphri.report DIR tolerance=0.02 n_boot=5000         # the sentence uses a 2-point tolerance
    python -m sphri.report DIR tolerances=se,2se,0.01,0.02        # the tolerances shown side by side
    python -m sphri.report DIR out=DIR2 mlflow=false              # elsewhere, not logged to MLflow
    python -m sphri.report DIR marks=false                        # figures without the SYNTHETIC banner and ids
    python -m sphri.report DIR formats=png                        # PNG figures only (default png,pdf,svg)

Arguments are ``key=value`` as in every sphri command (``uri``, ``output_dir``,
``out``, ``tolerances``, ``tolerance``, ``n_boot``, ``ci``, ``seed``,
``marks=auto|true|false``, ``formats=png,pdf,svg``, ``mlflow=true|false``); the ``--key value`` spellings are accepted too.

Writes ``DIR/report/`` (report.html, figures as PNG + PDF + SVG, summary.txt, CSV/JSON
tables), logs it to the sweep's MLflow parent run and prints the summary.
Exits 2 with a message when the sweep cannot be reported on.
"""

from __future__ import annotations

import argparse
import logging
import sys

from sphri.errors import clean_errors
from sphri.report.analysis import RuleSettings
from sphri.report.build import check_formats, make_report
from sphri.report.saturation import Tolerance
from sphri.report.sweep import ReportError

#: ``key=value`` arguments and the option each one stands for.
KEYS = {
    "uri": "--uri",
    "output_dir": "--output-dir",
    "out": "--out",
    "tolerances": "--tolerances",
    "tolerance": "--tolerance",
    "n_boot": "--n-boot",
    "ci": "--ci",
    "seed": "--seed",
    "marks": "--marks",
    "formats": "--formats",
}


def from_key_values(argv: list[str]) -> list[str]:
    """``key=value`` (sphri's style) -> argparse options; ``mlflow=false`` -> ``--no-log``."""
    out = []
    for a in argv:
        key, eq, value = a.partition("=")
        if a.startswith("-") or not eq:
            out.append(a)
        elif key in KEYS:
            out += [KEYS[key], value]
        elif key == "mlflow":
            if value.lower() not in ("true", "false"):
                raise SystemExit(f"sphri.report: mlflow={value} is invalid: must be true or false")
            out += [] if value.lower() == "true" else ["--no-log"]
        else:
            raise SystemExit(f"sphri.report: unknown argument {key!r}: expected one of {', '.join([*KEYS, 'mlflow'])}")
    return out


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        prog="python -m sphri.report",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", help="sweep directory (holding mlflow_parent_run.json) or the parent MLflow run id")
    p.add_argument(
        "--uri", default=None, help="MLflow tracking URI (default: the sweep's, else sqlite:///<output-dir>/mlflow.db)"
    )
    p.add_argument(
        "--output-dir", default="outputs", help="the runs' output_dir, for the default store (default: outputs)"
    )
    p.add_argument("--out", default=None, help="where to write the report (default: <sweep dir>/report)")
    p.add_argument(
        "--tolerances",
        default="se,0.01,0.02",
        help="tolerances of the paired rule shown side by side: se (one paired standard error), 2se, "
        "or accuracy units (0.01 = 1 point); default se,0.01,0.02",
    )
    p.add_argument(
        "--tolerance",
        default="0.01",
        help="the tolerance the requirement sentence uses (added to --tolerances if missing; default 0.01)",
    )
    p.add_argument("--n-boot", type=int, default=2000, help="participant bootstrap resamples (default 2000)")
    p.add_argument("--ci", type=float, default=0.95, help="interval coverage (default 0.95)")
    p.add_argument("--seed", type=int, default=0, help="bootstrap seed (default 0)")
    p.add_argument("--no-log", action="store_true", help="do not log the report to the MLflow parent run")
    p.add_argument(
        "--marks",
        default="auto",
        choices=("auto", "true", "false"),
        help="the SYNTHETIC DATA banner and sweep id on the figures: auto (for synthetic runs), true, false",
    )
    p.add_argument(
        "--formats",
        default="png,pdf,svg",
        help="figure file formats, comma-separated, png included (default png,pdf,svg)",
    )
    args = p.parse_args(from_key_values(list(sys.argv[1:] if argv is None else argv)))
    for name, ok, expected in (("--n-boot", args.n_boot >= 0, ">= 0"), ("--ci", 0 < args.ci < 1, "in (0, 1)")):
        if not ok:
            p.error(f"{name}={getattr(args, name[2:].replace('-', '_'))} is invalid: must be {expected}")
    try:
        names = [Tolerance.parse(t).name for t in args.tolerances.split(",") if t.strip()]
        primary = Tolerance.parse(args.tolerance).name
    except ValueError as exc:
        p.error(str(exc))
    try:
        args.formats = check_formats(args.formats.split(","))
    except ValueError as exc:
        p.error(str(exc))
    if primary not in names:
        names.append(primary)
    args.rule = RuleSettings(tolerances=tuple(names), primary=primary, n_boot=args.n_boot, ci=args.ci, seed=args.seed)
    return args


@clean_errors("sphri.report")
def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    rule = args.rule
    try:
        _, files, text = make_report(
            args.source,
            uri=args.uri,
            output_dir=args.output_dir,
            out_dir=args.out,
            rule=rule,
            log_to_mlflow=not args.no_log,
            marks={"auto": None, "true": True, "false": False}[args.marks],
            formats=args.formats,
        )
    except (ReportError, ValueError) as exc:
        print(f"sphri.report: {exc}", file=sys.stderr)
        return 2
    print(text)
    if files.logged_to:
        print(f"logged to MLflow parent run {files.logged_to} (artifacts under report/)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
