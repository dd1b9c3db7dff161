"""The sweep report: from a resolution sweep to "this skin needs a taxel every N mm".

``sphri report SWEEP_DIR`` (or a parent run id) reads the sweep's
MLflow runs and writes ``SWEEP_DIR/report/``: a self-contained
``report.html`` (figures embedded), the PNG figures, ``summary.txt``,
``saturation.csv``/``saturation.json``/``points.csv``; it logs them to the
sweep's parent run. The requirement rule and its bootstrap are pure
functions in :mod:`sphri.report.saturation` (:func:`certified_saturation`); a sweep over the false-on rate also gets
``requirement_map.csv`` and its figure (:mod:`sphri.report.reqmap`).
"""

from sphri.report.analysis import RuleSettings, SweepReport, analyze
from sphri.report.build import ReportFiles, make_report
from sphri.report.saturation import (
    Certificate,
    RerunNoise,
    Saturation,
    Tolerance,
    certified_saturation,
    curve_stats,
    physical_interval,
)
from sphri.report.sweep import ReportError, Sweep, load_sweep

__all__ = [
    "Certificate",
    "RerunNoise",
    "ReportError",
    "ReportFiles",
    "RuleSettings",
    "Saturation",
    "Sweep",
    "SweepReport",
    "analyze",
    "Tolerance",
    "curve_stats",
    "certified_saturation",
    "load_sweep",
    "make_report",
    "physical_interval",
]
