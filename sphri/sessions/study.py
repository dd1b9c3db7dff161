"""The whole-body scenario study: ``sphri coverage +experiment=scenario_study``.

Data flow (each step a module of :mod:`sphri.sessions`)::

    sessions (data=synthetic_sessions | sessions)       SessionDataset: both hands + link poses, world
      -> body_contacts (contact=exact, culled)            BodyContacts: rows in the touched link's frame
      -> segment_episodes (>= episode_gap_s apart)        episodes; the first coded one per session
      -> train_gesture_model + label_episodes             gesture probabilities per coded episode (sphri.sessions.labelling)
      -> read_codes (codes=PATH)                          or the gestures people coded (sphri.sessions.codes), with kappa
      -> body_surface + touched_pairs                     (frame, element) pairs on the whole surface
      -> CoverageAnalysis(by=scenario, pair_by=participant)   densities, SWD tests (Holm), coverage curves
      -> rank_parts + placement_table                     body parts per cm^2, greedy placement, held-out check
      -> skin_design (sphri.sessions.skin)                patches within parts, budget curve, patch placement, export
      -> files, HTML report, MLflow run (sphri.kind=scenario_study)

Sessions and contacts are the ``sessions`` and ``body_contact`` rows of :data:`sphri.stages.STAGES`
(their compute declared in :mod:`sphri.sessions.labelling`), wired by
:func:`sphri.pipeline.make_pipeline` like every stage (keys: data, hand, robot and
contact configs, component versions and input-file fingerprints), so re-running with
other study settings recomputes neither; the gesture chains of the same job share
their hand and robot in memory (:class:`sphri.pipeline.Memo`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri import figures
from sphri.fsutil import into_dir, moved, new_run_dir
from sphri.progress import bar
from sphri.sessions.schema import ScenarioStudySchema

log = logging.getLogger(__name__)

VERSION = "1"


@dataclass
class StudyResult:
    out_dir: Path
    settings: ScenarioStudySchema
    synthetic: bool
    sessions: pd.DataFrame
    episodes: pd.DataFrame
    coded: pd.DataFrame
    histogram: pd.DataFrame
    ranking: pd.DataFrame
    placement: pd.DataFrame
    sentences: list[str]
    comparison: Any
    coverage: Any
    notes: list[str]
    files: list[Path]
    seconds: dict[str, float] = field(default_factory=dict)
    gesture_accuracy: float = float("nan")
    mlflow_run_id: str | None = None
    design: Any = None
    """The skin design (:class:`sphri.sessions.skin.SkinDesign`): patches, budget curve, patch placement."""
    truth: Any = None
    """The generator's draws per session (synthetic sessions), else None."""
    mountable: Any = None
    """Per body part: reachable area, width, whether a skin can be mounted and why not
    (:func:`sphri.sessions.placement.mountable_parts`)."""
    plausibility: dict | None = None
    """Synthetic sessions' hands against the robot and the arm study
    (:func:`sphri.sessions.plausibility.plausibility`), else None."""
    codes: Any = None
    """Gestures coded by hand (:class:`sphri.sessions.codes.HumanCodes`, ``codes=PATH``), else None."""
    sensitivity: Any = None
    """The priors sensitivity run (:func:`sphri.sessions.sensitivity.priors_sensitivity`): (per-draw table,
    summary) on generated sessions with ``sensitivity_draws`` > 0, else None."""


#: The ``gesture`` of a session without a coded, labelled episode (``by=gesture`` maps it apart, never as a gesture).
UNLABELLED = "unlabelled"


def session_gestures(n_sessions: int, labelled: pd.DataFrame) -> list[str]:
    """Per session, the predicted gesture of its coded episode, or :data:`UNLABELLED` (never a gesture by default)."""
    gest = dict(zip(labelled["session"], labelled["gesture"]))
    return [str(gest.get(i) or UNLABELLED) for i in range(n_sessions)]


def run_study(overrides: Sequence[str], out: str | Path | None = None, log_mlflow: bool = True) -> StudyResult:
    """Run the study for the composed ``overrides`` (they must select ``+experiment=scenario_study``) and write its
    files under ``out`` (default: ``output_dir/scenario_study/<time>``); each step's time (s) goes to
    ``timing.json``. An ``out`` holding files is replaced whole once the study's files are written
    (:func:`sphri.fsutil.into_dir`; ``sphri coverage`` refuses it first unless ``overwrite=true``): old and new
    files never mix, and on a failure it is untouched. With ``log_mlflow``, one MLflow run (:func:`log_study`)."""
    job = _start(overrides, out)
    final = job.out_dir
    with into_dir(final) as write_dir:
        job.out_dir = write_dir  # every step writes there; it becomes final once the files are written
        with job.step(None):  # its stages time themselves
            sess = _sessions(job)
        with job.step("gestures"):
            gest = _code_gestures(job, sess)
        with job.step("maps_and_tests"):
            maps = _maps_and_tests(job, sess, gest)
        with job.step("placement"):
            place = _placement(job, sess, maps)
        with job.step("skin_design"):
            design = _skin_design(job, sess, maps, place)
        result = _result(job, sess, gest, maps, place, design)
        with job.step("files"), figures.only_formats(job.st.figure_formats):
            files = write_outputs(result, sess.robot, maps.body, sess.ds, gest.model, place.budget, sess.label)
        job.finish()
    job.out_dir = result.out_dir = final
    result.files = moved(files, write_dir, final)
    for s_ in result.sentences:
        log.info("%s (%s)", s_, sess.label)
    if log_mlflow:
        result.mlflow_run_id = log_study(job.cfg, result, job.overrides, sess.ds)
    return result


