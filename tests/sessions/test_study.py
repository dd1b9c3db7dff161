"""sphri coverage +experiment=scenario_study +debug=fast: every output, and layout=density reads the placement."""

from __future__ import annotations

import json
import logging

import numpy as np
import pandas as pd
import pytest
import trimesh
from hydra.utils import instantiate

from sphri.config import ConfigError, compose
from sphri.coverage import main
from sphri.types import GESTURES

#: What ``sphri.figures`` said about the study's figures (text past the canvas, too small, overlapping).
LAYOUT_PROBLEMS: list[str] = []


class _Collect(logging.Handler):
    def emit(self, record: logging.LogRecord) -> None:
        LAYOUT_PROBLEMS.append(record.getMessage())


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    runs = tmp_path_factory.mktemp("runs")  # MLflow store and cache (logged to MLflow, as the command does)
    handler = _Collect(level=logging.WARNING)
    logging.getLogger("sphri.figures").addHandler(handler)
    try:
        # PNG only and a coarser mesh: layout checks see every figure; three formats are tested
        # for the coverage figures (tests/analysis), which share sphri.figures.save
        rc = main(
            [
                "+experiment=scenario_study",
                "+debug=fast",
                f"out={out}",
                f"output_dir={runs}",
                "experiment.scenario_study.figure_formats=[png]",
                "experiment.scenario_study.view_faces=3000",
                f"cache.dir={runs}/cache",
            ]
        )
    finally:
        logging.getLogger("sphri.figures").removeHandler(handler)
    assert rc == 0
    assert (runs / "mlflow.db").is_file()
    # sessions and whole-body contacts are stage-cache entries: a second study reuses them
    assert list((runs / "cache" / "sessions").glob("*.entry")) and list(
        (runs / "cache" / "body_contact").glob("*.entry")
    )
    return out


def test_sessions_and_contacts_come_from_the_stage_cache(tmp_path):
    from sphri.cache import StageCache
    from sphri.sessions.labelling import load_sessions_and_contacts

    cfg = compose(["+experiment=scenario_study", "data.participants=1", "data.repetitions=1", f"cache.dir={tmp_path}"])
    cache = StageCache(tmp_path)
    _, _, ds1, bc1, _ = load_sessions_and_contacts(cfg, cache)
    _, _, ds2, bc2, _ = load_sessions_and_contacts(cfg, cache)
    assert ds1 is not ds2 and np.array_equal(ds1.hand_poses, ds2.hand_poses) and np.array_equal(bc1.frame, bc2.frame)
    assert len(list((tmp_path / "sessions").glob("*.entry"))) == 1


def test_writes_the_report_and_every_table(study):
    for name in (
        "report.html",
        "maps_views.png",
        "atlas_pooled.png",
        "swd_matrix.png",
        "gesture_histogram.png",
        "placement.png",
        "swd_effects.png",
        "density_mesh.ply",
        "density_maps.npz",
        "swd_pairs.csv",
        "swd_p_holm_matrix.csv",
        "swd_effects.csv",
        "gesture_histogram.csv",
        "body_part_ranking.csv",
        "placement.csv",
        "placement.txt",
    ):
        assert (study / name).is_file() and (study / name).stat().st_size > 0, name
    scen = ["S1_attention", "S2_path_redirection", "S3_move_aside", "S4_behaviour_correction", "S5_appreciation"]
    for s in scen:
        assert (study / f"map_{s}.png").is_file()
    html = (study / "report.html").read_text()
    assert "data:image/png;base64," in html and "SYNTHETIC" in html and "covering the" in html
    # placement, skin design patches, paired effects, gesture histogram, ranking; every figure embedded
    assert html.count("<table>") == 5 and html.count("<img ") == 8 and "Do scenarios differ?" in html
    assert "The skin design: budget curve and patches" in html
    pairs = pd.read_csv(study / "swd_pairs.csv")
    assert len(pairs) == 10 and pairs["p_holm"].between(0, 1).all() and (pairs["p_holm"] >= pairs["p_value"]).all()
    hist = pd.read_csv(study / "gesture_histogram.csv")
    assert set(hist["scenario"]) == set(scen) and set(hist["gesture"]) == set(GESTURES)
    for _, g in hist.groupby("scenario"):
        n = g["n_episodes"].iloc[0]
        assert g["count"].sum() == n and g["expected"].sum() == pytest.approx(n, abs=0.01)
    rank = pd.read_csv(study / "body_part_ranking.csv")
    allr = rank[(rank["scenario"] == "all") & ~rank["part"].str.startswith("group:")]
    assert allr["frames_per_cm2"].is_monotonic_decreasing and "gripper_l" in set(allr["part"])
    place = pd.read_csv(study / "placement.csv")
    assert place["group"].tolist() == ["all"] + scen
    assert (place["area_cm2"] <= 2000 + 1e-6).all() and place["captured"].between(0, 1).all()
    summary = json.loads((study / "summary.json").read_text())
    assert summary["synthetic"] and summary["n_sessions"] == 3 * 5 * 2
    # generated sessions: each participant's episodes coded by a model of the other participants' episodes
    assert summary["gesture_model"]["training"] == "episodes"
    assert summary["gesture_model"]["n_trials"] == summary["n_coded_episodes"]
    block = summary["plausibility"]  # the paired timing check and the CoST calibration beside it
    assert block["gestures"] and {"penetration_ok", "on_drawn_part_ok", "timing_ok", "ok"} <= set(block)
    for g in block["gestures"].values():
        assert {"duration_ratio", "contact_plan_ratio", "contact_fraction_ratio", "cost_sampling_interval"} <= set(g)
    notes = " ".join(summary["notes"])
    assert (
        "power" in notes and "never saw" in notes
    )  # 3 participants cannot reach Holm significance; parts off the model


