"""``sphri coverage``: contact maps, placement and condition tests for a dataset.

::

    sphri coverage                                   # every region of the default data
    sphri coverage +debug=fast data.regions=[torso] by=gesture out=DIR
    sphri coverage data=vr_gesture data.root=... bandwidth_mm=8 mlflow=false

Arguments are ``key=value`` (or ``--key value``, :mod:`sphri.args`). Keys of :class:`~sphri.analysis.schema.CoverageSchema`
(``by``, ``bandwidth_mm``, ..., also as ``coverage.<key>``) set the
analysis; ``out=DIR`` (default ``<output_dir>/coverage/<timestamp>``) and
``mlflow=true|false`` the run; everything else is a sphri config override
(composed with :func:`sphri.config.compose`). Each region of
``data.regions`` is analysed on its own link (the config is composed once
per region; the data and contact stages come from the stage cache), and its
files go to ``out/<region>/``. One MLflow run tagged ``sphri.kind=coverage``
holds the numbers and every file.

A config with ``experiment.scenario_study`` settings (``+experiment=scenario_study``)
runs the whole-body scenario study instead (:func:`sphri.sessions.study.run_study`):
its files go to ``out`` and its MLflow run is tagged ``sphri.kind=scenario_study``.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sphri.analysis.coverage import ALL, CoverageAnalysis, RegionCoverage, write_region
from sphri.analysis.schema import CoverageSchema
from sphri.args import ArgsError, arg, first_paragraph, help_text, parse, parse_known
from sphri.config import ConfigError, check_out_apart, check_output_dir, compose
from sphri.errors import clean_errors

if TYPE_CHECKING:
    from sphri.sessions.study import StudyResult

log = logging.getLogger(__name__)

#: Settings of the analysis (CoverageSchema fields).
ANALYSIS_KEYS = tuple(f.name for f in dataclasses.fields(CoverageSchema) if f.name != "_target_")


@dataclass
class CoverageRunArgs:
    """The run's own arguments (beside the analysis settings, :class:`CoverageSchema`)."""

    out: str = arg("", help="folder of the files (default <output_dir>/coverage/<timestamp>)", metavar="DIR")
    mlflow: bool = arg(True, help="log one MLflow run tagged sphri.kind=coverage")
    overwrite: bool = arg(False, help="replace an existing, non-empty out folder whole (refused otherwise)")


@dataclass
class CoverageRun:
    """What one ``sphri coverage`` produced."""

    out_dir: Path
    regions: dict[str, RegionCoverage]
    files: dict[str, list[Path]]
    mlflow_run_id: str | None = None
    seconds: dict[str, float] = field(default_factory=dict)


def split_args(argv: Sequence[str], prog: str = "sphri coverage") -> tuple[list[str], CoverageSchema, CoverageRunArgs]:
    """(config overrides, analysis settings, run arguments) from the command line, through
    :mod:`sphri.args` (typed, range-checked; :class:`ArgsError` names the key)."""
    words = []
    for a in argv:
        key = a.partition("=")[0]
        if key.startswith("coverage."):  # the analysis keys also as coverage.<key>
            if key.removeprefix("coverage.") not in ANALYSIS_KEYS:
                raise ArgsError(f"unknown argument {key!r}; coverage settings: {', '.join(ANALYSIS_KEYS)}")
            a = a.removeprefix("coverage.")
        words.append(a)
    settings, rest = parse_known(CoverageSchema, words, prog)
    run_args, overrides = parse_known(CoverageRunArgs, rest, prog)
    return overrides, settings, run_args


def load_settings(args: Sequence[str] = ()) -> CoverageSchema:
    """The analysis settings: schema defaults with ``key=value`` ``args`` applied and checked."""
    return parse(CoverageSchema, args, "sphri coverage")


#: Settings of the figures only (not of the analysis).
FIGURE_KEYS = ("marks", "formats")


def analysis_from(settings: CoverageSchema) -> CoverageAnalysis:
    kwargs = {k: getattr(settings, k) for k in ANALYSIS_KEYS if k not in FIGURE_KEYS}
    return CoverageAnalysis(**kwargs)


