"""Write a sweep's report: HTML, PNG figures, text and tables in ``<sweep_dir>/report/``,
logged to the sweep's MLflow parent run.

:func:`make_report` is what ``sphri report`` runs: load the sweep
(:mod:`sphri.report.sweep`), analyse it (:mod:`sphri.report.analysis`),
draw (:mod:`sphri.report.figures`), render (:mod:`sphri.report.render`),
then log the folder to the parent run under ``report/``, set the parent's
description (``mlflow.note.content``) to the text summary, its
``sphri.synthetic`` tag, and one metric per group and number of the
saturation point (``saturation/<group>/pitch_mm`` ...).
"""

from __future__ import annotations

import json
import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri.report.analysis import RuleSettings, SweepReport, analyze
from sphri.report.compute import COLUMNS as COMPUTE_COLUMNS
from sphri.report.compute import compute_rows
from sphri.report.figures import plot_bootstrap, plot_curves, plot_recall, plot_tornado
from sphri.report.render import comparison_rows, render_html, render_text, sensitivity_rows, tolerance_rows
from sphri.report.reqmap import filter_rows, map_rows, plot_filter_map, plot_map
from sphri.report.sweep import ReportError, Sweep, load_sweep

log = logging.getLogger(__name__)


#: Figure files the report writes (besides ``confusion_<group>.png``).
#: Formats of every figure (:data:`sphri.figures.FORMATS`).
FIGURE_FORMATS = ("png", "pdf", "svg")
FIGURE_FILES = (
    "accuracy_vs_resolution.png",
    "recall_vs_resolution.png",
    "saturation_bootstrap.png",
    "sensitivity_tornado.png",
    "requirement_map.png",
    "filter_map.png",
)


@dataclass
class ReportFiles:
    """Where the report was written."""

    out_dir: Path
    html: Path
    text: Path
    figures: dict[str, Path]
    confusions: dict[str, Path]
    tables: dict[str, Path]
    logged_to: str | None
    """Parent run id the report was logged to (None when not logged)."""


def slug(label: str) -> str:
    """A file- and MLflow-safe name for a group label."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", label).strip("_") or "all"


def check_formats(formats: Sequence[str]) -> tuple[str, ...]:
    """The report's figure formats, checked: a non-empty subset of :data:`FIGURE_FORMATS` holding ``png``
    (the HTML page shows the PNGs)."""
    formats = tuple(dict.fromkeys(str(f).strip().lower() for f in formats))
    bad = [f for f in formats if f not in FIGURE_FORMATS]
    if bad or "png" not in formats:
        raise ValueError(
            f"formats={','.join(formats)} is invalid: choose from {','.join(FIGURE_FORMATS)}, "
            f"png included (the HTML page shows the PNGs)"
        )
    return formats


def _confusions(
    sweep: Sweep, report: SweepReport, out_dir: Path, marks: bool | None, formats: Sequence[str] = FIGURE_FORMATS
) -> dict[str, Path]:
    """Each group's confusion matrix at its saturation point, redrawn from that job's ``confusion.csv`` under
    the report's own marks (PNG, PDF, SVG); a run logged before that file existed gives its images as logged."""
    import shutil
    import tempfile

    from mlflow.tracking import MlflowClient

    from sphri.figures import Provenance
    from sphri.tracking.artifacts import draw_confusion

    client = MlflowClient(tracking_uri=sweep.uri)
    out = {}
    for g in report.groups:
        run_id = g.recommended["run_id"]
        dst = out_dir / f"confusion_{slug(g.label)}.png"
        with tempfile.TemporaryDirectory(prefix="sphri-report-") as tmp:
            try:
                counts = pd.read_csv(client.download_artifacts(run_id, "confusion.csv", tmp), index_col=0)
            except Exception:  # artifacts disabled for the job, or a run from before confusion.csv
                counts = None
            if counts is not None:
                prov = Provenance(
                    synthetic=bool(g.context["synthetic"]), ids=f"sweep {report.sweep.sweep_id}", show=marks
                )
                draw_confusion(
                    counts.to_numpy(float),
                    [str(c) for c in counts.columns],
                    dst,
                    f"{g.label} at {int(g.recommended['res'])} taxels along the link",
                    prov,
                    formats=formats,
                )
                out[g.label] = dst
                continue
            for fmt in formats:
                try:
                    src = client.download_artifacts(run_id, f"confusion.{fmt}", tmp)
                except Exception as exc:
                    report.notes.append(
                        f"{g.label}: no confusion.{fmt} artifact (nor confusion.csv) in run {run_id} "
                        f"({type(exc).__name__})"
                    )
                    continue
                shutil.copyfile(src, dst.with_suffix("." + fmt))
        if dst.exists():
            out[g.label] = dst
    return out