def test_every_study_figure_is_clean_in_the_chosen_formats(study):
    pngs = sorted(study.glob("*.png"))
    assert len(pngs) >= 11 and all(p.stat().st_size > 0 for p in pngs)
    assert not list(study.glob("*.pdf")) and not list(study.glob("*.svg"))  # figure_formats=[png]
    assert LAYOUT_PROBLEMS == []


def test_density_mesh_carries_the_density_as_a_vertex_attribute(study):
    text = (study / "density_mesh.ply").read_bytes()
    header = text[: text.index(b"end_header")].decode()
    assert "property float density_pooled" in header and "property float density_S1_attention" in header
    mesh = trimesh.load(study / "density_mesh.ply", process=False)
    assert len(mesh.vertices) > 1000


def test_layout_density_reads_the_placement_mask(study):
    npz = sorted(study.glob("placement_*.npz"))
    assert npz
    link = npz[0].stem[len("placement_") :]
    cfg = compose(
        [
            "robot=reachy_full",
            f"data.regions=[{link}]",
            "layout=density",
            "encoder=coverage",
            f"layout.density_path={npz[0]}",
        ]
    )
    robot = instantiate(cfg.robot).build()
    surface = instantiate(cfg.surface).fit(robot.links[link])
    layout = instantiate(cfg.layout).build(robot.links[link], surface, 6)
    with np.load(npz[0]) as z:
        masked = z["points_m"][z["mask"]]
    # every taxel sits on the chosen part(s)
    d = np.linalg.norm(layout.position_m[:, None, :] - masked[None, :, :], axis=2).min(axis=1)
    assert layout.n_taxels > 0 and np.median(d) < 0.01


def test_study_settings_are_checked():
    with pytest.raises(ConfigError, match=r"experiment.scenario_study.budget_taxels"):
        compose(["+experiment=scenario_study", "experiment.scenario_study.pitch_mm=10"])
    with pytest.raises(ConfigError, match=r"robot='reachy' is invalid.*kinematic tree"):
        compose(["+experiment=scenario_study", "robot=reachy"])
    for key, value in (
        ("patch_cm2", "0.5"),
        ("skin_pitch_mm", "0"),
        ("heldout_splits", "-1"),
        ("export_format", "obj"),
    ):
        with pytest.raises(ConfigError, match=rf"experiment.scenario_study.{key}"):
            compose(["+experiment=scenario_study", f"experiment.scenario_study.{key}={value}"])
    from sphri.pipeline import chain_region

    with pytest.raises(ConfigError, match=r"data=SyntheticSessions holds free-interaction sessions.*scenario_study"):
        chain_region(compose(["+experiment=scenario_study"]))