def run(
    overrides: Sequence[str] = (),
    settings: CoverageSchema | None = None,
    out: str | Path | None = None,
    log_mlflow: bool = True,
    overwrite: bool = False,
) -> CoverageRun | StudyResult:
    """Analyse every region of the composed config's data; write files; log MLflow (``+experiment=scenario_study``:
    the whole-body study's result). An ``out`` that exists and is not empty is refused unless ``overwrite``, and
    then replaced whole when the files are written (:func:`sphri.fsutil.into_dir`): old and new files never mix,
    and the MLflow run logs only this run's."""
    from sphri.fsutil import into_dir, moved, new_run_dir

    settings = settings or CoverageSchema()
    analysis = analysis_from(settings)
    overrides = list(overrides)
    base = compose(overrides)
    from sphri.sessions.schema import study_settings

    if out:  # before any computing: a file there, or an old run's files, is one line, not a traceback or a mix
        check_out_apart(str(out), base)  # every file of out is logged: never the store, artifacts or cache
        check_output_dir(str(out), key="out", overwrite=overwrite)
    if study_settings(base) is not None:  # +experiment=scenario_study: the whole-body study
        from sphri.sessions.study import run_study

        refuse_link_settings(settings)
        return run_study(overrides, out, log_mlflow)
    regions = [str(r) for r in base.data.regions]
    if not regions:
        raise ConfigError("data.regions=[] is invalid: name at least one skin region")
    out_dir = Path(out) if out else new_run_dir(Path(base.output_dir) / "coverage")
    with into_dir(out_dir) as write_dir:
        cov, meta = _analyse_regions(analysis, settings, overrides, regions, write_dir)
    cov.files = {region: moved(paths, write_dir, out_dir) for region, paths in cov.files.items()}
    cov.out_dir = out_dir
    if log_mlflow:
        cov.mlflow_run_id = log_coverage(base, settings, cov, overrides, meta)
    return cov


def _analyse_regions(
    analysis: CoverageAnalysis, settings: CoverageSchema, overrides: list[str], regions: list[str], out_dir: Path
) -> tuple[CoverageRun, dict[str, Any]]:
    """Each region analysed on its own link (one composition per region; data and contact from the stage cache),
    its files under ``out_dir/<region>``, then ``settings.json`` and ``recommendation.txt``; the run and what the
    MLflow run records of the data."""
    from sphri.figures import Provenance, only_formats
    from sphri.pipeline import make_pipeline, open_cache

    rest = [o for o in overrides if not o.lstrip("+").startswith("data.regions=")]
    results: dict[str, RegionCoverage] = {}
    files: dict[str, list[Path]] = {}
    seconds: dict[str, float] = {}
    meta: dict[str, Any] = {}
    for region in regions:
        t0 = time.perf_counter()
        cfg = compose(rest + [f"data.regions=[{region}]"])
        p = make_pipeline(cfg, open_cache(cfg))
        dataset, contacts = p.get("data"), p.get("contact")
        robot, surface = p.get("robot"), p.get("surface")
        link = robot.link_for(region)
        t1 = time.perf_counter()
        result = analysis.analyze(dataset, contacts, link, surface, region)
        marks = Provenance(synthetic=bool(dataset.synthetic), ids=dataset.name, show=settings.marks)
        with only_formats(settings.formats):
            files[region] = write_region(
                result, out_dir / region, link, surface, settings.render, settings.views, marks
            )
        results[region] = result
        seconds[f"{region}.stages"] = t1 - t0
        seconds[f"{region}.analysis"] = time.perf_counter() - t1
        meta = {
            "dataset": dataset.name,
            "synthetic": bool(dataset.synthetic),
            "robot": robot.name,
            "n_participants": int(dataset.trials["participant"].nunique()),
        }
        log.info("coverage %s: %s", region, result.sentences[ALL])
    (out_dir / "settings.json").write_text(
        json.dumps(
            {"coverage": dataclasses.asdict(settings), "overrides": overrides, "regions": regions, **meta}, indent=2
        )
    )
    (out_dir / "recommendation.txt").write_text(
        "".join(
            f"[{r}]\n" + "\n".join(res.sentences[n] for n in [ALL] + res.groups) + "\n\n" for r, res in results.items()
        )
    )
    return CoverageRun(out_dir, results, files, None, seconds), meta


#: Settings of one link's analysis and the study's setting of the same meaning (``experiment.scenario_study.<key>``).
STUDY_KEYS = {"formats": "figure_formats"}


def refuse_link_settings(settings: CoverageSchema) -> None:
    """The scenario study reads its settings from ``experiment.scenario_study``, none of one link's analysis:
    a link setting given with ``+experiment=scenario_study`` is refused, naming the study's key when it has one
    (:class:`ConfigError`), never ignored."""
    from sphri.sessions.schema import ScenarioStudySchema

    default = CoverageSchema()
    study_keys = {f.name for f in dataclasses.fields(ScenarioStudySchema)}
    for key in ANALYSIS_KEYS:
        value = getattr(settings, key)
        if value == getattr(default, key):
            continue
        other = STUDY_KEYS.get(key, key)
        where = (
            f"set experiment.scenario_study.{other} instead"
            if other in study_keys
            else "it has no such setting (its settings: conf/experiment/scenario_study.yaml)"
        )
        shown = ",".join(map(str, value)) if isinstance(value, list) else value
        raise ConfigError(
            f"coverage.{key}={shown} is a setting of one link's analysis; the scenario study "
            f"(+experiment=scenario_study) does not read it: {where}"
        )