@dataclass
class _Job:
    """The composed run every step reads: config, study settings, output folder, stage cache, the hand and robot
    the chains share in memory, and each step's time (s) with a progress bar over the steps."""

    overrides: list[str]
    cfg: Any
    st: ScenarioStudySchema
    out_dir: Path
    cache: Any
    memo: Any
    seconds: dict[str, float]
    shown: Any
    started: float
    """``time.perf_counter()`` at the start."""

    @contextmanager
    def step(self, name: str | None) -> Iterator[None]:
        """Time the block into ``seconds[name]`` (none when None) and advance the progress bar."""
        t = time.perf_counter()
        yield
        if name is not None:
            self.seconds[name] = time.perf_counter() - t
        self.shown.update(1)

    def finish(self) -> None:
        """The total time (s), the bar closed, ``timing.json`` written."""
        self.seconds["total"] = time.perf_counter() - self.started
        self.shown.close()
        (self.out_dir / "timing.json").write_text(json.dumps(self.seconds, indent=1))


def _start(overrides: Sequence[str], out: str | Path | None) -> _Job:
    """Compose ``overrides``, check they hold the study's settings, make the output folder, open the stage cache."""
    from sphri.config import ConfigError, compose
    from sphri.pipeline import Memo, open_cache
    from sphri.sessions.schema import study_settings

    overrides = list(overrides)
    cfg = compose(overrides)
    st = study_settings(cfg)
    if st is None:
        raise ConfigError("the scenario study needs +experiment=scenario_study (experiment.scenario_study settings)")
    out_dir = Path(out) if out else new_run_dir(Path(cfg.output_dir) / "scenario_study")
    cache = open_cache(cfg)
    started = time.perf_counter()
    shown = bar(6, "scenario study", unit="step")  # sessions, gestures, maps, placement, skin, files
    return _Job(overrides, cfg, st, out_dir, cache, Memo(), {}, shown, started)


@dataclass
class _Sessions:
    """The sessions with their contacts and episodes (:func:`sphri.sessions.labelling.segment`)."""

    hand: Any
    robot: Any
    ds: Any
    """The sessions (:class:`sphri.sessions.format.SessionDataset`)."""
    bc: Any
    """Their contacts with the whole robot (:class:`sphri.sessions.contact.BodyContacts`)."""
    episodes: pd.DataFrame
    coded: pd.DataFrame
    """The first coded episode of each session that has one."""
    notes: list[str]
    """The study's notes so far; later steps add theirs."""
    scenarios: list[str]
    label: str
    """``SYNTHETIC`` or ``recorded``."""


def _sessions(job: _Job) -> _Sessions:
    """Generate or read the sessions, their whole-body contacts and episodes (stage-cached)."""
    from sphri.sessions.labelling import segment

    hand, robot, ds, bc, _row_part, episodes, coded, notes, sec = segment(job.cfg, job.st, job.cache, job.memo)
    job.seconds.update(sec)
    label = "SYNTHETIC" if ds.synthetic else "recorded"
    scenarios = sorted(pd.unique(ds.sessions["scenario"]))
    return _Sessions(hand, robot, ds, bc, episodes, coded, notes, scenarios, label)


@dataclass
class _Gestures:
    """The coded episodes' gestures and their histogram per scenario."""

    model: Any
    """The gesture model trained in this job (its LOSO accuracy labels the figures)."""
    labelled: pd.DataFrame
    """The coded episodes with their gesture (the model's, or a person's with ``codes=PATH``)."""
    histogram: pd.DataFrame
    codes: Any
    """:class:`sphri.sessions.codes.HumanCodes`, or None."""


def _code_gestures(job: _Job, sess: _Sessions) -> _Gestures:
    """Label the coded episodes with the gesture model trained in this job; a person's codes (``codes=PATH``,
    read first: a bad file stops at once) replace its labels, the model's stay as the suggestion."""
    from sphri.sessions.codes import read_codes
    from sphri.sessions.gestures import gesture_histogram
    from sphri.sessions.labelling import label as label_gestures

    st = job.st
    codes = read_codes(st.codes, sess.coded, sess.ds, st.coder) if st.codes else None
    gm, labelled, more = label_gestures(sess.coded, sess.ds, job.overrides, st, job.cache, job.memo)
    sess.notes += more
    if codes is not None:
        labelled = codes.apply(labelled)
        sess.notes += codes.notes(labelled)
    return _Gestures(gm, labelled, gesture_histogram(labelled, sess.scenarios), codes)


@dataclass
class _Maps:
    """The whole robot's surface and the coded episodes' contact on it, mapped and tested per group."""

    body: Any
    """:class:`sphri.sessions.body.BodySurface`: elements of every link at the rest pose."""
    frame_session: np.ndarray
    """(F,) session index of each global frame."""
    frames: np.ndarray
    """(K,) global frame of each (frame, element) pair touched in a coded episode."""
    elements: np.ndarray
    """(K,) its surface element."""
    coverage: Any
    """:class:`sphri.analysis.coverage.RegionCoverage`: densities, curves and SWD tests per ``by`` group."""


