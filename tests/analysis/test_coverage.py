"""The coverage analysis on a hand-made study: maps land where the contacts were put."""

from __future__ import annotations

import json

import numpy as np
import pytest
from coverage_fixtures import RADIUS, make_study

from sphri.analysis.coverage import ALL, CoverageAnalysis, group_order, write_region
from sphri.surface.cylinder import CylinderSurface


@pytest.fixture(scope="module")
def surface(study):
    return CylinderSurface().fit(study.link)


@pytest.fixture(scope="module")
def result(study, surface):
    return CoverageAnalysis(n_projections=64).analyze(study.dataset, study.contacts, study.link, surface, "arm")


def peak(result, group):
    s = result.samples
    return s.points_m[np.argmax(result.densities[group])]


def test_maps_peak_where_each_gesture_touched(result):
    assert result.groups == ["poke", "stroke", "grab"]
    np.testing.assert_allclose(peak(result, "poke"), [RADIUS, 0, 0.08], atol=0.012)
    p = peak(result, "stroke")
    assert p[0] < -0.03 and abs(p[2] + 0.02) < 0.03
    assert abs(peak(result, "grab")[2] + 0.09) < 0.012
    for g in [ALL] + result.groups:
        assert result.densities[g] @ result.samples.area_m2 == pytest.approx(1.0)
    # "all" is the frame-weighted mix of the groups' counts
    np.testing.assert_allclose(result.counts[ALL], sum(result.counts[g] for g in result.groups))


def test_placement_follows_the_spread_of_each_gesture(result):
    c = result.curves
    assert c["poke"].area_at_capture < c["grab"].area_at_capture < c["stroke"].area_at_capture < c[ALL].area_at_capture
    assert c[ALL].n_frames == sum(c[g].n_frames for g in result.groups)  # every group's frames are distinct
    sentence = result.sentences["poke"]
    assert sentence.startswith("poke: covering ") and "captures 90 % of contact frames" in sentence
    assert "a 3" in sentence or "a 0" in sentence  # the poke sits at angle ~0 (the +x seam)
    # held-out participants are still mostly captured by the others' placement
    h = result.heldout
    assert set(h["group"]) == {ALL, "poke", "stroke", "grab"}
    assert h.groupby("group")["captured"].mean().min() > 0.75
    assert (h["unit"].nunique()) == 6


def test_different_gestures_differ_and_identical_ones_do_not(surface):
    from coverage_fixtures import TARGETS

    targets = {"poke": TARGETS["poke"], "tap": TARGETS["poke"], "stroke": TARGETS["stroke"]}
    st = make_study(participants=8, repetitions=4, seed=3, targets=targets)
    res = CoverageAnalysis(n_projections=64, render=False, heldout=False).analyze(
        st.dataset, st.contacts, st.link, surface, "arm"
    )
    assert res.groups == ["poke", "stroke", "tap"]  # the study's gesture order
    t = res.comparison.table.set_index(["cond_a", "cond_b"])
    assert t.loc[("poke", "stroke"), "significant"] and t.loc[("stroke", "tap"), "significant"]
    assert not t.loc[("poke", "tap"), "significant"]
    assert t.loc[("poke", "tap"), "p_holm"] > 0.05
    assert t["exact"].all() and (t["n_permutations"] == 256).all()
    assert t.loc[("poke", "stroke"), "mean_between_swd_mm"] > 5 * t.loc[("poke", "tap"), "mean_between_swd_mm"]


def test_grouping_by_any_trial_column(study, surface):
    ds = study.dataset
    trials = ds.trials.copy()
    trials["scenario"] = np.where(trials["trial_ordinal"] % 2 == 0, "even", "odd")
    ds2 = type(ds)(ds.name, ds.synthetic, ds.hand, trials, ds.poses, ds.frame_rate_hz)
    res = CoverageAnalysis(by="scenario", render=False, n_projections=32).analyze(
        ds2, study.contacts, study.link, surface, "arm"
    )
    assert res.groups == ["even", "odd"]
    assert len(res.comparison.table) == 1
    by_p = CoverageAnalysis(by="participant", render=False, heldout=False).analyze(
        ds, study.contacts, study.link, surface, "arm"
    )
    assert by_p.comparison is None and any("pair_by" in n for n in by_p.notes)
    assert group_order(trials["gesture"], "gesture") == ["poke", "stroke", "grab"]


def test_bad_inputs_name_the_problem(study, surface):
    a = CoverageAnalysis(render=False)
    with pytest.raises(ValueError, match="coverage.by='scenario'"):
        CoverageAnalysis(by="scenario").analyze(study.dataset, study.contacts, study.link, surface, "arm")
    with pytest.raises(ValueError, match="no trials in region 'torso'"):
        a.analyze(study.dataset, study.contacts, study.link, surface, "torso")
    c = study.contacts
    bad = type(c)(**{**c.__dict__, "n_frames": c.n_frames + 1})
    with pytest.raises(ValueError, match="different datasets"):
        a.analyze(study.dataset, bad, study.link, surface, "arm")
    from sphri.config import ConfigError

    with pytest.raises(ConfigError, match="coverage.bandwidth_mm"):
        CoverageAnalysis(bandwidth_mm=0.1)
    with pytest.raises(ConfigError, match="coverage.spacing_mm"):
        CoverageAnalysis(bandwidth_mm=5, spacing_mm=8)


