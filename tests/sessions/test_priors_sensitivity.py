"""Every setting of the scenario priors says where it comes from; the part ranking's stability under them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from sphri.sessions import sensitivity as sens
from sphri.sessions import synthetic as syn

PARTS = [
    "head",
    "torso_front_upper",
    "torso_front_lower",
    "torso_back_upper",
    *[f"{p}_{s}" for p in ("shoulder", "upper_arm", "forearm", "wrist", "gripper") for s in "lr"],
]


def _write(tmp_path: Path, table: dict) -> Path:
    path = tmp_path / "priors.yaml"
    path.write_text(yaml.safe_dump(table))
    return path


def test_the_default_priors_cite_a_source_or_say_assumption_for_every_setting():
    table = syn.load_priors(syn.DEFAULT_PRIORS, PARTS)
    prov = table["provenance"]
    for name in table["scenarios"]:
        for field in syn.SCENARIO_KEYS:
            e = prov[f"scenarios.{name}.{field}"]
            assert e.get("source") in table["sources"] or e.get("assumption") is True
    assert prov["scenarios.S1_attention.parts"]["assumption"] is True
    assert prov["scenarios.S2_path_redirection.robot_motion"]["source"] == "reference_phase1"
    assert {"tail_s", "base_speed_m_s"} <= set(prov)


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda t: t["provenance"].pop("scenarios.*.parts"), r"scenarios\.S1_attention\.parts has neither a source"),
        (lambda t: t.pop("provenance"), r"needs a mapping 'provenance'"),
        (
            lambda t: t["provenance"].update({"scenarios.S3_move_aside.gestures": {"note": "guessed"}}),
            r"scenarios\.S3_move_aside\.gestures has neither a source nor assumption: true",
        ),
        (lambda t: t["provenance"].pop("tail_s"), r": tail_s has neither a source"),
        (
            lambda t: t["provenance"].update({"scenarios.*.start_distance_m": {"source": "hall1967"}}),
            r"provenance\.scenarios\.\*\.start_distance_m\.source='hall1967' is not a key of sources",
        ),
        (
            lambda t: t["provenance"].update({"scenarios.*.part": {"assumption": True}}),
            r"provenance\.scenarios\.\*\.part: names no setting",
        ),
        (
            lambda t: t["provenance"]["scenarios.*.parts"].update({"perturb": [2.0, 0.5]}),
            r"provenance\.scenarios\.\*\.parts\.perturb=\[2\.0, 0\.5\] is invalid",
        ),
    ],
)
def test_a_setting_without_provenance_is_refused_naming_it(tmp_path, edit, match):
    table = yaml.safe_load(syn.DEFAULT_PRIORS.read_text())
    edit(table)
    path = _write(tmp_path, table)
    with pytest.raises(syn.PriorsError, match=match) as err:
        syn.load_priors(path, PARTS)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_an_optional_setting_given_needs_provenance_too(tmp_path):
    table = yaml.safe_load(syn.DEFAULT_PRIORS.read_text())
    table["scenarios"]["S1_attention"]["duration_scale"] = [1.0, 1.2]
    assert syn.load_priors(_write(tmp_path, table), PARTS)["provenance"]["scenarios.S1_attention.duration_scale"]
    table["provenance"].pop("scenarios.*.duration_scale")
    with pytest.raises(syn.PriorsError, match=r"scenarios\.S1_attention\.duration_scale has neither"):
        syn.load_priors(_write(tmp_path, table), PARTS)


def test_draw_probability_is_the_generators_frequency():
    """The probability of a (gesture, part, hands) draw matches the generator's own draws (_draw, resolve_part)."""
    s = {
        "parts": {"shoulder_near": 3, "head": 1, "gripper_far": 2},
        "gestures": {"tap": 1, "push": 3},
        "two_hands": 0.3,
    }
    rng = np.random.default_rng(0)
    for side in (1.0, 0.0):
        n = 20000
        seen: dict[tuple, int] = {}
        for _ in range(n):
            g = syn._draw(rng, s["gestures"])
            p = syn.resolve_part(syn._draw(rng, s["parts"]), side, rng)
            two = bool(rng.random() < s["two_hands"])
            seen[(g, p, two)] = seen.get((g, p, two), 0) + 1
        for (g, p, two), c in seen.items():
            assert c / n == pytest.approx(sens.draw_probability(s, g, p, two, side), abs=0.01)
        total = sum(sens.draw_probability(s, g, p, t, side) for g in ("tap", "push") for p in PARTS for t in (0, 1))
        assert total == pytest.approx(1.0)


