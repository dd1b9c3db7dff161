"""The whole-body scenario study: ``python -m sphri.coverage +experiment=scenario_study``.

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

Sessions and contacts are the stages of :data:`sphri.stages.SESSION_STAGES` (computed in
:mod:`sphri.sessions.labelling`), wired by
:func:`sphri.pipeline.make_pipeline` like every chain (keys: data, hand, robot and
contact configs, component versions and input-file fingerprints), so re-running with
other study settings recomputes neither; the gesture chains of the same job share
their hand and robot in memory (:class:`sphri.pipeline.Memo`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri import figures
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
    """Run the study for the composed ``overrides`` (they must select ``+experiment=scenario_study``)."""
    from sphri.analysis.coverage import CoverageAnalysis
    from sphri.config import ConfigError, compose
    from sphri.pipeline import Memo, open_cache
    from sphri.sessions.body import body_surface, touched_pairs
    from sphri.sessions.codes import read_codes
    from sphri.sessions.gestures import gesture_histogram
    from sphri.sessions.labelling import label as label_gestures
    from sphri.sessions.labelling import segment
    from sphri.sessions.placement import frame_part_matrix, mountable_parts, placement_table, rank_parts, sentence
    from sphri.sessions.schema import study_settings
    from sphri.types import GestureDataset

    overrides = list(overrides)
    cfg = compose(overrides)
    st = study_settings(cfg)
    if st is None:
        raise ConfigError("the scenario study needs +experiment=scenario_study (experiment.scenario_study settings)")
    out_dir = Path(out) if out else Path(cfg.output_dir) / "scenario_study" / time.strftime("%Y-%m-%d_%H-%M-%S")
    out_dir.mkdir(parents=True, exist_ok=True)
    cache = open_cache(cfg)
    seconds: dict[str, float] = {}
    t_all = time.perf_counter()
    shown = bar(6, "scenario study", unit="step")  # sessions, gestures, maps, placement, skin, files

    memo = Memo()  # the sessions' chain and the gesture chains share the hand and robot
    hand, robot, ds, bc, _row_part, episodes, coded, notes, sec = segment(cfg, st, cache, memo)
    seconds.update(sec)
    shown.update(1)
    label = "SYNTHETIC" if ds.synthetic else "recorded"
    scenarios = sorted(pd.unique(ds.sessions["scenario"]))
    codes = (
        read_codes(st.codes, coded, ds, st.coder) if st.codes else None
    )  # before the model: a bad file stops at once

    # gesture model, trained in this job on the gesture dataset, labels the coded episodes
    t = time.perf_counter()
    gm, labelled, more = label_gestures(coded, ds, overrides, st, cache, memo)
    notes += more
    if codes is not None:  # a person's codes replace the model's labels; the model's stay as the suggestion
        labelled = codes.apply(labelled)
        notes += codes.notes(labelled)
    hist = gesture_histogram(labelled, scenarios)
    seconds["gestures"] = time.perf_counter() - t
    shown.update(1)

    # whole-body maps, tests and coverage curves (by scenario, paired by participant)
    t = time.perf_counter()
    body = body_surface(
        robot,
        ds.links,
        st.spacing_mm,
        st.bandwidth_mm,
        st.seed,
        floor_height_m=st.reach_floor_height_m,
        down_cos=st.reach_down_cos,
    )
    fsi = ds.frame_session_index()
    in_coded = np.zeros(ds.n_frames, dtype=bool)
    for e in coded.itertuples():
        in_coded[e.start_frame : e.end_frame + 1] = True
    rows = np.flatnonzero(in_coded[bc.frame])
    frames, elements = touched_pairs(body, bc, rows)
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
    gd = GestureDataset(
        name=ds.name,
        synthetic=ds.synthetic,
        hand=hand,
        trials=trials,
        poses=ds.hand_poses[:, 1],
        frame_rate_hz=ds.frame_rate_hz,
    )
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
    cov = analysis.analyze(
        gd, None, body.mesh, None, None, samples=body.samples, kernel=body.kernel, touched=(frames, elements)
    )
    notes += cov.notes
    comp = cov.comparison
    if comp is not None:
        n_max = int(comp.table["n_participants"].max()) if len(comp.table) else 0
        m = len(comp.table)
        if n_max and n_max <= st.exact_max and m * 2.0**-n_max > st.alpha:
            need = int(np.ceil(np.log2(m / st.alpha)))
            notes.append(
                f"power: with {n_max} participants the smallest Holm-corrected p over {m} scenario pairs is "
                f"{m} x 2^-{n_max} = {m * 2.0**-n_max:.3g} > alpha {st.alpha:g}: no pair can reach "
                f"significance; at least {need} participants are needed"
            )
    seconds["maps_and_tests"] = time.perf_counter() - t
    shown.update(1)

    # body parts ranked, placement under the budget (pooled and per scenario, held-out participants)
    t = time.perf_counter()
    # areas, densities per cm^2 and budgets count only what a skin can cover (sphri.sessions.body.reachable_elements)
    reach_area = body.part_area_m2(reachable=True)
    parts = [p for p in body.parts if reach_area[p] > 0]
    # only mountable parts are ranked first and placed: no rotating joint, no rod, nothing below min_patch_cm2
    mount = mountable_parts(body, robot, reach_area, st.min_diameter_mm, st.min_patch_cm2)
    reasons = dict(zip(mount["part"], mount["reason"]))
    if (mount["reason"] != "").any():
        notes.append(
            "body parts left out of ranking, placement and skin design (not mountable): "
            + "; ".join(f"{r.part}: {r.reason}" for r in mount.itertuples() if r.reason)
        )
    excluded = {p: reasons[p] for p in parts if reasons[p]}
    allowed = np.array([p not in excluded for p in parts])
    part_index = {p: i for i, p in enumerate(parts)}
    pidx = np.array([part_index.get(p, 0) for p in body.part], dtype=np.int64)
    sel = body.reachable[elements]
    uf, mat = frame_part_matrix(frames[sel], elements[sel], pidx, len(parts))
    area = np.array([reach_area[p] for p in parts])
    f_scen = ds.sessions["scenario"].to_numpy()[fsi[uf]]
    f_unit = ds.sessions["participant"].to_numpy()[fsi[uf]]
    ranking = rank_parts(mat, parts, area, excluded)
    ranking.insert(0, "scenario", "all")
    per = [ranking]
    for s in scenarios:
        r = rank_parts(mat[f_scen == s], parts, area, excluded)
        r.insert(0, "scenario", s)
        per.append(r)
    group_rows = []
    for g, members in robot.groups.items():
        cols = [part_index[p] for p in members if p in part_index]
        if not cols:
            continue
        a = float(area[cols].sum())
        n = int(mat[:, cols].any(axis=1).sum())
        group_rows.append(
            dict(
                scenario="all",
                part=f"group:{g}",
                area_cm2=a * 1e4,
                contact_frames=n,
                frame_share=n / max(len(uf), 1),
                frames_per_cm2=n / (a * 1e4),
                excluded=(
                    "holds parts not mountable: " + ", ".join(p for p in members if p in excluded)
                    if any(p in excluded for p in members)
                    else ""
                ),
            )
        )
    ranking_all = pd.concat(per + [pd.DataFrame(group_rows)], ignore_index=True)
    placement = placement_table(mat, f_scen, f_unit, scenarios, parts, area, st.budget_m2, allowed)
    sentences = [sentence(r, robot.groups) for _, r in placement.iterrows()]
    budget = (
        f"{st.budget_taxels} taxels at {st.pitch_mm:g} mm pitch ({st.budget_m2 * 1e4:.0f} cm^2)"
        if st.budget_taxels
        else f"{st.budget_cm2:g} cm^2"
    )
    sensitivity = _sensitivity(cfg, st, ds, robot, mat, fsi[uf], parts, area, allowed)
    seconds["placement"] = time.perf_counter() - t
    shown.update(1)

    # the skin design: patches within parts, greedy by captured contact per cm^2, budget curve, export
    t = time.perf_counter()
    from sphri.sessions.skin import skin_design

    design = skin_design(
        body,
        frames,
        elements,
        fsi,
        ds.sessions,
        scenarios,
        st.patch_cm2,
        st.design_pitch_mm,
        st.budget_m2,
        st.heldout_splits,
        st.seed,
        mountable=np.isin(body.part, mount.loc[mount["mountable"], "part"].to_numpy()),
    )
    seconds["skin_design"] = time.perf_counter() - t
    shown.update(1)

    result = StudyResult(
        out_dir,
        st,
        ds.synthetic,
        ds.sessions,
        episodes,
        labelled,
        hist,
        ranking_all,
        placement,
        sentences,
        comp,
        cov,
        notes,
        [],
        seconds,
        gm.accuracy_mean,
        design=design,
        truth=ds.truth,
        codes=codes,
        mountable=mount,
        plausibility=_plausibility(cfg, ds, bc, robot, notes),
        sensitivity=sensitivity,
    )
    t = time.perf_counter()
    with figures.only_formats(st.figure_formats):
        result.files = write_outputs(result, cfg, robot, body, ds, gm, budget, label)
    seconds["files"] = time.perf_counter() - t
    shown.update(1)
    seconds["total"] = time.perf_counter() - t_all
    shown.close()
    (out_dir / "timing.json").write_text(json.dumps(seconds, indent=1))
    for s_ in sentences:
        log.info("%s (%s)", s_, label)
    if log_mlflow:
        result.mlflow_run_id = log_study(cfg, result, overrides, ds)
    return result


def _mask_npz(body, robot, density: np.ndarray, chosen: set[str], out_dir: Path) -> list[Path]:
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


def write_outputs(res: StudyResult, cfg, robot, body, ds, gm, budget: str, label: str) -> list[Path]:
    from sphri.analysis.coverage import ALL, safe_name
    from sphri.analysis.render import _vmax, plot_swd_heatmap

    out = res.out_dir
    files: list[Path] = []
    cov = res.coverage
    scen = cov.groups
    dens = {s: cov.densities[s] for s in scen}
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
    files.append(out / "density_maps.npz")
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
    files.append(out / "density_maps.csv")
    res.sessions.to_csv(out / "sessions.csv", index=False)
    res.episodes.to_csv(out / "episodes.csv", index=False)
    res.coded.to_csv(out / "coded_episodes.csv", index=False, float_format="%.4g")
    res.histogram.to_csv(out / "gesture_histogram.csv", index=False, float_format="%.4g")
    res.ranking.to_csv(out / "body_part_ranking.csv", index=False, float_format="%.5g")
    res.placement.to_csv(out / "placement.csv", index=False, float_format="%.4g")
    if res.mountable is not None:
        res.mountable.to_csv(out / "mountable_parts.csv", index=False, float_format="%.4g")
        files.append(out / "mountable_parts.csv")
    areas = body.area_table()
    areas.to_csv(out / "body_part_area.csv", index=False, float_format="%.1f")
    files.append(out / "body_part_area.csv")
    if getattr(robot, "skipped", ()):  # a robot read from a URDF: what has no surface here, and why
        pd.DataFrame(list(robot.skipped), columns=["link", "reason"]).to_csv(
            out / "robot_skipped_links.csv", index=False
        )
        files.append(out / "robot_skipped_links.csv")
    files += [
        out / n
        for n in (
            "sessions.csv",
            "episodes.csv",
            "coded_episodes.csv",
            "gesture_histogram.csv",
            "body_part_ranking.csv",
            "placement.csv",
        )
    ]
    files += _design_and_gesture_files(res, body, robot, out)
    if res.comparison is not None:
        files += res.comparison.write_csv(out, "swd")
        eff = _effects(res.comparison)
        eff.to_csv(out / "swd_effects.csv", index=False, float_format="%.5g")
        files.append(out / "swd_effects.csv")
    chosen = set(str(res.placement.loc[res.placement["group"] == "all", "parts"].iat[0]).split(";")) - {""}
    files += _mask_npz(body, robot, cov.densities[ALL], chosen, out)
    (out / "placement.txt").write_text("\n".join(res.sentences) + f"\n(budget {budget}; {label})\n")
    files.append(out / "placement.txt")
    summary = {
        "dataset": ds.name,
        "synthetic": ds.synthetic,
        "robot": robot.name,
        "n_participants": int(ds.sessions["participant"].nunique()),
        "n_sessions": int(len(ds.sessions)),
        "scenarios": scen,
        "n_coded_episodes": int(len(res.coded)),
        "gesture_model": {
            "regions": gm.regions,
            "loso_accuracy": gm.accuracy,
            "res": gm.res,
            "loso_accuracy_mean": gm.accuracy_mean,
            "loso_accuracy_std": gm.accuracy_std,
            "n_trials": gm.n_trials,
        },
        "surface": {
            "area_cm2": float(areas["area_cm2"].sum()),
            "reachable_cm2": float(areas["reachable_cm2"].sum()),
            "floor_facing_cm2": float(areas["floor_facing_cm2"].sum()),
            "buried_cm2": float(areas["buried_cm2"].sum()),
            "floor_height_m": res.settings.reach_floor_height_m,
            "down_cos": res.settings.reach_down_cos,
        },
        "budget": budget,
        "mountable": {
            "criterion": "contact frames per cm^2 of a mountable part's reachable surface (ranking and greedy)",
            "min_diameter_mm": res.settings.min_diameter_mm,
            "min_patch_cm2": res.settings.min_patch_cm2,
            "excluded": (
                [
                    {"part": r.part, "reason": r.reason, "width_mm": round(float(r.width_mm), 1)}
                    for r in res.mountable.itertuples()
                    if r.reason
                ]
                if res.mountable is not None
                else []
            ),
        },
        "human_codes": res.codes.summary(res.coded) if res.codes is not None else None,
        "plausibility": res.plausibility,
        "priors_sensitivity": res.sensitivity[1] if res.sensitivity is not None else None,
        "skin_design": _design_summary(res.design),
        "skin_export": _export_summary(out / "skin_export" / "manifest.json"),
        "sentences": res.sentences,
        "notes": res.notes,
        "seconds": res.seconds,
        "settings": dataclasses.asdict(res.settings),
    }
    if ds.truth is not None and len(res.coded):
        tr = ds.truth.reset_index(drop=True)
        c = res.coded
        truth_g = tr["gesture"].to_numpy()[c["session"].to_numpy()]
        truth_p = tr["part"].to_numpy()[c["session"].to_numpy()]
        ok = c["gesture"].to_numpy() != ""
        summary["against_generator"] = {
            "gesture_agreement": float((c["gesture"].to_numpy()[ok] == truth_g[ok]).mean()) if ok.any() else None,
            "dominant_part_agreement": float((c["dominant_part"].to_numpy() == truth_p).mean()),
        }
    if res.sensitivity is not None:
        res.sensitivity[0].to_csv(out / "priors_sensitivity.csv", index=False, float_format="%.4g")
        files.append(out / "priors_sensitivity.csv")
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    files.append(out / "summary.json")
    if not res.settings.render:
        return files
    from sphri.figures import Provenance, human
    from sphri.sessions.render import (
        body_view,
        drawn_shares,
        plot_atlas,
        plot_effects,
        plot_gesture_histogram,
        plot_placement,
        plot_views,
        write_density_ply,
    )

    prov = Provenance(synthetic=bool(ds.synthetic), ids=ds.name)  # one banner on every figure (sphri.figures.mark)
    view = body_view(body, res.settings.view_faces)
    figs = {}
    figs["maps"] = plot_views(
        view,
        {**dens, "pooled": cov.densities[ALL]},
        out / "maps_views.png",
        f"Contact density per {cov.by}, one colour scale",
        provenance=prov,
    )
    top = _vmax([*dens.values(), cov.densities[ALL]])  # every scenario's own figure on the maps' one scale
    for s in scen:
        files.append(
            plot_views(
                view, {s: cov.densities[s]}, out / f"map_{safe_name(s)}.png", f"{human(s)}", provenance=prov, vmax=top
            )
        )
    figs["atlas"] = plot_atlas(
        body,
        robot,
        cov.densities[ALL],
        out / "atlas_pooled.png",
        "Atlas of the whole surface, pooled over scenarios",
        provenance=prov,
    )
    files.append(write_density_ply(view, {"pooled": cov.densities[ALL], **dens}, out / "density_mesh.ply"))
    if res.comparison is not None:
        figs["swd"] = plot_swd_heatmap(
            res.comparison, out / "swd_matrix.png", "Scenario maps: paired sliced Wasserstein", provenance=prov
        )
        figs["effects"] = plot_effects(
            _effects(res.comparison),
            scen,
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
        else f"Gestures of the coded episodes per scenario (model LOSO accuracy {100 * gm.accuracy_mean:.0f} %)",
        provenance=prov,
        drawn=drawn_shares(res.coded, ds.truth) if ds.truth is not None and len(res.coded) else None,
    )
    if res.design is not None:
        from sphri.sessions.skin_render import plot_budget_curve, plot_skin

        d = res.design
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
            cov.densities[ALL],
            d.element_mask,
            out / "skin_design.png",
            f"The recommended skin under {budget}: pooled density on the chosen patches",
            provenance=prov,
        )
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


def _design_and_gesture_files(res: StudyResult, body, robot, out: Path) -> list[Path]:
    """The skin design's files (``sphri.sessions.skin.write_design``), gesture counts with participant-bootstrap
    intervals and, for synthetic sessions, the confusion of episode labels against the generator."""
    from sphri.sessions.gesture_report import confusion_against_generator, gesture_counts
    from sphri.sessions.skin import write_design

    files = []
    if res.design is not None:
        files += write_design(res.design, body, robot, out, res.settings.export_format, res.settings.min_patch_cm2)
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
    adds a note."""
    if not ds.synthetic or ds.truth is None or "touch_frames" not in ds.truth:
        return None
    from sphri.sessions.plausibility import plausibility

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


def _design_summary(design) -> dict | None:
    if design is None:
        return None
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


def _export_summary(path: Path) -> dict | None:
    """The patch export's totals (``skin_export/manifest.json``), without the per-piece rows."""
    if not path.is_file():
        return None
    return {k: v for k, v in json.loads(path.read_text()).items() if k != "patches"}


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
