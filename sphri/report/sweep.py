"""Read a finished sweep back from MLflow: its parent run, jobs and per-participant scores.

A sweep is found from its directory (``<sweep_dir>/mlflow_parent_run.json``
names the parent run and the tracking URI) or from the parent's run id and a
tracking URI. Its jobs are the parent's children (tag ``mlflow.parentRunId``)
plus any run named by a job's ``sphri_status.json`` (a resumed sweep's
skipped jobs point at an earlier finished run). A folder holding the jobs of
another sweep (a status file naming a run of another parent that the sweep
did not skip for, or two finished runs with other settings in one job folder)
is refused: the report reads one sweep. Per-participant scores come
from each job's ``per_participant.csv`` artifact, else from its
``participant/<id>/accuracy`` metrics.

Jobs are grouped into curves by :mod:`sphri.report.grouping`: the params that
vary across the sweep's own jobs and can change a result, other than the
resolution (e.g. ``model`` in a model comparison, ``robot`` in a morphology
sweep, ``layout`` or ``noise``), or the keys ``group_by`` names. ``variant``
(the assumption variant of ``+experiment=requirement_sensitivity``, one per
``conf/sensitivity/*.yaml``) comes first, and a parameter that the keys before
it already fix (the ``encoder`` of ``variant=coverage``, the ``noise.p`` of
``variant=noise0``) is not a key of its own. A job the sweep skipped because
an earlier job outside it had finished the same config joins the curve of its
point and is named in the report's notes.

``seed`` is not a group key: jobs that differ only in their seed (and in
settings the seed alone fixes, such as ``model.seed``) are replicates of the
same sweep point, kept in the ``seed`` column of :attr:`Sweep.runs`; the
report measures the rerun noise between them and averages each participant's
score over them (:func:`sphri.report.saturation.certified_saturation`).
"""

from __future__ import annotations

import json
import logging
import re
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri.report.grouping import REPLICATE_KEY, chosen_keys, group_keys, group_label, res_param
from sphri.tracking.mlflow_tracker import PARENT_FILE, default_uri, no_artifact_bars
from sphri.types import GESTURES

log = logging.getLogger(__name__)

STATUS_FILE = "sphri_status.json"
_RUN_ID = re.compile(r"^[0-9a-f]{32}$")

#: The layout's geometry at one resolution (the columns of the report's points table).
GEOMETRY_PARAMS = (
    "n_taxels",
    "grid_h",
    "grid_w",
    "pitch_u_mm",
    "pitch_v_mm",
    "area_per_taxel_cm2",
    "taxels_per_24cm",
)
#: Per-resolution columns read from the jobs' ``resolution.*`` params (floats).
RESOLUTION_PARAMS = (*GEOMETRY_PARAMS, "link_length_mm", "circumference_mm")


class ReportError(ValueError):
    """The sweep cannot be reported on; the message says what is missing."""


@dataclass
class Sweep:
    """A sweep's jobs and their per-participant scores."""

    parent_id: str
    uri: str
    sweep_id: str
    sweep_dir: Path | None
    parent_tags: dict[str, str]
    runs: pd.DataFrame
    """One row per finished job: run_id, res, group, ``key.<k>`` per group key, ``joined`` (a run of an
    earlier job outside the sweep, found through a job's status file, not a child of the parent), context
    (robot, region, link, dataset, synthetic, cv_scheme, model), the
    ``RESOLUTION_PARAMS`` (mm, cm^2, counts), and where and how long it ran: ``stage_s`` (wall seconds, the sum of its
    ``time/<stage>_s`` metrics), ``evaluated_here``, ``cpu_model``, ``cpu_count``, ``gpu``, ``torch``,
    ``device``, ``precision`` (the model's, as resolved on that machine; "" when not recorded)."""
    folds: pd.DataFrame
    """One row per (job, participant): run_id, participant, n_test, accuracy,
    macro_f1, recall_<gesture> (NaN where unknown)."""
    group_keys: list[str]
    failed: list[dict[str, Any]]
    """Jobs that failed: run_id, res, group, error."""
    notes: list[str] = field(default_factory=list)

    @property
    def synthetic(self) -> str:
        """ "all", "some" or "none": whether the jobs ran on SYNTHETIC data."""
        flags = self.runs["synthetic"].astype(bool)
        return "all" if flags.all() else ("some" if flags.any() else "none")

    def groups(self) -> list[tuple[str, pd.DataFrame]]:
        """(label, its jobs sorted by res) for each group, labels in natural sort order."""
        return [
            (label, self.runs[self.runs["group"] == label].sort_values("res", kind="stable").reset_index(drop=True))
            for label in sorted(self.runs["group"].unique(), key=natural_key)
        ]