def write_report(
    report: SweepReport, out_dir: Path, marks: bool | None = None, formats: Sequence[str] = FIGURE_FORMATS
) -> ReportFiles:
    """Figures (``formats``: PNG, PDF, SVG by default), confusion matrices, tables, HTML and text of ``report``
    into ``out_dir``.

    ``marks``: the SYNTHETIC banner and sweep id on the figures (None: only for synthetic runs)."""
    from sphri.figures import only_formats

    formats = check_formats(formats)
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in FIGURE_FILES:  # figures of an earlier report that may not be redrawn (all formats)
        for fmt in FIGURE_FORMATS:
            (out_dir / name).with_suffix("." + fmt).unlink(missing_ok=True)
    for fmt in FIGURE_FORMATS:
        for old in out_dir.glob(f"confusion_*.{fmt}"):
            old.unlink()
    with only_formats(formats):
        figures = {"curves": plot_curves(report, out_dir / "accuracy_vs_resolution.png", marks=marks)}
        for name, fig in (
            ("recall", plot_recall(report, out_dir / "recall_vs_resolution.png", marks=marks)),
            ("bootstrap", plot_bootstrap(report, out_dir / "saturation_bootstrap.png", marks=marks)),
            ("tornado", plot_tornado(report, out_dir / "sensitivity_tornado.png", marks=marks)),
            ("map", plot_map(report, out_dir / "requirement_map.png", marks=marks)),
            ("filter_map", plot_filter_map(report, out_dir / "filter_map.png", marks=marks)),
        ):
            if fig is not None:
                figures[name] = fig
    confusions = _confusions(report.sweep, report, out_dir, marks, formats)

    points = pd.concat(
        [
            g.points.assign(saturation=np.arange(len(g.points)) == g.sat.index, synthetic=bool(g.context["synthetic"]))
            for g in report.groups
        ],
        ignore_index=True,
    )
    points.insert(0, "group", [g.label for g in report.groups for _ in range(len(g.points))])
    # an optional table without rows is not written, and an earlier report's copy of it is removed
    frames = {
        "comparison": ("saturation.csv", pd.DataFrame(comparison_rows(report))),
        "tolerances": ("tolerances.csv", pd.DataFrame(tolerance_rows(report))),
        "sensitivity": ("sensitivity.csv", pd.DataFrame(sensitivity_rows(report)) if report.sensitivity else None),
        "requirement_map": ("requirement_map.csv", pd.DataFrame(map_rows(report)) if report.maps else None),
        "filter_pairs": ("filter_pairs.csv", pd.DataFrame(pairs) if (pairs := filter_rows(report)) else None),
        "compute": ("compute.csv", pd.DataFrame(compute_rows(report.sweep), columns=COMPUTE_COLUMNS)),
        "points": ("points.csv", points),
    }
    tables = {}
    for key, (name, frame) in frames.items():
        if frame is None:
            (out_dir / name).unlink(missing_ok=True)
        else:
            tables[key] = out_dir / name
            frame.to_csv(tables[key], index=False, float_format="%.6g")
    tables["json"] = out_dir / "saturation.json"
    tables["json"].write_text(json.dumps(_json(report), indent=2))

    html_path = out_dir / "report.html"
    html_path.write_text(render_html(report, figures, confusions), encoding="utf-8")
    text_path = out_dir / "summary.txt"
    text_path.write_text(render_text(report, html_path) + "\n", encoding="utf-8")
    return ReportFiles(out_dir, html_path, text_path, figures, confusions, tables, None)