def _maps_and_tests(job: _Job, sess: _Sessions, gest: _Gestures) -> _Maps:
    """Densities on the whole surface per ``by`` group (default: scenario), coverage curves and the paired SWD
    tests (paired by participant, Holm), from the contact of the coded episodes; notes on too little power."""
    from sphri.analysis.coverage import CoverageAnalysis
    from sphri.sessions.body import body_surface, touched_pairs

    st, ds, bc = job.st, sess.ds, sess.bc
    body = body_surface(
        sess.robot,
        ds.links,
        st.spacing_mm,
        st.bandwidth_mm,
        st.seed,
        floor_height_m=st.reach_floor_height_m,
        down_cos=st.reach_down_cos,
    )
    in_coded = np.zeros(ds.n_frames, dtype=bool)
    for e in sess.coded.itertuples():
        in_coded[e.start_frame : e.end_frame + 1] = True
    frames, elements = touched_pairs(body, bc, np.flatnonzero(in_coded[bc.frame]))
    analysis = CoverageAnalysis(
        by=st.by,
        pair_by="participant",
        bandwidth_mm=st.bandwidth_mm,
        spacing_mm=st.spacing_mm,
        capture=0.9,
        n_projections=st.n_projections,
        alpha=st.alpha,
        exact_max=st.exact_max,
        n_permutations=st.n_permutations,
        seed=st.seed,
        render=False,
    )
    gd = _session_trials(sess, gest.labelled)
    cov = analysis.analyze(
        gd, None, body.mesh, None, None, samples=body.samples, kernel=body.kernel, touched=(frames, elements)
    )
    sess.notes += cov.notes
    power = _power_note(cov.comparison, st)
    if power:
        sess.notes.append(power)
    return _Maps(body, ds.frame_session_index(), frames, elements, cov)


def _session_trials(sess: _Sessions, labelled: pd.DataFrame):
    """The sessions as the trials of a :class:`sphri.types.GestureDataset` (one trial per session, region
    ``body``, its coded gesture and the right hand's poses), the form :class:`CoverageAnalysis` reads."""
    from sphri.types import GestureDataset

    ds = sess.ds
    trials = pd.DataFrame(
        {
            "participant": ds.sessions["participant"],
            "region": "body",
            "trial_ordinal": ds.sessions["repetition"],
            "trial_id": [f"{i:04d}_hit" for i in range(len(ds.sessions))],
            "gesture": session_gestures(len(ds.sessions), labelled),
            "start": ds.sessions["start"],
            "n_frames": ds.sessions["n_frames"],
            "scenario": ds.sessions["scenario"],
            "start_position": ds.sessions["start_position"],
            "repetition": ds.sessions["repetition"].astype(str),
        }
    )
    return GestureDataset(
        name=ds.name,
        synthetic=ds.synthetic,
        hand=sess.hand,
        trials=trials,
        poses=ds.hand_poses[:, 1],
        frame_rate_hz=ds.frame_rate_hz,
    )


def _power_note(comp, st: ScenarioStudySchema) -> str | None:
    """A note when, with this few participants, even the smallest exact Holm-corrected p over the pairs exceeds
    ``alpha`` (with the participants needed), else None."""
    if comp is None:
        return None
    n_max = int(comp.table["n_participants"].max()) if len(comp.table) else 0
    m = len(comp.table)
    if not (n_max and n_max <= st.exact_max and m * 2.0**-n_max > st.alpha):
        return None
    need = int(np.ceil(np.log2(m / st.alpha)))
    return (
        f"power: with {n_max} participants the smallest Holm-corrected p over {m} scenario pairs is "
        f"{m} x 2^-{n_max} = {m * 2.0**-n_max:.3g} > alpha {st.alpha:g}: no pair can reach "
        f"significance; at least {need} participants are needed"
    )


@dataclass
class _Parts:
    """The body parts a skin can reach (reachable area > 0), and which of them can hold one."""

    names: list[str]
    area_m2: np.ndarray
    """(N,) reachable area of each part (m^2)."""
    index: dict[str, int]
    mountable: pd.DataFrame
    """Every part of the surface: width, reachable area, whether mountable and why not
    (:func:`sphri.sessions.placement.mountable_parts`)."""
    excluded: dict[str, str]
    """Reachable parts that cannot hold a skin -> why."""
    allowed: np.ndarray
    """(N,) bool: mountable."""


@dataclass
class _Placement:
    """Body parts ranked and the greedy placement under the budget."""

    parts: _Parts
    ranking: pd.DataFrame
    """Per part and scenario (and ``all``, with the robot's part groups): frames per cm^2 of reachable area."""
    table: pd.DataFrame
    """The placement pooled and per scenario, with the held-out capture."""
    sentences: list[str]
    budget: str
    """The budget in words (cm^2, or taxels at a pitch)."""
    sensitivity: Any
    """The priors sensitivity run (per-draw table, summary), or None."""