def natural_key(s: str) -> list[Any]:
    """Sort key putting ``seed=2`` before ``seed=10``."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", str(s))]


def resolve_source(
    source: str | Path, uri: str | None = None, output_dir: str | Path = "outputs"
) -> tuple[str, str, Path | None]:
    """(parent run id, tracking URI, sweep dir or None) for a sweep dir or a parent run id."""
    path = Path(source)
    if path.is_dir():
        parent_file = path / PARENT_FILE
        if not parent_file.exists():
            raise ReportError(
                f"{path}: no {PARENT_FILE} here, so this is not a tracked sphri sweep directory "
                "(run the sweep with `python -m sphri -m ...` and tracking.enabled=true, or pass the parent run id)"
            )
        try:
            info = json.loads(parent_file.read_text())
            run_id = str(info["run_id"])
        except (ValueError, KeyError, RecursionError) as exc:
            raise ReportError(
                f"{parent_file}: unreadable ({type(exc).__name__}: {exc}); expected {{run_id, sweep_id, uri}}"
            ) from None
        return run_id, uri or str(info.get("uri") or default_uri(output_dir)), path.resolve()
    text = str(source).strip()
    if _RUN_ID.match(text):
        return text, uri or default_uri(output_dir), None
    if path.exists() or "/" in text or "\\" in text:
        raise ReportError(f"{source}: no such sweep directory")
    raise ReportError(
        f"{source!r} is neither a sweep directory (with {PARENT_FILE}) nor an MLflow run id (32 hex characters)"
    )


def load_sweep(
    source: str | Path,
    uri: str | None = None,
    output_dir: str | Path = "outputs",
    group_by: Sequence[str] | None = None,
) -> Sweep:
    """Read the sweep named by ``source`` (sweep dir or parent run id) from MLflow; ``group_by``: the params
    whose values make the curves (``["none"]``: one curve), else those the sweep varies
    (:mod:`sphri.report.grouping`)."""
    from mlflow.tracking import MlflowClient

    no_artifact_bars()
    parent_id, uri, sweep_dir = resolve_source(source, uri, output_dir)
    if uri.startswith("sqlite:///") and not Path(uri[len("sqlite:///") :]).exists():
        raise ReportError(f"tracking store {uri} does not exist (wrong --output-dir or --uri?)")
    client = MlflowClient(tracking_uri=uri)
    try:
        parent = client.get_run(parent_id)
    except Exception as exc:
        raise ReportError(f"parent run {parent_id} not found in {uri}: {exc}") from None
    ptags = dict(parent.data.tags)
    if sweep_dir is None:
        sweep_dir = _recorded_sweep_dir(ptags)
    sweep_id = ptags.get("sphri.sweep_id", parent_id[:8])

    runs = _children(client, parent.info.experiment_id, parent_id)
    own = {r.info.run_id for r in runs}
    notes: list[str] = []
    _one_sweep_per_job_dir(runs, sweep_dir, parent_id)
    if sweep_dir is not None:
        _add_status_file_runs(client, runs, sweep_dir, Path(str(source)).is_dir(), parent_id, notes)
    if not runs:
        raise ReportError(f"sweep {sweep_id} (parent run {parent_id}) has no job runs in {uri}")
    finished, failed_runs = _finished_runs(runs, sweep_id, notes)
    params = {r.info.run_id: dict(r.data.params) for r in finished}
    table = _latest_per_config(finished, notes)
    table, keys = _group_table(table, params, own, group_by, notes)
    table, folds = _with_scores(client, finished, table, sweep_id, notes)
    _note_joined(table, notes)
    failed = _failed_jobs(failed_runs, table, keys, notes)
    return Sweep(parent_id, uri, sweep_id, sweep_dir, ptags, table, folds, keys, failed, notes)


def _recorded_sweep_dir(ptags: dict[str, str]) -> Path | None:
    """The sweep directory the parent run's tags record, when it is on this machine."""
    if not ptags.get("sphri.sweep_dir"):
        return None
    d = Path(ptags["sphri.sweep_dir"])
    return d if d.is_dir() else None


