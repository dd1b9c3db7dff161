"""robot=reachy2 (the packaged Reachy 2, no ../shared) runs the scenario study end to end at a small size."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from sphri.coverage import main


@pytest.mark.slow  # `make test-all`; the packaged tree is checked in `make test` (tests/robots/test_urdf_tree.py)
def test_packaged_reachy2_runs_a_small_scenario_study(tmp_path, monkeypatch):
    monkeypatch.setenv("SPHRI_SHARED", str(tmp_path / "no_shared"))  # nothing may come from ../shared
    out, runs = tmp_path / "out", tmp_path / "runs"
    rc = main(
        [
            "+experiment=scenario_study",
            "robot=reachy2",
            "+debug=fast",
            "data.participants=2",
            "data.repetitions=1",
            "data.scenarios=[S3_move_aside,S4_behaviour_correction]",
            "experiment.scenario_study.gesture_repetitions=2",
            "experiment.scenario_study.render=false",
            f"out={out}",
            f"output_dir={runs}",
            f"cache.dir={runs}/cache",
            "tracking.enabled=false",
        ]
    )
    assert rc == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["robot"] == "reachy2"
    ranking = pd.read_csv(out / "body_part_ranking.csv")
    parts = set(ranking["part"])
    # Reachy 2's own parts (not reachy_full's), e.g. the antennas, elbows and torso top, and its groups
    assert {"antenna_l", "elbow_r", "torso_top", "gripper_r", "base", "group:antennas"} <= parts
    touched = ranking[(ranking["scenario"] == "all") & (ranking["contact_frames"] > 0)]
    assert len(touched) >= 2
    skipped = pd.read_csv(out / "robot_skipped_links.csv")
    assert {"link", "reason"} <= set(skipped.columns) and "drivewhl1_link" in set(skipped["link"])
    # the skin design on Reachy 2: budget curve, gesture tables and the patch export (meshes in link frames)
    import trimesh

    curve = pd.read_csv(out / "budget_curve.csv")
    ins = curve[(curve["scenario"] == "all") & (curve["curve"] == "in_sample")]
    # every patch taken captures every frame on mountable surface; frames only on a joint ball or antenna none
    assert ins["captured"].is_monotonic_increasing and 0.5 < ins["captured"].iloc[-1] <= 1.0
    excluded = {e["part"] for e in summary["mountable"]["excluded"]}
    assert {"shoulder_ball_l", "elbow_r", "wrist_l", "antenna_l"} <= excluded
    placed = pd.read_csv(out / "placement.csv")
    assert not {p for row in placed["parts"].dropna() for p in row.split(";")} & excluded
    assert (out / "gesture_counts.csv").is_file() and (out / "gesture_confusion.csv").is_file()
    manifest = pd.read_csv(out / "skin_export" / "manifest.csv")
    assert len(manifest) > 0 and set(manifest["link"]) <= set(summary_links(out))
    from sphri.sessions.skin import connected_pieces

    assert not set(manifest["part"]) & excluded
    for r in manifest.itertuples():
        mesh = trimesh.load(out / "skin_export" / r.file, process=False)
        assert abs(mesh.area * 1e4 - r.area_cm2) <= 1e-4 * r.area_cm2
        assert len(connected_pieces(mesh.vertices, mesh.faces)) == 1 and r.area_cm2 >= 20.0
        taxels = pd.read_csv(out / "skin_export" / r.taxel_file)[["x_m", "y_m", "z_m"]].to_numpy()
        assert len(taxels) == r.taxels_placed and trimesh.proximity.closest_point(mesh, taxels)[1].max() < 0.5e-3


def summary_links(out):
    """The links the study mapped (density_maps.csv)."""
    return pd.read_csv(out / "density_maps.csv", usecols=["link"])["link"].unique()