def _placement(job: _Job, sess: _Sessions, maps: _Maps) -> _Placement:
    """Rank the body parts by contact frames per cm^2 of reachable surface (pooled and per scenario) and place a
    skin under the budget on the mountable ones (greedy, checked on held-out participants); with generated
    sessions, the ranking under perturbed priors."""
    from sphri.sessions.placement import frame_part_matrix, placement_table, sentence

    st, ds, robot, body = job.st, sess.ds, sess.robot, maps.body
    parts = _reachable_parts(body, robot, st, sess.notes)
    pidx = np.array([parts.index.get(p, 0) for p in body.part], dtype=np.int64)
    sel = body.reachable[maps.elements]
    uf, mat = frame_part_matrix(maps.frames[sel], maps.elements[sel], pidx, len(parts.names))
    f_scen = ds.sessions["scenario"].to_numpy()[maps.frame_session[uf]]
    f_unit = ds.sessions["participant"].to_numpy()[maps.frame_session[uf]]
    ranking = _ranking(mat, f_scen, sess.scenarios, parts, robot.groups)
    table = placement_table(
        mat, f_scen, f_unit, sess.scenarios, parts.names, parts.area_m2, st.budget_m2, parts.allowed
    )
    sentences = [sentence(r, robot.groups) for _, r in table.iterrows()]
    budget = (
        f"{st.budget_taxels} taxels at {st.pitch_mm:g} mm pitch ({st.budget_m2 * 1e4:.0f} cm^2)"
        if st.budget_taxels
        else f"{st.budget_cm2:g} cm^2"
    )
    sensitivity = _sensitivity(
        job.cfg, st, ds, robot, mat, maps.frame_session[uf], parts.names, parts.area_m2, parts.allowed
    )
    return _Placement(parts, ranking, table, sentences, budget, sensitivity)


def _reachable_parts(body, robot, st: ScenarioStudySchema, notes: list[str]) -> _Parts:
    """The parts with reachable surface (:func:`sphri.sessions.body.reachable_elements`: areas, densities per cm^2
    and budgets count only what a skin can cover) and which are mountable: no rotating joint, no rod narrower
    than ``min_diameter_mm``, nothing below ``min_patch_cm2``; a note names those left out."""
    from sphri.sessions.placement import mountable_parts

    reach_area = body.part_area_m2(reachable=True)
    parts = [p for p in body.parts if reach_area[p] > 0]
    mount = mountable_parts(body, robot, reach_area, st.min_diameter_mm, st.min_patch_cm2)
    reasons = dict(zip(mount["part"], mount["reason"]))
    if (mount["reason"] != "").any():
        notes.append(
            "body parts left out of ranking, placement and skin design (not mountable): "
            + "; ".join(f"{r.part}: {r.reason}" for r in mount.itertuples() if r.reason)
        )
    excluded = {p: reasons[p] for p in parts if reasons[p]}
    return _Parts(
        names=parts,
        area_m2=np.array([reach_area[p] for p in parts]),
        index={p: i for i, p in enumerate(parts)},
        mountable=mount,
        excluded=excluded,
        allowed=np.array([p not in excluded for p in parts]),
    )


def _ranking(
    mat: np.ndarray, f_scen: np.ndarray, scenarios: list[str], parts: _Parts, groups: Mapping[str, Sequence[str]]
) -> pd.DataFrame:
    """The ranking of the parts (:func:`sphri.sessions.placement.rank_parts`) over all contact frames
    (``mat``: (U, N) bool, frame touches part), then per scenario, then the robot's part ``groups`` pooled."""
    from sphri.sessions.placement import rank_parts

    ranking = rank_parts(mat, parts.names, parts.area_m2, parts.excluded)
    ranking.insert(0, "scenario", "all")
    per = [ranking]
    for s in scenarios:
        r = rank_parts(mat[f_scen == s], parts.names, parts.area_m2, parts.excluded)
        r.insert(0, "scenario", s)
        per.append(r)
    group_rows = []
    for g, members in groups.items():
        cols = [parts.index[p] for p in members if p in parts.index]
        if not cols:
            continue
        a = float(parts.area_m2[cols].sum())
        n = int(mat[:, cols].any(axis=1).sum())
        left_out = [p for p in members if p in parts.excluded]
        group_rows.append(
            dict(
                scenario="all",
                part=f"group:{g}",
                area_cm2=a * 1e4,
                contact_frames=n,
                frame_share=n / max(len(mat), 1),
                frames_per_cm2=n / (a * 1e4),
                excluded=("holds parts not mountable: " + ", ".join(left_out) if left_out else ""),
            )
        )
    return pd.concat(per + [pd.DataFrame(group_rows)], ignore_index=True)


def _skin_design(job: _Job, sess: _Sessions, maps: _Maps, place: _Placement):
    """The skin design (:func:`sphri.sessions.skin.skin_design`): mountable parts split into patches of about
    ``patch_cm2``, chosen greedily by captured contact per cm^2 under the budget, the budget curve in-sample and
    on held-out participants."""
    from sphri.sessions.skin import skin_design

    st, mount = job.st, place.parts.mountable
    return skin_design(
        maps.body,
        maps.frames,
        maps.elements,
        maps.frame_session,
        sess.ds.sessions,
        sess.scenarios,
        st.patch_cm2,
        st.design_pitch_mm,
        st.budget_m2,
        st.heldout_splits,
        st.seed,
        mountable=np.isin(maps.body.part, mount.loc[mount["mountable"], "part"].to_numpy()),
    )


def _result(job: _Job, sess: _Sessions, gest: _Gestures, maps: _Maps, place: _Placement, design) -> StudyResult:
    """The steps' results in one :class:`StudyResult`, with the synthetic hands' plausibility checks."""
    return StudyResult(
        job.out_dir,
        job.st,
        sess.ds.synthetic,
        sess.ds.sessions,
        sess.episodes,
        gest.labelled,
        gest.histogram,
        place.ranking,
        place.table,
        place.sentences,
        maps.coverage.comparison,
        maps.coverage,
        sess.notes,
        [],
        job.seconds,
        gest.model.accuracy_mean,
        design=design,
        truth=sess.ds.truth,
        codes=gest.codes,
        mountable=place.parts.mountable,
        plausibility=_plausibility(job.cfg, sess.ds, sess.bc, sess.robot, sess.notes),
        sensitivity=place.sensitivity,
    )