def _add_status_file_runs(
    client: Any, runs: list[Any], sweep_dir: Path, given_dir: bool, parent_id: str, notes: list[str]
) -> None:
    """Add to ``runs`` the runs named by the job status files of ``sweep_dir`` that are not children of the
    parent: those of jobs the sweep skipped for an earlier finished run. A run of another sweep is refused
    when the sweep was given as a directory (``given_dir``), else left out with a note."""
    known = {r.info.run_id for r in runs}
    for status in sorted(sweep_dir.glob(f"*/{STATUS_FILE}")):
        try:
            info = json.loads(status.read_text())
            rid = info.get("mlflow_run_id")
        except (ValueError, RecursionError, AttributeError):
            notes.append(f"{status}: unreadable job status file, ignored")
            continue
        if rid and rid not in known and info.get("status") != "SKIPPED":
            # not a job of this parent, and not one the sweep skipped for an earlier run: another sweep's
            theirs = _parent_of(client, rid)
            if given_dir:
                raise ReportError(
                    f"{sweep_dir} holds the jobs of more than one sweep: {status} names run {rid}"
                    f"{f' of the sweep with parent run {theirs}' if theirs else ''}, not a job of this folder's "
                    f"sweep (parent run {parent_id}); the report reads one sweep only: give the parent run id "
                    f"of the sweep to report (`sphri report {parent_id}`"
                    f"{f' or {theirs}' if theirs else ''})"
                )
            notes.append(f"{status}: run {rid} belongs to another sweep (parent run {theirs or 'none'}), left out")
            continue
        if rid and rid not in known:
            try:
                runs.append(client.get_run(rid))
                known.add(rid)
            except Exception:
                notes.append(f"{status}: run {rid} not found in the tracking store")


def _finished_runs(runs: list[Any], sweep_id: str, notes: list[str]) -> tuple[list[Any], list[Any]]:
    """(finished, failed) runs; notes the interrupted attempts of jobs that finished later and the jobs
    that did not finish. Raises :class:`ReportError` when none finished."""
    finished = [r for r in runs if r.info.status == "FINISHED"]
    failed_runs = [r for r in runs if r.info.status == "FAILED"]
    finished_hashes = {_config_hash(r) for r in finished}
    other = [r for r in runs if r.info.status not in ("FINISHED", "FAILED")]
    resumed = [r for r in other if _config_hash(r) in finished_hashes]
    other = [r for r in other if _config_hash(r) not in finished_hashes]
    if resumed:
        notes.append(
            f"{len(resumed)} interrupted attempt(s) of jobs that finished later (resumed): "
            "the compute table counts only the finished runs' stage times"
        )
    if other:
        notes.append(
            f"{len(other)} job(s) not finished ({', '.join(sorted({r.info.status for r in other}))}): left out"
        )
    if not finished:
        raise ReportError(f"sweep {sweep_id}: none of its {len(runs)} jobs finished; nothing to report")
    return finished, failed_runs