def test_report_escapes_scenario_names_and_notes(tmp_path):
    """Scenario names come from the data: one that reads as a script tag stays text in the page."""
    from sphri.sessions.schema import ScenarioStudySchema
    from sphri.sessions.study import StudyResult, write_report

    hostile = "<script>alert('x')</script>"
    figs = {}
    for name in ("placement", "maps", "atlas", "gestures"):
        figs[name] = tmp_path / f"{name}.png"
        figs[name].write_bytes(b"\x89PNG\r\n\x1a\n" + name.encode())
    empty = pd.DataFrame()
    res = StudyResult(
        out_dir=tmp_path,
        settings=ScenarioStudySchema(),
        synthetic=True,
        sessions=empty,
        episodes=empty,
        coded=empty,
        histogram=pd.DataFrame(
            {"scenario": [hostile, hostile, "S1"], "gesture": ["tap", "pat", "tap"], "count": [2, 1, 3]}
        ),
        ranking=pd.DataFrame(
            {
                "scenario": ["all", "all", hostile],
                "part": [hostile, "head", "head"],
                "frames_per_cm2": [0.5, float("nan"), 0.1],
            }
        ),
        placement=pd.DataFrame(
            {"group": ["all", hostile], "parts": ["head", "head"], "held_out_share": [0.81234, 0.5]}
        ),
        sentences=[f"Cover head first ({hostile})."],
        comparison=None,
        coverage=None,
        notes=[f"WARNING: scenario {hostile} has one session"],
        files=[],
        seconds={"study": 1.234},
    )
    summary = {
        "dataset": hostile,
        "robot": "reachy",
        "n_participants": 3,
        "n_sessions": 6,
        "n_coded_episodes": 5,
        "gesture_model": {
            "regions": ["head"],
            "res": 4,
            "loso_accuracy": {hostile: 0.5},
            "loso_accuracy_mean": 0.5,
            "loso_accuracy_std": 0.1,
            "n_trials": 12,
        },
        "human_codes": {  # codes=PATH: whose codes, and the coders' agreement (kappa None: undefined)
            "file": "codes.csv",
            "coder": hostile,
            "n_episodes": 5,
            "agreement": [
                {"coder_a": hostile, "coder_b": "ben", "n_episodes": 5, "agreement": 0.8, "kappa": None},
                {"coder_a": hostile, "coder_b": "model", "n_episodes": 5, "agreement": 0.4, "kappa": 0.2512},
            ],
        },
    }
    page = write_report(res, figs, summary, "40 cm^2", hostile, tmp_path / "report.html").read_text()
    assert "<script" not in page.lower()
    assert page.count("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;") == 13
    # the tables keep their rows: the ranking is the pooled one (two parts), numbers formatted, NaN as a dash
    assert page.count("<table>") == 4 and "0.812" in page and "&ndash;" in page
    assert "Coded by hand" in page and "<td>0.25</td>" in page and "<td>none</td>" in page
    assert "the model&#39;s suggestions" in page
    assert 'class="warn"' in page and "Do scenarios differ?" not in page


def test_budget_curve_rises_to_one_and_held_out_stays_below(study):
    curve = pd.read_csv(study / "budget_curve.csv")
    scen = sorted(pd.read_csv(study / "sessions.csv")["scenario"].unique())
    assert set(curve["scenario"]) == {"all", *scen} and set(curve["curve"]) == {"in_sample", "heldout"}
    summary = json.loads((study / "summary.json").read_text())
    pitch = summary["skin_design"]["pitch_mm"]
    for (s, kind), c in curve.groupby(["scenario", "curve"]):
        assert c["area_cm2"].is_monotonic_increasing and c["captured"].is_monotonic_increasing, (s, kind)
        assert c["captured"].iloc[0] == 0 and c["captured"].between(0, 1).all()
        # taxels at the pitch: area / pitch^2 (the CSV rounds the area to 6 digits)
        assert np.abs(c["taxels"] - c["area_cm2"] * 100 / pitch**2).max() <= 1.0
    pooled = curve[curve["scenario"] == "all"].set_index("curve")
    ins, held = pooled.loc["in_sample"], pooled.loc["heldout"]
    assert ins["captured"].iloc[-1] == pytest.approx(1.0)  # every patch taken: every frame captured
    assert ins["captured"].iloc[1] < 1.0  # ... but not with the first 1 % of the area (the curve rises)
    assert held["captured"].mean() <= ins["captured"].mean()
    assert (held["n_splits"] == 20).all()  # 10 halvings, each half scores the other's choice
    assert (study / "budget_curve.png").is_file() and (study / "skin_design.png").is_file()
    assert "budget_curve.csv" in (study / "report.html").read_text()