def _mask_npz(body, density: np.ndarray, chosen: set[str], out_dir: Path) -> list[Path]:
    """Per link holding chosen parts: ``placement_<link>.npz`` for ``layout=density layout.density_path=...``
    (``points_m``/``normal`` in the link frame, ``density`` = the pooled density on the chosen parts (a
    floor of 5 % of its peak keeps every chosen element), 0 elsewhere; ``mask``, ``area_m2``, ``part``)."""
    files = []
    for li, name in enumerate(body.links):
        sl = slice(body.offset[li], body.offset[li + 1])
        mask = np.isin(body.part[sl], list(chosen))
        if not mask.any():
            continue
        d = density[sl]
        dens = np.where(mask, d + 0.05 * max(float(d.max()), 1e-12), 0.0)
        s = body.local[li]
        path = out_dir / f"placement_{name}.npz"
        np.savez_compressed(
            path,
            points_m=s.points_m,
            normal=s.normal,
            density=dens,
            mask=mask,
            area_m2=s.area_m2,
            part=body.part[sl].astype(str),
        )
        files.append(path)
    return files


def write_outputs(res: StudyResult, robot, body, ds, gm, budget: str, label: str) -> list[Path]:
    """Write the study's files under ``res.out_dir``: maps, tables, skin design and export, SWD tests,
    ``placement_<link>.npz``, ``summary.json``; with ``render``, the figures and ``report.html``. Returns
    their paths."""
    from sphri.analysis.coverage import ALL

    out = res.out_dir
    files = _write_maps(res, body)
    areas = body.area_table()
    files += _write_tables(res, robot, areas)
    files += _design_and_gesture_files(res, body, robot, out)
    if res.comparison is not None:
        files += res.comparison.write_csv(out, "swd")
        _effects(res.comparison).to_csv(out / "swd_effects.csv", index=False, float_format="%.5g")
        files.append(out / "swd_effects.csv")
    chosen = set(str(res.placement.loc[res.placement["group"] == "all", "parts"].iat[0]).split(";")) - {""}
    files += _mask_npz(body, res.coverage.densities[ALL], chosen, out)
    (out / "placement.txt").write_text("\n".join(res.sentences) + f"\n(budget {budget}; {label})\n")
    files.append(out / "placement.txt")
    summary = _summary(res, robot, ds, gm, areas, budget)
    if res.sensitivity is not None:
        res.sensitivity[0].to_csv(out / "priors_sensitivity.csv", index=False, float_format="%.4g")
        files.append(out / "priors_sensitivity.csv")
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    files.append(out / "summary.json")
    if res.settings.render:
        files += _write_figures(res, body, ds, gm, budget, label, summary)
    return files


def _write_maps(res: StudyResult, body) -> list[Path]:
    """``density_maps.npz`` (elements: points, normals, area, part, link; density (1/m^2) and contact counts per
    group, pooled density) and ``density_maps.csv`` (per element, densities in 1/cm^2)."""
    from sphri.analysis.coverage import ALL

    out = res.out_dir
    cov = res.coverage
    scen = cov.groups
    np.savez_compressed(
        out / "density_maps.npz",
        points_m=body.samples.points_m,
        normal=body.samples.normal,
        area_m2=body.samples.area_m2,
        part=body.part.astype(str),
        link=np.array(body.links)[body.link_of],
        scenarios=np.array(scen),
        density=np.stack([cov.densities[s] for s in scen]),
        pooled=cov.densities[ALL],
        counts=np.stack([cov.counts[s] for s in scen]),
    )
    per = pd.DataFrame(
        {
            "element": np.arange(body.samples.n),
            "link": np.array(body.links)[body.link_of],
            "part": body.part,
            "area_cm2": body.samples.area_m2 * 1e4,
            **{f"density_{s}": cov.densities[s] * 1e-2 for s in [ALL] + scen},
        }
    )
    per.to_csv(out / "density_maps.csv", index=False, float_format="%.6g")
    return [out / "density_maps.npz", out / "density_maps.csv"]


def _write_tables(res: StudyResult, robot, areas: pd.DataFrame) -> list[Path]:
    """The tables: mountable parts, body part areas (``areas``, cm^2), the links a URDF robot has no surface for,
    sessions, episodes, coded episodes, gesture histogram, ranking and placement."""
    out = res.out_dir
    res.mountable.to_csv(out / "mountable_parts.csv", index=False, float_format="%.4g")
    areas.to_csv(out / "body_part_area.csv", index=False, float_format="%.1f")
    files = [out / "mountable_parts.csv", out / "body_part_area.csv"]
    if getattr(robot, "skipped", ()):  # a robot read from a URDF: what has no surface here, and why
        pd.DataFrame(list(robot.skipped), columns=["link", "reason"]).to_csv(
            out / "robot_skipped_links.csv", index=False
        )
        files.append(out / "robot_skipped_links.csv")
    for name, table, fmt in (
        ("sessions", res.sessions, None),
        ("episodes", res.episodes, None),
        ("coded_episodes", res.coded, "%.4g"),
        ("gesture_histogram", res.histogram, "%.4g"),
        ("body_part_ranking", res.ranking, "%.5g"),
        ("placement", res.placement, "%.4g"),
    ):
        table.to_csv(out / f"{name}.csv", index=False, float_format=fmt)
        files.append(out / f"{name}.csv")
    return files