def log_coverage(cfg, settings: CoverageSchema, cov: CoverageRun, overrides: Sequence[str], meta: dict) -> str | None:
    """One MLflow run tagged ``sphri.kind=coverage``: params, per-group metrics, all files."""
    from mlflow.entities import Metric, Param

    from sphri.tracking.mlflow_tracker import flatten_params, log_analysis_run

    tags = {
        "sphri.dataset": str(meta.get("dataset", "")),
        "sphri.synthetic": str(meta.get("synthetic", "")).lower(),
        "sphri.coverage_dir": str(cov.out_dir.resolve()),
        "mlflow.note.content": "\n\n".join(
            f"[{r}]\n" + "\n".join(res.sentences[n] for n in [ALL] + res.groups) for r, res in cov.regions.items()
        ),
    }

    def numbers() -> tuple[list[Metric], list[Param]]:
        params = {
            k: v
            for k, v in flatten_params(cfg).items()
            if k.split(".")[0] in ("seed", "data", "robot", "contact", "surface")
        }
        params.update({f"coverage.{k}": str(getattr(settings, k)) for k in ANALYSIS_KEYS})
        params["coverage.regions"] = ",".join(cov.regions)
        now = int(time.time() * 1000)
        metrics = []
        for region, res in cov.regions.items():
            summ = res.summary()
            for g, entry in summ["groups"].items():
                for key in (
                    "area_share_at_capture",
                    "n_contact_frames",
                    "heldout_captured_mean",
                    "heldout_area_share_mean",
                ):
                    if key in entry:
                        metrics.append(Metric(f"{region}/{key}/{_metric_name(g)}", float(entry[key]), now, 0))
            if res.comparison is not None:  # summary() has "comparison" exactly then
                metrics.append(
                    Metric(f"{region}/n_significant_pairs", float(summ["comparison"]["n_significant"]), now, 0)
                )
                for row in res.comparison.table.itertuples(index=False):
                    name = f"{_metric_name(row.cond_a)}-{_metric_name(row.cond_b)}"
                    if row.p_holm == row.p_holm:
                        metrics.append(Metric(f"{region}/p_holm/{name}", float(row.p_holm), now, 0))
                        metrics.append(Metric(f"{region}/swd_mm/{name}", float(row.mean_between_swd_mm), now, 0))
        for k, v in cov.seconds.items():
            metrics.append(Metric(f"time/{k}_s", float(v), now, 0))
        return metrics, [Param(k, str(v)[:500]) for k, v in params.items()]

    return log_analysis_run(cfg, "coverage", f"coverage-by-{settings.by}", tags, numbers, cov.out_dir)


def _metric_name(value: str) -> str:
    import re

    return re.sub(r"[^\w.\- /]+", "_", str(value))


@clean_errors("sphri coverage")
def main(argv: Sequence[str] | None = None, prog: str = "sphri coverage") -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if any(a in ("-h", "--help") for a in argv):
        print(help_text(CoverageSchema, prog, first_paragraph(__doc__), overrides=True))
        print("\n" + help_text(CoverageRunArgs, prog).split("\n", 2)[2].replace("arguments", "run arguments", 1))
        return 0
    try:
        overrides, settings, run_args = split_args(argv, prog)
    except ArgsError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        res = run(overrides, settings, run_args.out or None, run_args.mlflow, run_args.overwrite)
    except ConfigError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2
    if not isinstance(res, CoverageRun):  # the scenario study
        for s in res.sentences:
            print(s)
        for n in res.notes:
            print("note: " + n)
        print(
            f"files: {res.out_dir} (report.html)" + (f"; MLflow run {res.mlflow_run_id}" if res.mlflow_run_id else "")
        )
        return 0
    for region, r in res.regions.items():
        print(f"[{region}] {r.link}: {r.samples.n} elements, {r.curves[ALL].n_frames} contact frames")
        summary = r.summary()["groups"]
        for n in [ALL] + r.groups:
            print("  " + r.sentences[n])
            g = summary.get(n, {})
            if "heldout_captured_mean" in g:  # the in-sample sentence is optimistic: say what held-out people get
                print(
                    f"    on held-out participants the same area captures {g['heldout_captured_mean']:.0%} "
                    f"of their contact frames (worst participant {g['heldout_captured_min']:.0%})"
                )
        if r.comparison is not None:
            t = r.comparison.table
            print(
                f"  {int(t['significant'].sum())}/{len(t)} pairs of {r.by} differ (Holm, alpha {r.comparison.alpha:g})"
            )
        for note in r.notes:
            print(f"  note: {note}")
    print(f"files: {res.out_dir}" + (f"; MLflow run {res.mlflow_run_id}" if res.mlflow_run_id else ""))
    return 0