def test_files_written_and_readable(result, study, surface, tmp_path):
    import dataclasses

    small = dataclasses.replace(result, groups=["poke"])  # render two groups only (time)
    paths = write_region(small, tmp_path, study.link, surface, render=True, views=3)
    names = {p.name for p in paths}
    for g in ["all", "poke"]:
        assert {f"density_{g}.npz", f"map_{g}.png", f"map_{g}.ply", f"uv_{g}.png"} <= names
    assert {
        "overview.png",
        "coverage_curve.png",
        "coverage_curve.csv",
        "swd_heatmap.png",
        "swd_pairs.csv",
        "swd_p_holm_matrix.csv",
        "recommendation.txt",
        "summary.json",
        "heldout.csv",
    } <= names
    with np.load(tmp_path / "density_poke.npz") as z:
        assert z["points_m"].shape == (result.samples.n, 3) and z["density"].shape == (result.samples.n,)
        assert z["mask"].dtype == bool and z["mask"].sum() == result.curves["poke"].k
    # the format layout=density reads
    from sphri.layout import poisson

    pts, dens = poisson.load_density(tmp_path / "density_all.npz")
    assert pts.shape[0] == dens.shape[0] == result.samples.n
    import trimesh

    mesh = trimesh.load(tmp_path / "map_poke.ply", process=False)
    assert mesh.visual.vertex_colors.shape[0] == mesh.vertices.shape[0]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["groups"]["poke"]["area_share_at_capture"] == pytest.approx(result.curves["poke"].area_at_capture)
    assert summary["comparison"]["n_pairs"] == 3
    text = (tmp_path / "recommendation.txt").read_text().splitlines()
    assert len(text) == 2 and text[0].startswith("all: covering") and text[1].startswith("poke: covering")
    from PIL import Image

    im = np.asarray(Image.open(tmp_path / "map_poke.png").convert("RGB")).astype(float)
    assert im.std() > 10  # not a blank picture


def test_every_coverage_figure_is_clean_in_three_formats(result, study, surface, tmp_path, caplog):
    """PNG, PDF and SVG of every figure, and no text past the canvas, under 7 pt or overlapping
    (``sphri.figures.save`` logs each layout problem; the SYNTHETIC mark is drawn too)."""
    import dataclasses
    import logging

    from sphri.figures import Provenance

    caplog.set_level(logging.WARNING, logger="sphri.figures")
    small = dataclasses.replace(result, groups=result.groups[:2])
    paths = write_region(
        small,
        tmp_path,
        study.link,
        surface,
        render=True,
        views=4,
        provenance=Provenance(synthetic=True, ids="test study"),
    )
    pngs = [p for p in paths if p.suffix == ".png"]
    assert {p.stem for p in pngs} >= {"map_all", "uv_all", "overview", "coverage_curve", "swd_heatmap"}
    for png in pngs:
        for fmt in ("pdf", "svg"):
            assert png.with_suffix("." + fmt).stat().st_size > 0, f"{png.stem}.{fmt} missing"
        assert "SYNTHETIC DATA" in png.with_suffix(".svg").read_text()
    assert [r.getMessage() for r in caplog.records if r.name == "sphri.figures"] == []


def test_every_repetition_enters_the_swd_tests(surface):
    """Three repetitions: one split-half (k = 1) would use repetitions 1 and 2 only. The tests average over the
    rotations of the trial order, so moving repetition 3 out of the compared conditions changes the statistic."""
    from coverage_fixtures import TARGETS

    from sphri.analysis.compare import n_rotations, rotated_halves

    covered = set()
    for r in range(n_rotations(3, 1)):
        h0, h1 = rotated_halves([1, 2, 3], 1, r)
        covered |= set(h0.tolist()) | set(h1.tolist())
    assert covered == {0, 1, 2} and n_rotations(4, 2) == 1

    targets = {"poke": TARGETS["poke"], "stroke": TARGETS["stroke"]}
    st = make_study(participants=4, repetitions=3, seed=5, targets=targets)
    an = CoverageAnalysis(n_projections=32, render=False, heldout=False)
    full = an.analyze(st.dataset, st.contacts, st.link, surface, "arm").comparison
    ds = st.dataset
    trials = ds.trials.copy()
    third = trials["trial_ordinal"] > 4  # the third repetition of both gestures
    trials.loc[third, "gesture"] = "grab"
    moved = an.analyze(
        type(ds)(ds.name, ds.synthetic, ds.hand, trials, ds.poses, ds.frame_rate_hz),
        st.contacts,
        st.link,
        surface,
        "arm",
    ).comparison
    pf = full.per_participant.set_index(["participant", "cond_a", "cond_b"])
    pm = moved.per_participant.set_index(["participant", "cond_a", "cond_b"])
    key = [k for k in pf.index if k[1:] == ("poke", "stroke")]
    assert len(key) == 4 and (pf.loc[key, "n_splits"] == 3).all()
    mkey = [k for k in pm.index if set(k[1:]) == {"poke", "stroke"}]
    assert (pm.loc[mkey, "n_splits"] == 1).all()
    # with repetition 3 the differences are those of three splits, not of repetitions 1 and 2 alone
    assert not np.allclose(pf.loc[key, "diff_mm"].to_numpy(), pm.loc[mkey, "diff_mm"].to_numpy())