def _summary(res: StudyResult, robot, ds, gm, areas: pd.DataFrame, budget: str) -> dict:
    """``summary.json``: the dataset, the gesture model, the surface's areas (cm^2), the budget, the parts left
    out, codes, plausibility, sensitivity, the skin design and export, sentences, notes, times and settings;
    with the generator's draws, how well the episodes' labels agree with them."""
    st, manifest = res.settings, res.out_dir / "skin_export" / "manifest.json"
    summary = {
        "dataset": ds.name,
        "synthetic": ds.synthetic,
        "robot": robot.name,
        "n_participants": int(ds.sessions["participant"].nunique()),
        "n_sessions": int(len(ds.sessions)),
        "scenarios": res.coverage.groups,
        "n_coded_episodes": int(len(res.coded)),
        "gesture_model": {
            "training": gm.training,
            "regions": gm.regions,
            "loso_accuracy": gm.accuracy,
            "res": gm.res,
            "loso_accuracy_mean": gm.accuracy_mean,
            "loso_accuracy_std": gm.accuracy_std,
            "n_trials": gm.n_trials,
        },
        "surface": {
            **{c: float(areas[c].sum()) for c in ("area_cm2", "reachable_cm2", "floor_facing_cm2", "buried_cm2")},
            "floor_height_m": st.reach_floor_height_m,
            "down_cos": st.reach_down_cos,
        },
        "budget": budget,
        "mountable": {
            "criterion": "contact frames per cm^2 of a mountable part's reachable surface (ranking and greedy)",
            "min_diameter_mm": st.min_diameter_mm,
            "min_patch_cm2": st.min_patch_cm2,
            "excluded": [
                {"part": r.part, "reason": r.reason, "width_mm": round(float(r.width_mm), 1)}
                for r in res.mountable.itertuples()
                if r.reason
            ],
        },
        "human_codes": res.codes.summary(res.coded) if res.codes is not None else None,
        "plausibility": res.plausibility,
        "priors_sensitivity": res.sensitivity[1] if res.sensitivity is not None else None,
        "skin_design": _design_summary(res.design),
        "skin_export": {k: v for k, v in json.loads(manifest.read_text()).items() if k != "patches"},  # totals
        "sentences": res.sentences,
        "notes": res.notes,
        "seconds": res.seconds,
        "settings": dataclasses.asdict(st),
    }
    if ds.truth is not None and len(res.coded):
        summary["against_generator"] = _against_generator(res.coded, ds.truth)
    return summary


def _against_generator(coded: pd.DataFrame, truth: pd.DataFrame) -> dict:
    """Share of the coded episodes whose gesture (of those labelled) and dominant part are the generator's."""
    tr = truth.reset_index(drop=True)
    truth_g = tr["gesture"].to_numpy()[coded["session"].to_numpy()]
    truth_p = tr["part"].to_numpy()[coded["session"].to_numpy()]
    ok = coded["gesture"].to_numpy() != ""
    return {
        "gesture_agreement": float((coded["gesture"].to_numpy()[ok] == truth_g[ok]).mean()) if ok.any() else None,
        "dominant_part_agreement": float((coded["dominant_part"].to_numpy() == truth_p).mean()),
    }


def _write_figures(res: StudyResult, body, ds, gm, budget: str, label: str, summary: dict) -> list[Path]:
    """The figures (each marked SYNTHETIC or with the dataset's name), the density PLY and ``report.html``."""
    from sphri.figures import Provenance
    from sphri.sessions.render import body_view, plot_placement

    out = res.out_dir
    prov = Provenance(synthetic=bool(ds.synthetic), ids=ds.name)  # one banner on every figure (sphri.figures.mark)
    view = body_view(body, res.settings.view_faces)
    figs: dict[str, Path] = {}
    files = _map_figures(res, body, view, prov, figs)
    _test_and_gesture_figures(res, ds, gm, prov, figs)
    _design_figures(res, view, budget, prov, figs)
    figs["placement"] = plot_placement(
        res.ranking[res.ranking["scenario"] == "all"].query("~part.str.startswith('group:')"),
        res.placement,
        out / "placement.png",
        f"Placement under {budget}",
        provenance=prov,
    )
    files += list(figs.values())
    files.append(write_report(res, figs, summary, budget, label, out / "report.html"))
    return files


def _map_figures(res: StudyResult, body, view, prov, figs: dict[str, Path]) -> list[Path]:
    """The density views of every group on one colour scale (``figs["maps"]``), one figure per group on that
    scale, the pooled atlas (``figs["atlas"]``); returns the per-group figures and the density PLY."""
    from sphri.analysis.coverage import ALL, safe_name
    from sphri.analysis.render import _vmax
    from sphri.figures import human
    from sphri.sessions.render import plot_atlas, plot_views, write_density_ply

    out, cov = res.out_dir, res.coverage
    scen = cov.groups
    dens = {s: cov.densities[s] for s in scen}
    figs["maps"] = plot_views(
        view,
        {**dens, "pooled": cov.densities[ALL]},
        out / "maps_views.png",
        f"Contact density per {cov.by}, one colour scale",
        provenance=prov,
    )
    top = _vmax([*dens.values(), cov.densities[ALL]])  # every scenario's own figure on the maps' one scale
    files = [
        plot_views(
            view, {s: cov.densities[s]}, out / f"map_{safe_name(s)}.png", f"{human(s)}", provenance=prov, vmax=top
        )
        for s in scen
    ]
    figs["atlas"] = plot_atlas(
        body,
        cov.densities[ALL],
        out / "atlas_pooled.png",
        "Atlas of the whole surface, pooled over scenarios",
        provenance=prov,
    )
    files.append(write_density_ply(view, {"pooled": cov.densities[ALL], **dens}, out / "density_mesh.ply"))
    return files