def _latest_per_config(finished: list[Any], notes: list[str]) -> pd.DataFrame:
    """One row per finished job (:func:`_run_row`), the latest run of each config hash."""
    table = pd.DataFrame([_run_row(r) for r in finished])
    table = table.sort_values("start_time", kind="stable")
    n_before = len(table)
    table = table.drop_duplicates("config_hash", keep="last")
    if len(table) < n_before:
        notes.append(
            f"{n_before - len(table)} duplicate job(s) with the same config hash: the latest run of each is used"
        )
    return table


def _group_table(
    table: pd.DataFrame,
    params: dict[str, dict[str, str]],
    own: set[str],
    group_by: Sequence[str] | None,
    notes: list[str],
) -> tuple[pd.DataFrame, list[str]]:
    """(``table`` with ``joined``, ``key.<k>`` per group key, ``group`` and ``seed`` columns, the latest job of
    each (group, resolution, seed) kept; the group keys)."""
    table["joined"] = ~table["run_id"].isin(own)
    # the sweep's own jobs say what it varies; a joined run has the config of the point it stands for
    basis = [params[rid] for rid in table.loc[~table["joined"], "run_id"]] or [params[rid] for rid in table["run_id"]]
    keys = chosen_keys(group_by, [params[rid] for rid in table["run_id"]]) if group_by else group_keys(basis)
    for k in keys:  # "key.robot" (the component choice) beside "robot" (the robot's name)
        table[f"key.{k}"] = [params[rid].get(k, "") for rid in table["run_id"]]
    table["group"] = [
        group_label({k: params[rid].get(k, "") for k in keys}, model)
        for rid, model in zip(table["run_id"], table["model"])
    ]
    n_before = len(table)
    table["seed"] = [params[rid].get(REPLICATE_KEY, "0") for rid in table["run_id"]]
    table = table.drop_duplicates(["group", "res", "seed"], keep="last")
    if len(table) < n_before:
        notes.append(
            f"{n_before - len(table)} job(s) repeat a (group, resolution, seed) with a different config: "
            "the latest is used"
        )
    return table.reset_index(drop=True), keys