def _plain(x: object) -> Any:
    """JSON-safe copy: numpy scalars and arrays to Python, non-finite floats to None."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    if x is None or isinstance(x, str):
        return x
    return str(x)


def _json(report: SweepReport) -> dict:
    return _plain(
        {
            "sweep_id": report.sweep.sweep_id,
            "parent_run_id": report.sweep.parent_id,
            "synthetic": report.synthetic,
            "rule": report.rule.describe(),
            "tolerances": list(report.rule.tolerances),
            "primary_tolerance": report.rule.primary_tolerance.name,
            "n_boot": report.rule.n_boot,
            "ci": report.rule.ci,
            "seed": report.rule.seed,
            "groups": [
                {
                    **row,
                    "requirement": g.requirement,
                    "interval": g.interval_text,
                    "facts": g.facts,
                    "warnings": g.warnings,
                    "saturation_index": g.sat.index,
                    "best_index": g.sat.best_index,
                    "interval_index": g.sat.interval,
                    "note": g.sat.note,
                }
                for g, row in zip(report.groups, comparison_rows(report))
            ],
            "tolerance_table": tolerance_rows(report),
            "sensitivity": [
                {
                    "others": s.label,
                    "sentence": s.sentence,
                    "variants": [r for r in sensitivity_rows(report) if r["others"] == s.label],
                }
                for s in report.sensitivity
            ],
            "requirement_map": map_rows(report),
            "filter_pairs": filter_rows(report),
            "compute": compute_rows(report.sweep),
            "notes": report.notes,
            "failed": report.sweep.failed,
        }
    )


def log_report(report: SweepReport, files: ReportFiles, text: str) -> str:
    """Log ``files`` to the sweep's parent run (artifacts under ``report/``, description, tags, metrics)."""
    from mlflow.entities import Metric, RunTag
    from mlflow.tracking import MlflowClient

    s = report.sweep
    client = MlflowClient(tracking_uri=s.uri)
    client.log_artifacts(s.parent_id, str(files.out_dir), artifact_path="report")
    tags = [
        RunTag("mlflow.note.content", text[:50000]),
        RunTag("sphri.synthetic", {"all": "true", "some": "mixed", "none": "false"}[report.synthetic]),
        RunTag(
            "sphri.report.requirement",
            " | ".join([s.sentence for s in report.sensitivity] + [g.requirement for g in report.groups])[:5000],
        ),
    ]
    note = s.parent_tags.get("mlflow.note.content", "")
    if note.startswith("sweep:") and "sphri.sweep_note" not in s.parent_tags:
        tags.append(RunTag("sphri.sweep_note", note[:5000]))  # keep the sweep command the report replaces
    metrics = []
    import time

    now = int(time.time() * 1000)
    for row in comparison_rows(report):
        name = slug(str(row["group"]))
        for key in (
            "saturation_pitch_mm",
            "pitch_low_mm",
            "pitch_high_mm",
            "area_per_taxel_cm2",
            "saturation_res",
            "accuracy",
            "tolerance",
            "best_accuracy",
            "gap_to_best",
        ):
            v = float(row[key]) if row[key] is not None else float("nan")
            if np.isfinite(v):
                metrics.append(Metric(f"saturation/{name}/{key}", v, now, 0))
    client.log_batch(s.parent_id, metrics=metrics[:1000], tags=tags)
    return s.parent_id


def make_report(
    source: str | Path,
    uri: str | None = None,
    output_dir: str | Path = "outputs",
    out_dir: str | Path | None = None,
    rule: RuleSettings = RuleSettings(),  # noqa: B008 (frozen dataclass)
    log_to_mlflow: bool = True,
    marks: bool | None = None,
    formats: Sequence[str] = FIGURE_FORMATS,
    group_by: Sequence[str] | None = None,
) -> tuple[SweepReport, ReportFiles, str]:
    """Report on the sweep ``source`` (its directory or parent run id); returns (report, files, text).

    ``formats``: the figures' file formats (PNG, PDF and SVG by default; PNG alone for a quick look).
    ``group_by``: the params whose values make the curves (``["none"]``: one curve; default: what the sweep varies).

    ``out_dir`` defaults to ``<sweep_dir>/report``; it is required when the
    sweep directory is unknown (a run id from another machine).
    """
    formats = check_formats(formats)
    sweep = load_sweep(source, uri=uri, output_dir=output_dir, group_by=group_by)
    if out_dir is None:
        if sweep.sweep_dir is None:
            raise ReportError(
                f"the sweep directory of run {sweep.parent_id} is not on this machine "
                f"({sweep.parent_tags.get('sphri.sweep_dir', 'not recorded')}); pass --out DIR"
            )
        out_dir = sweep.sweep_dir / "report"
    report = analyze(sweep, rule)
    files = write_report(report, Path(out_dir), marks=marks, formats=formats)
    text = render_text(report, files.html)
    if log_to_mlflow:
        files.logged_to = log_report(report, files, text)
    return report, files, text