def _toy():
    """Two scenarios' priors, 40 sessions, each session one contact frame on its drawn part."""
    table = syn.load_priors(syn.DEFAULT_PRIORS, PARTS)
    rng = np.random.default_rng(1)
    rows = []
    for i in range(40):
        scen = "S3_move_aside" if i % 2 else "S5_appreciation"
        s = table["scenarios"][scen]
        rows.append(
            dict(
                scenario=scen,
                start_position="front",
                gesture=syn._draw(rng, s["gestures"]),
                part=syn.resolve_part(syn._draw(rng, s["parts"]), 0.0, rng),
                two_hands=False,
            )
        )
    truth = pd.DataFrame(rows)
    parts = sorted(set(truth["part"]))
    mat = np.zeros((len(truth), len(parts)), dtype=bool)
    mat[np.arange(len(truth)), [parts.index(p) for p in truth["part"]]] = True
    return table, truth, mat, parts


def test_without_perturbation_the_ranking_is_the_unperturbed_one():
    table, truth, mat, parts = _toy()
    for key in list(table["provenance"]):
        table["provenance"][key] = {**table["provenance"][key], "perturb": [1.0, 1.0]}
    df, summary = sens.priors_sensitivity(
        table, truth, np.arange(len(truth)), mat, parts, np.full(len(parts), 0.01), np.ones(len(parts), bool), 5, 0
    )
    assert (df["tau"] == 1.0).all() and (df["top_k_overlap"] == 1.0).all() and (df["ess_share"] == 1.0).all()
    assert summary["tau_median"] == 1.0 and summary["same_first_share"] == 1.0


def test_the_weights_move_the_ranking_towards_the_perturbed_priors():
    """Reweighted to priors that almost never draw the head, the head falls to the bottom of the ranking."""
    table, truth, mat, parts = _toy()
    pert = {
        n: {k: dict(s[k]) if k != "two_hands" else s[k] for k in sens.PERTURBED} for n, s in table["scenarios"].items()
    }
    pert["S5_appreciation"]["parts"]["head"] = 1e-6
    w = sens.session_weights(table, pert, truth)
    assert np.allclose(w[truth["part"].to_numpy() == "head"], 1e-6 / 4 * 13 / (13 - 4 + 1e-6), rtol=1e-6)
    score = w @ mat
    assert score[parts.index("head")] == pytest.approx(min(score), abs=1e-3)
    same = sens.session_weights(
        table, {n: {k: s[k] for k in sens.PERTURBED} for n, s in table["scenarios"].items()}, truth
    )
    assert np.allclose(same, 1.0)


def test_the_default_ranges_give_a_spread_of_rankings():
    table, truth, mat, parts = _toy()
    df, summary = sens.priors_sensitivity(
        table, truth, np.arange(len(truth)), mat, parts, np.full(len(parts), 0.01), np.ones(len(parts), bool), 50, 3, 3
    )
    assert len(df) == 50 and summary["top_k"] == 3
    assert -1.0 <= summary["tau_p5"] < summary["tau_median"] <= 1.0
    assert summary["ranges"]["parts"] == [0.5, 2.0]
    assert 0 < summary["ess_share_median"] < 1.0