def _with_scores(
    client: Any, finished: list[Any], table: pd.DataFrame, sweep_id: str, notes: list[str]
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(the jobs of ``table`` that logged per-participant scores, their scores (:func:`_fold_rows`)); raises
    :class:`ReportError` when none did."""
    folds = pd.concat(
        [_fold_rows(client, r) for r in finished if r.info.run_id in set(table["run_id"])], ignore_index=True
    )
    no_scores = sorted(set(table["run_id"]) - set(folds["run_id"]))
    if no_scores:
        notes.append(f"{len(no_scores)} job(s) logged no per-participant scores: left out")
        table = table[~table["run_id"].isin(no_scores)].reset_index(drop=True)
    if table.empty:
        raise ReportError(
            f"sweep {sweep_id}: no finished job has per-participant scores (per_participant.csv or participant/<id>/accuracy)"
        )
    return table, folds


def _note_joined(table: pd.DataFrame, notes: list[str]) -> None:
    """Name the points joined from earlier jobs outside the sweep (the sweep skipped them)."""
    joined = table[table["joined"]]
    if len(joined):
        points = ", ".join(f"res {r.res} ({r.group}: run {r.run_id[:8]})" for r in joined.itertuples())
        notes.append(
            f"{len(joined)} point(s) joined from earlier jobs outside this sweep (the same config: the sweep "
            f"skipped them): {points}"
        )


def _failed_jobs(
    failed_runs: list[Any], table: pd.DataFrame, keys: list[str], notes: list[str]
) -> list[dict[str, Any]]:
    """The failed jobs (run_id, res, group, error) whose point no finished run of ``table`` stands for; notes
    how many failed runs a finished run superseded."""
    failed = []
    done = set(zip(table["group"], table["res"].astype(str)))
    n_superseded = 0
    for r in failed_runs:
        p = dict(r.data.params)
        label = group_label({k: p.get(k, "") for k in keys}, p.get("model", "?"))
        if (label, res_param(p, "?")) in done:
            n_superseded += 1  # failed once, finished on a resumed run
            continue
        failed.append(
            {
                "run_id": r.info.run_id,
                "res": res_param(p, "?"),
                "group": label,
                "error": r.data.tags.get("sphri.error", "no error recorded"),
            }
        )
    if n_superseded:
        notes.append(f"{n_superseded} failed job run(s) were superseded by a finished run of the same point")
    return failed


def _parent_of(client: Any, run_id: str) -> str | None:
    try:
        return client.get_run(run_id).data.tags.get("mlflow.parentRunId")
    except Exception:  # gone from the store
        return None


def _job_settings(run: Any) -> dict[str, str]:
    """The params of a job run that say what it computed (not how it ran, nor what it measured)."""
    from sphri.config import result_neutral, runtime_keys

    runtime = runtime_keys()
    return {
        k: v
        for k, v in run.data.params.items()
        if not k.startswith(("meta.", "resolution.")) and not result_neutral(k, runtime)
    }


def _one_sweep_per_job_dir(runs: Sequence[Any], sweep_dir: Path | None, parent_id: str) -> None:
    """Raise :class:`ReportError` when two finished jobs of the parent ran in one job folder with other
    settings: two sweeps shared the folder and its parent run, and the report cannot tell which is which."""
    seen: dict[str, tuple[Any, dict[str, str]]] = {}
    for r in runs:
        job_dir = r.data.tags.get("sphri.job_dir")
        if not job_dir or r.info.status != "FINISHED":
            continue
        settings = _job_settings(r)
        if job_dir not in seen:
            seen[job_dir] = (r, settings)
            continue
        first, before = seen[job_dir]
        differ = sorted(k for k in set(before) | set(settings) if before.get(k) != settings.get(k))
        if differ:
            shown = ", ".join(f"{k}={before.get(k)} vs {settings.get(k)}" for k in differ[:3])
            raise ReportError(
                f"{sweep_dir or 'the sweep'} was used by more than one sweep under parent run {parent_id}: job folder "
                f"{job_dir} holds runs {first.info.run_id} and {r.info.run_id} with other settings ({shown}); "
                "the report reads one sweep only and cannot tell them apart"
            )


def _children(client: Any, experiment_id: str, parent_id: str) -> list[Any]:
    runs, token = [], None
    query = f"tags.`mlflow.parentRunId` = '{parent_id}'"
    while True:
        page = client.search_runs([experiment_id], query, max_results=1000, page_token=token)
        runs.extend(page)
        token = page.token
        if not token:
            return runs


def _config_hash(run: Any) -> str:
    return str(run.data.tags.get("sphri.config_hash", run.info.run_id))


def _stage_seconds(metrics: dict[str, float]) -> float:
    """Wall seconds of the job's stages in this run: the sum of its ``time/<stage>_s`` metrics. (A job's
    MLflow run is opened when the job logs its result, so the run's own start-to-end time is not the job's.)
    Folds a resumed job loaded from the stage cache are not counted."""
    return float(sum(v for k, v in metrics.items() if k.startswith("time/") and k.endswith("_s") and np.isfinite(v)))


def _float(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def _run_row(run: Any) -> dict[str, Any]:
    p, t, m = run.data.params, run.data.tags, run.data.metrics
    try:
        res = int(res_param(p))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ReportError(f"job run {run.info.run_id} has no integer param layout.res (got {res_param(p)!r})") from None
    row: dict[str, Any] = {
        "run_id": run.info.run_id,
        "start_time": int(run.info.start_time or 0),
        "config_hash": _config_hash(run),
        "res": res,
        "model": p.get("model", "?"),
        "robot": p.get("meta.robot", p.get("robot", "?")),
        "region": p.get("meta.region", "?"),
        "link": p.get("meta.link", "?"),
        "dataset": t.get("sphri.dataset", p.get("data", "?")),
        "synthetic": t.get("sphri.synthetic", "false").lower() == "true",
        "cv_scheme": t.get("sphri.cv_scheme", p.get("cv", "?")),
        "layout_kind": p.get("resolution.layout_kind", p.get("layout", "?")),
        "n_participants": _float(p.get("meta.n_participants")),
        "job_dir": t.get("sphri.job_dir", ""),
        # where and how long (the report's compute table, sphri.report.compute)
        "stage_s": _stage_seconds(dict(m)),
        "evaluated_here": t.get("sphri.evaluated", "in this run") == "in this run",
        "cpu_model": t.get("sphri.machine.cpu_model", "unknown CPU"),
        "cpu_count": t.get("sphri.machine.cpu_count", "?"),
        "gpu": t.get("sphri.machine.gpu", "unknown"),
        "torch": t.get("sphri.lib.torch", ""),
        "device": p.get("run.device", ""),
        "precision": p.get("run.precision", ""),
    }
    for k in RESOLUTION_PARAMS:
        row[k] = _float(p.get(f"resolution.{k}"))
    row["false_on_rate"] = false_on_rate(p)
    for k in ("accuracy_mean", "accuracy_std", "macro_f1_mean", "macro_f1_std"):
        row[f"logged_{k}"] = _float(m.get(k))
    return row


def false_on_rate(params: dict[str, str]) -> float:
    """The probability per taxel and frame that an untouched taxel reads on, from a job's noise params.

    ``noise=salt_pepper``: ``p * salt_vs_pepper`` in replace mode (a corrupted reading becomes 1 with
    probability salt_vs_pepper), ``p`` in flip mode (an untouched taxel reads 0, so every flip turns it on);
    ``noise=threshold``: ``P(N(0, sigma_mm2^2 + drift_sigma_mm2^2) > threshold_mm2)``
    (:func:`sphri.noise.components.threshold_false_on_rate`, the schema's defaults for unswept settings);
    ``noise=none``: 0; any other noise: NaN (not a false-on rate per frame).
    """
    if params.get("noise") in ("none", "NoNoise"):
        return 0.0
    if params.get("noise") in ("threshold", "ThresholdNoise"):
        from sphri.noise.components import threshold_false_on_rate
        from sphri.noise.schema import ThresholdNoiseSchema

        d = ThresholdNoiseSchema()
        return threshold_false_on_rate(
            _float(params.get("noise.sigma_mm2", str(d.sigma_mm2))),
            _float(params.get("noise.threshold_mm2", str(d.threshold_mm2))),
            _float(params.get("noise.drift_sigma_mm2", str(d.drift_sigma_mm2))),
        )
    if "noise.p" not in params:
        return float("nan")
    p = _float(params.get("noise.p"))
    if params.get("noise.mode", "replace") == "flip":
        return p
    svp = _float(params.get("noise.salt_vs_pepper", "0.5"))
    return p * svp


def _fold_rows(client: Any, run: Any) -> pd.DataFrame:
    """Per-participant scores of one job: its CSV artifact, else its participant metrics."""
    rid = run.info.run_id
    cols = ["participant", "n_test", "accuracy", "macro_f1"] + [f"recall_{g}" for g in GESTURES]
    df = None
    try:
        with tempfile.TemporaryDirectory(prefix="sphri-report-") as tmp:
            path = client.download_artifacts(rid, "per_participant.csv", tmp)
            df = pd.read_csv(path, dtype={"fold": str})
    except Exception as exc:  # no artifact (tracking.artifacts=false) or unreadable
        log.debug("run %s: no per_participant.csv (%s); using participant metrics", rid, exc)
    if df is not None and {"fold", "accuracy"} <= set(df.columns):
        df = df.rename(columns={"fold": "participant"})
    else:
        pat = re.compile(r"^participant/(?P<p>.+)/accuracy$")
        rows = [
            {"participant": m.group("p"), "accuracy": float(v)}
            for k, v in run.data.metrics.items()
            if (m := pat.match(k))
        ]
        df = pd.DataFrame(rows, columns=["participant", "accuracy"])
    df = df.reindex(columns=cols)  # a column the job did not log: NaN
    df["participant"] = df["participant"].astype(str)
    for c in cols[1:]:
        df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    df.insert(0, "run_id", rid)
    return df