def _test_and_gesture_figures(res: StudyResult, ds, gm, prov, figs: dict[str, Path]) -> None:
    """``figs["swd"]`` and ``figs["effects"]`` (the SWD tests, when run) and ``figs["gestures"]`` (the coded
    episodes' gestures per scenario, with the generator's shares for synthetic sessions)."""
    from sphri.analysis.render import plot_swd_heatmap
    from sphri.sessions.render import drawn_shares, plot_effects, plot_gesture_histogram

    out = res.out_dir
    if res.comparison is not None:
        figs["swd"] = plot_swd_heatmap(
            res.comparison, out / "swd_matrix.png", "Scenario maps: paired sliced Wasserstein", provenance=prov
        )
        figs["effects"] = plot_effects(
            _effects(res.comparison),
            res.coverage.groups,
            res.settings.alpha,
            out / "swd_effects.png",
            "Scenario maps differ? Paired effect per pair",
            provenance=prov,
        )
    figs["gestures"] = plot_gesture_histogram(
        res.histogram,
        out / "gesture_histogram.png",
        f"Gestures of the coded episodes per scenario, coded by {res.codes.coder}"
        if res.codes is not None
        else f"Gestures of the coded episodes per scenario ({_model_words(gm)})",
        provenance=prov,
        drawn=drawn_shares(res.coded, ds.truth) if ds.truth is not None and len(res.coded) else None,
    )


def _model_words(gm) -> str:
    """How the gesture model was trained and how well it did, for a figure title."""
    if gm.training == "episodes":
        return f"model of the other participants' episodes: {100 * gm.accuracy_mean:.0f} % agreement"
    return f"model LOSO accuracy {100 * gm.accuracy_mean:.0f} %"


def _design_figures(res: StudyResult, view, budget: str, prov, figs: dict[str, Path]) -> None:
    """``figs["budget_curve"]`` (contact captured against skin area) and ``figs["skin"]`` (the pooled density on
    the chosen patches) of the skin design."""
    from sphri.analysis.coverage import ALL
    from sphri.sessions.skin_render import plot_budget_curve, plot_skin

    d, out = res.design, res.out_dir
    figs["budget_curve"] = plot_budget_curve(
        d.curves,
        d.pitch_mm,
        d.budget_m2 * 1e4,
        out / "budget_curve.png",
        f"Contact captured against skin area, patches of ~{res.settings.patch_cm2:g} cm$^2$",
        provenance=prov,
    )
    figs["skin"] = plot_skin(
        view,
        res.coverage.densities[ALL],
        d.element_mask,
        out / "skin_design.png",
        f"The recommended skin under {budget}: pooled density on the chosen patches",
        provenance=prov,
    )


def _design_and_gesture_files(res: StudyResult, body, robot, out: Path) -> list[Path]:
    """The skin design's files (``sphri.sessions.skin.write_design``), gesture counts with participant-bootstrap
    intervals and, for synthetic sessions, the confusion of episode labels against the generator."""
    from sphri.sessions.gesture_report import confusion_against_generator, gesture_counts
    from sphri.sessions.skin import write_design

    files = write_design(res.design, body, robot, out, res.settings.export_format, res.settings.min_patch_cm2)
    meta = json.loads((out / "skin_export" / "manifest.json").read_text())
    if meta["dropped_pieces"]:
        res.notes.append(
            f"skin export: {meta['dropped_pieces']} piece(s) of chosen patches below min_patch_cm2="
            f"{res.settings.min_patch_cm2:g} dropped ({meta['dropped_area_cm2']:.1f} cm^2); "
            f"{len(meta['patches'])} connected pieces exported"
        )
    scen = sorted(pd.unique(res.sessions["scenario"]))
    gesture_counts(res.coded, scen, seed=res.settings.seed).to_csv(
        out / "gesture_counts.csv", index=False, float_format="%.4g"
    )
    files.append(out / "gesture_counts.csv")
    if res.truth is not None and len(res.coded):
        confusion_against_generator(res.coded, res.truth).to_csv(out / "gesture_confusion.csv", float_format="%.4g")
        files.append(out / "gesture_confusion.csv")
    return files


def _plausibility(cfg, ds, bc, robot, notes: list[str]) -> dict | None:
    """The ``plausibility`` block of generated sessions (with the generator's draws), else None; a failed check
    adds a note. Sessions generated before version 5 (no planned contact phase in the truth table) get none."""
    from sphri.sessions.plausibility import TRUTH_COLUMNS, plausibility

    if not ds.synthetic or ds.truth is None or any(c not in ds.truth for c in TRUTH_COLUMNS):
        return None

    block = plausibility(ds, bc, robot, float(cfg.data.get("compliance_mm", 5.0)))
    failed = [k[:-3] for k in ("penetration_ok", "on_drawn_part_ok", "timing_ok") if not block[k]]
    if failed:
        notes.append(f"synthetic hands fail the plausibility checks {failed} (summary.json: plausibility)")
    return block