def test_patch_placement_and_export_a_lab_can_build_from(study):
    patches = pd.read_csv(study / "patches.csv")
    # patches are regions within parts: some part holds several
    assert patches.groupby(["link", "part"]).size().max() > 1
    place = pd.read_csv(study / "patch_placement.csv")
    assert place["group"].iloc[0] == "all" and (place["area_cm2"] <= 2000 + 1e-6).all()
    assert place["captured"].between(0, 1).all() and place["heldout_captured"].between(0, 1).all()
    manifest = pd.read_csv(study / "skin_export" / "manifest.csv")
    meta = json.loads((study / "skin_export" / "manifest.json").read_text())
    assert len(meta["patches"]) == len(manifest) == place["n_patches"].iloc[0]
    assert {"link", "part", "patch", "file", "area_cm2", "taxels", "share_captured_alone", "share_added"} <= set(
        manifest
    )
    assert manifest["sampled_area_cm2"].sum() <= 2000 + 1e-6
    assert manifest["share_added"].sum() == pytest.approx(place["captured"].iloc[0])
    for r in manifest.itertuples():
        mesh = trimesh.load(study / "skin_export" / r.file, process=False)
        assert mesh.area * 1e4 == pytest.approx(r.area_cm2, rel=1e-4)
        # the mesh covers about the patch's sampled surface (faces cut at the element spacing)
        assert 0.6 < r.area_cm2 / r.sampled_area_cm2 < 1.6, r.patch
        assert r.taxels == int(np.floor(r.area_cm2 * 100 / meta["pitch_mm"] ** 2 + 1e-9))
    # in each link's frame: the patch lies on its link's mesh
    robot = instantiate(compose(["robot=reachy_full"]).robot).build()
    r = manifest.iloc[0]
    mesh = trimesh.load(study / "skin_export" / r["file"], process=False)
    link = robot.links[r["link"]]
    closest = trimesh.Trimesh(link.vertices, link.faces, process=False).nearest.on_surface(mesh.vertices[:50])[1]
    assert np.max(closest) < 1e-6


def test_gesture_counts_with_intervals_and_confusion_against_the_generator(study):
    counts = pd.read_csv(study / "gesture_counts.csv")
    assert (counts["count_lo"] <= counts["count"] + 1e-9).all() and (counts["count"] <= counts["count_hi"] + 1e-9).all()
    assert (counts["expected_lo"] <= counts["expected_hi"]).all()
    coded = pd.read_csv(study / "coded_episodes.csv", keep_default_na=False)
    for s, g in counts.groupby("scenario"):
        assert g["count"].sum() == ((coded["scenario"] == s) & (coded["gesture"] != "")).sum()
    conf = pd.read_csv(study / "gesture_confusion.csv", index_col=0)
    assert conf["n"].sum() == len(coded)
    diag = sum(conf.loc[g, g] for g in conf.index if g in conf.columns)
    summary = json.loads((study / "summary.json").read_text())
    labelled = (coded["gesture"] != "").sum()
    assert diag / labelled == pytest.approx(summary["against_generator"]["gesture_agreement"])


def test_priors_sensitivity_of_the_part_ranking_at_debug_size(study):
    """The study reports how stable its part ranking is under the priors' stated ranges (priors_sensitivity)."""
    summary = json.loads((study / "summary.json").read_text())
    block = summary["priors_sensitivity"]
    draws = pd.read_csv(study / "priors_sensitivity.csv")
    assert block["draws"] == len(draws) == summary["settings"]["sensitivity_draws"] == 200
    assert block["ranges"]["parts"] == [0.5, 2.0] and block["ranges"]["gestures"] == [0.5, 2.0]
    # the CSV keeps 4 significant digits (float_format %.4g): its median may sit 5e-5 from the exact one
    assert block["tau_median"] == pytest.approx(draws["tau"].median(), abs=1e-4)
    assert -1.0 <= block["tau_p5"] <= block["tau_median"] <= 1.0
    assert 0.0 <= block["top_k_overlap_p5"] <= block["top_k_overlap_median"] <= 1.0
    ranked = pd.read_csv(study / "body_part_ranking.csv", keep_default_na=False)
    ranked = ranked[
        (ranked["scenario"] == "all") & (ranked["excluded"] == "") & ~ranked["part"].str.startswith("group:")
    ]
    first = ranked["part"].tolist()
    assert block["unperturbed_top"] == first[: block["top_k"]]
