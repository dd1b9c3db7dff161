"""``sphri report``: the report of a finished sweep.

::

    sphri report outputs/sweeps/resolution_rf          # a sweep directory
    sphri report 3f2a...c9 output_dir=outputs          # a parent run id (store outputs/mlflow.db)
    sphri report DIR tolerance=0.02 n_boot=5000         # the sentence uses a 2-point tolerance
    sphri report DIR tolerances=0.01,0.02,0.05          # the tolerances shown side by side
    sphri report DIR out=DIR2 mlflow=false              # elsewhere, not logged to MLflow
    sphri report DIR marks=false                        # figures without the SYNTHETIC banner and ids
    sphri report DIR formats=png                        # PNG figures only (default png,pdf,svg)
    sphri report DIR group_by=model                     # one curve per model (none: one curve)

Arguments are ``key=value`` as in every sphri command (:class:`ReportArgs`: ``uri``, ``output_dir``,
``out``, ``tolerances``, ``tolerance``, ``n_boot``, ``ci``, ``seed``, ``marks=auto|true|false``,
``formats=png,pdf,svg``, ``mlflow=true|false``, ``group_by``); the ``--key value`` spellings
(``--n-boot 100``, ``--no-log``) are accepted too.

Writes ``DIR/report/`` (report.html, figures as PNG + PDF + SVG, summary.txt, CSV/JSON
tables), logs it to the sweep's MLflow parent run and prints the summary.
Exits 2 with a message when the sweep cannot be reported on.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import Literal

from sphri.args import ArgsError, arg
from sphri.limits import over_limit
from sphri.report.analysis import RuleSettings
from sphri.report.build import check_formats, make_report
from sphri.report.saturation import Tolerance
from sphri.report.sweep import ReportError


def _tolerances(values: list[str]) -> None:
    for t in values:
        Tolerance.parse(t)  # a ValueError names the tolerance and the rule


#: Bytes the bootstrap keeps per resample (the selected resolution and its gap, ``sphri.report.saturation``).
BOOT_BYTES = 16


def _n_boot(n: int) -> str | None:
    if n < 0:
        return "must be >= 0"
    return over_limit(f"the bootstrap's {n} resamples ({BOOT_BYTES} bytes each, per tolerance)", float(n) * BOOT_BYTES)


def _formats(values: list[str]) -> None:
    check_formats(values)  # a ValueError names the formats and the rule


@dataclasses.dataclass
class ReportArgs:
    source: str = arg(
        positional=True, metavar="SOURCE", help="sweep directory (holding mlflow_parent_run.json) or the parent run id"
    )
    uri: str | None = arg(
        None, help="MLflow tracking URI (default: the sweep's, else sqlite:///<output_dir>/mlflow.db)"
    )
    output_dir: str = arg("outputs", help="the runs' output_dir, for the default store")
    out: str | None = arg(
        None,
        help="where to write the report: a new or empty folder, or an earlier report's (default: <sweep dir>/report)",
    )
    tolerances: list[str] = arg(
        ["0.01", "0.02", "0.03"],
        check=_tolerances,
        help="tolerances shown side by side, in accuracy units (0.01 = 1 point); each is raised to the smallest "
        "tolerance the study can certify when that is larger",
    )
    tolerance: str = arg(
        "0.01",
        check=lambda t: _tolerances([t]),
        help="the tolerance the requirement sentence asks for (added to tolerances)",
    )
    n_boot: int = arg(2000, check=_n_boot, help="participant bootstrap resamples")
    ci: float = arg(0.95, check=lambda c: None if 0 < c < 1 else "must be in (0, 1)", help="interval coverage")
    seed: int = arg(0, help="bootstrap seed")
    mlflow: bool = arg(True, flags={"--no-log": "false"}, help="log the report to the sweep's MLflow parent run")
    marks: Literal["auto", "true", "false"] = arg(
        "auto", help="the SYNTHETIC DATA banner and sweep id on the figures: auto (for synthetic runs), true, false"
    )
    formats: list[str] = arg(
        ["png", "pdf", "svg"], check=_formats, help="figure file formats, png included (the HTML page shows the PNGs)"
    )
    group_by: list[str] = arg(
        [],
        help="the params whose values make the curves (group_by=model, group_by=robot,model; none: one curve); "
        "default: the params the sweep varies that can change a result",
    )

    @property
    def rule(self) -> RuleSettings:
        names = [Tolerance.parse(t).name for t in self.tolerances]
        primary = Tolerance.parse(self.tolerance).name
        if primary not in names:
            names.append(primary)
        return RuleSettings(tolerances=tuple(names), primary=primary, n_boot=self.n_boot, ci=self.ci, seed=self.seed)


def check_report_folder(out: Path) -> None:
    """``out`` is absent, empty or an earlier report's folder (its ``report.html`` there): the report is logged to
    MLflow as the whole folder, so a folder of other files would be uploaded with it (:class:`ArgsError`)."""
    if out.is_dir() and any(out.iterdir()) and not (out / "report.html").is_file():
        raise ArgsError(
            f"out={out} is invalid: {out} holds files and no earlier report (report.html); the report is logged to "
            "MLflow as the whole folder: give a new or empty folder"
        )


def command(args: ReportArgs) -> int:
    """Write SOURCE/report/ (report.html, figures, summary.txt, CSV/JSON tables), log it to the sweep's
    MLflow parent run and print the summary; exit 2 with a message when the sweep cannot be reported on."""
    logging.basicConfig(level=logging.WARNING)
    if args.out:
        from sphri.config import ConfigError, check_output_dir

        try:  # before reading the sweep: a file in the way is one line, exit 2
            check_output_dir(args.out, key="out")
        except ConfigError as exc:
            raise ArgsError(str(exc)) from None
        check_report_folder(Path(args.out))
    try:
        _, files, text = make_report(
            args.source,
            uri=args.uri,
            output_dir=args.output_dir,
            out_dir=args.out,
            rule=args.rule,
            log_to_mlflow=args.mlflow,
            marks={"auto": None, "true": True, "false": False}[args.marks],
            formats=check_formats(args.formats),
            group_by=args.group_by or None,
        )
    except (ReportError, ValueError) as exc:  # no sweep there, or one that cannot be reported on: exit 2
        raise ArgsError(str(exc)) from None
    print(text)
    if files.logged_to:
        print(f"logged to MLflow parent run {files.logged_to} (artifacts under report/)")
    return 0