def _sensitivity(cfg, st, ds, robot, mat, frame_session, parts, area, allowed):
    """The priors sensitivity run on generated sessions drawn from a priors table (``data=synthetic_sessions``),
    else None (recorded sessions, or ``sensitivity_draws=0``)."""
    priors = cfg.data.get("priors", False) if hasattr(cfg.data, "get") else False
    if st.sensitivity_draws == 0 or ds.truth is None or priors is False or "part" not in ds.truth:
        return None
    from sphri.sessions.sensitivity import priors_sensitivity
    from sphri.sessions.synthetic import DEFAULT_PRIORS, load_priors

    table = load_priors(priors or DEFAULT_PRIORS, [p.name for p in robot.parts])
    truth = ds.truth.reset_index(drop=True).assign(start_position=ds.sessions["start_position"].to_numpy())
    return priors_sensitivity(
        table, truth, frame_session, mat, parts, area, allowed, st.sensitivity_draws, st.seed, st.sensitivity_top_k
    )


def _design_summary(design) -> dict:
    row = design.placement.iloc[0]
    pooled = design.curves[(design.curves["scenario"] == "all")]
    out = {
        "patches": int(len(design.patches.table)),
        "pitch_mm": design.pitch_mm,
        "budget_cm2": design.budget_m2 * 1e4,
        "chosen_patches": int(row["n_patches"]),
        "area_cm2": float(row["area_cm2"]),
        "captured": float(row["captured"]),
        "heldout_captured": float(row["heldout_captured"]),
    }
    for kind in ("in_sample", "heldout"):
        c = pooled[pooled["curve"] == kind]
        if len(c):  # the smallest area on the curve capturing 90 % of the frames
            hit = c[c["captured"] >= 0.9]
            out[f"area_cm2_for_90pct_{kind}"] = float(hit["area_cm2"].iat[0]) if len(hit) else None
    return out


def _effects(comp) -> pd.DataFrame:
    """Per pair: mean paired SWD difference (mm), its standardized size d_z = mean / SD over participants, p, p_holm."""
    pp = comp.per_participant
    rows = []
    for r in comp.table.itertuples(index=False):
        d = pp[(pp["cond_a"] == r.cond_a) & (pp["cond_b"] == r.cond_b)]["diff_mm"].to_numpy(float)
        sd = float(d.std(ddof=1)) if d.size > 1 else float("nan")
        rows.append(
            dict(
                cond_a=r.cond_a,
                cond_b=r.cond_b,
                n_participants=r.n_participants,
                between_swd_mm=r.mean_between_swd_mm,
                within_swd_mm=r.mean_within_swd_mm,
                diff_swd_mm=r.mean_diff_swd_mm,
                effect_dz=float(d.mean() / sd) if sd and sd == sd else float("nan"),
                p_value=r.p_value,
                p_holm=r.p_holm,
                significant=r.significant,
            )
        )
    return pd.DataFrame(rows)


def write_report(res: StudyResult, figs: dict, summary: dict, budget: str, label: str, path: Path) -> Path:
    """A self-contained HTML page (``sphri/templates/scenario_study.html.j2``): every figure embedded, the tables,
    the placement sentences."""
    from sphri.templating import render_page

    page = render_page(
        "scenario_study.html.j2",
        label=label,
        summary=summary,
        gm=summary["gesture_model"],
        budget=budget,
        episode_gap_s=res.settings.episode_gap_s,
        sentences=res.sentences,
        notes=res.notes,
        figs=figs,
        placement=res.placement,
        effects=_effects(res.comparison) if "swd" in figs else None,
        design=(res.design.placement.drop(columns=["patches"]) if "budget_curve" in figs else None),
        patch_cm2=res.settings.patch_cm2,
        histogram=res.histogram.pivot(index="scenario", columns="gesture", values="count").reset_index(),
        ranking=res.ranking[res.ranking["scenario"] == "all"],
        timing=json.dumps({k: round(v, 1) for k, v in res.seconds.items()}),
    )
    path.write_text(page, encoding="utf-8")
    return path


def log_study(cfg, res: StudyResult, overrides: Sequence[str], ds) -> str | None:
    """One MLflow run tagged ``sphri.kind=scenario_study``: settings, numbers, every file."""
    from mlflow.entities import Metric, Param

    from sphri.tracking.mlflow_tracker import log_analysis_run

    tags = {
        "sphri.dataset": ds.name,
        "sphri.synthetic": str(ds.synthetic).lower(),
        "sphri.study_dir": str(res.out_dir.resolve()),
        "mlflow.note.content": "\n".join(res.sentences),
    }

    def numbers() -> tuple[list[Metric], list[Param]]:
        now = int(time.time() * 1000)
        params = [Param(f"study.{k}", str(v)) for k, v in dataclasses.asdict(res.settings).items()]
        params.append(Param("overrides", " ".join(overrides)[:500]))
        metrics = [Metric(f"time/{k}_s", float(v), now, 0) for k, v in res.seconds.items()]
        metrics.append(Metric("gesture_model/loso_accuracy", float(res.gesture_accuracy), now, 0))
        for r in res.placement.itertuples():
            for k in ("captured", "heldout_captured", "area_share"):
                v = float(getattr(r, k))
                if v == v:
                    metrics.append(Metric(f"placement/{k}/{r.group}", v, now, 0))
        if res.comparison is not None:
            for r in res.comparison.table.itertuples():
                if r.p_holm == r.p_holm:
                    metrics.append(Metric(f"swd/p_holm/{r.cond_a}-{r.cond_b}", float(r.p_holm), now, 0))
        return metrics, params

    return log_analysis_run(cfg, "scenario_study", "scenario_study", tags, numbers, res.out_dir)
