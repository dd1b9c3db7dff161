"""How stable the body-part ranking is under the scenario priors' assumptions.

The synthetic sessions draw, per session, a gesture, a body part and whether
a second hand touches, from the priors table's weights
(:mod:`sphri.sessions.synthetic`). A perturbed table (each weight of a
scenario's ``parts`` and ``gestures`` times a factor, and the odds of
``two_hands`` times a factor, each factor log-uniform in the entry's
``perturb: [lo, hi]`` range, seeded) would draw the same sessions with other
probabilities. :func:`session_weights` gives each generated session its
importance weight under the perturbed table (its draw's probability under the
perturbed table over that under the table it was drawn from), so the ranking
under the perturbed table is the weighted count of contact frames per cm^2,
without generating sessions again. :func:`priors_sensitivity` compares each
draw's ranking of the mountable parts with the unperturbed one: Kendall's tau-b
and the overlap of the top ``k`` parts, with the effective sample size of the
weights (``(sum w)^2 / sum w^2`` over the sessions, as a share of them).

What this does not perturb: the geometric settings (start distances, approach
times, the base's speed, the tail), which change the sessions themselves.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import kendalltau

from sphri.sessions.synthetic import DIRECTIONS

#: The settings of a scenario the sensitivity run perturbs (weights of a draw, and a probability).
PERTURBED = ("parts", "gestures", "two_hands")


def _part_prob(weights: dict[str, float], part: str, side: float) -> float:
    """P(the drawn key resolves to ``part``) for a participant on ``side`` (see ``resolve_part``)."""
    total = sum(weights.values())
    p = 0.0
    for key, w in weights.items():
        for suffix, near in (("_near", True), ("_far", False)):
            if key.endswith(suffix):
                base = key[: -len(suffix)]
                if abs(side) <= 1e-9:
                    p += w * 0.5 * (part in (f"{base}_l", f"{base}_r"))
                else:
                    p += w * (part == f"{base}_{'l' if (side > 0) == near else 'r'}")
                break
        else:
            p += w * (part == key)
    return p / total


def draw_probability(scenario: dict[str, Any], gesture: str, part: str, two_hands: bool, side: float) -> float:
    """The probability of one session's draw (gesture, part, one or two hands) under a scenario's priors."""
    g = {k: float(v) for k, v in scenario["gestures"].items()}
    pg = g.get(gesture, 0.0) / sum(g.values())
    pp = _part_prob({k: float(v) for k, v in scenario["parts"].items()}, part, side)
    q = float(scenario["two_hands"])
    return pg * pp * (q if two_hands else 1.0 - q)


def perturb(table: dict[str, Any], rng: np.random.Generator) -> dict[str, dict[str, Any]]:
    """Per scenario, its ``parts``, ``gestures`` and ``two_hands`` with each weight (and the odds of
    ``two_hands``) times a log-uniform factor in its provenance's ``perturb`` range (no range: unchanged)."""
    prov = table.get("provenance", {})
    out: dict[str, dict[str, Any]] = {}
    for name, s in table["scenarios"].items():

        def factor(field: str, n: int, name: str = name) -> np.ndarray:
            lo, hi = prov.get(f"scenarios.{name}.{field}", {}).get("perturb", [1.0, 1.0])
            return np.exp(rng.uniform(np.log(lo), np.log(hi), n))

        new: dict[str, Any] = {}
        for field in ("parts", "gestures"):
            f = factor(field, len(s[field]))
            new[field] = {k: float(v) * fk for (k, v), fk in zip(s[field].items(), f)}
        q = float(s["two_hands"])
        f2 = float(factor("two_hands", 1)[0])
        new["two_hands"] = q if q in (0.0, 1.0) else q * f2 / (1.0 - q + q * f2)
        out[name] = new
    return out


def session_weights(table: dict[str, Any], perturbed: dict[str, dict[str, Any]], truth: pd.DataFrame) -> np.ndarray:
    """Per session (rows of ``truth``: scenario, start_position, gesture, part, two_hands), its draw's probability
    under ``perturbed`` over that under ``table`` (1 for every session when nothing is perturbed)."""
    w = np.empty(len(truth))
    for i, r in enumerate(truth.itertuples(index=False)):
        side = float(np.round(np.sin(np.radians(DIRECTIONS[r.start_position])), 6))
        base = table["scenarios"][r.scenario]
        p = draw_probability(base, r.gesture, r.part, bool(r.two_hands), side)
        q = draw_probability({**base, **perturbed[r.scenario]}, r.gesture, r.part, bool(r.two_hands), side)
        w[i] = q / p
    return w


def priors_sensitivity(
    table: dict[str, Any],
    truth: pd.DataFrame,
    frame_session: np.ndarray,
    mat: np.ndarray,
    parts: list[str],
    area_m2: np.ndarray,
    allowed: np.ndarray,
    draws: int,
    seed: int,
    top_k: int = 5,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The ranking of the mountable parts (``allowed``) by contact frames per cm^2 of the (U, parts) frame-part
    matrix ``mat`` (frame ``u`` from session ``frame_session[u]``), against ``draws`` perturbed priors.

    Returns one row per draw (``tau``, ``top_k_overlap``, ``same_first``, ``ess_share``) and a summary: median and
    5th percentile of tau and of the top-k overlap, the share of draws with the same first part, the ranges and
    the settings perturbed."""
    if draws < 1:
        raise ValueError(f"experiment.scenario_study.sensitivity_draws={draws} is invalid: at least 1")
    truth = truth.reset_index(drop=True)
    keep = np.flatnonzero(allowed)
    if keep.size < 2:
        raise ValueError(f"priors sensitivity: {keep.size} mountable part(s) touched; a ranking needs 2")
    k = min(int(top_k), keep.size)
    m = mat[:, keep].astype(np.float64)
    area = area_m2[keep] * 1e4
    base = m.sum(axis=0) / area
    names = np.array([parts[j] for j in keep])
    base_order = np.lexsort((names, -base))  # as the ranking: frames per cm^2, then the part's name
    base_top = set(base_order[:k])
    rng = np.random.default_rng([int(seed), 7])
    rows = []
    for d in range(draws):
        w = session_weights(table, perturb(table, rng), truth)
        score = (w[frame_session] @ m) / area
        order = np.lexsort((names, -score))
        rows.append(
            dict(
                draw=d,
                tau=float(kendalltau(base, score).statistic),
                top_k_overlap=len(set(order[:k]) & base_top) / k,
                same_first=bool(order[0] == base_order[0]),
                first=str(names[order[0]]),
                ess_share=float(w.sum() ** 2 / (w**2).sum() / len(w)),
            )
        )
    df = pd.DataFrame(rows)
    ranges: dict[str, Any] = {}
    for key, e in table.get("provenance", {}).items():
        if "perturb" in e and key.split(".")[-1] in PERTURBED:
            ranges.setdefault(key.split(".")[-1], {})[key.split(".")[1]] = list(e["perturb"])
    for fld, per in list(ranges.items()):  # one range for every scenario: stated once
        if len({tuple(r) for r in per.values()}) == 1 and len(per) == len(table["scenarios"]):
            ranges[fld] = next(iter(per.values()))
    summary = {
        "method": (
            "importance weights of the generated sessions under perturbed priors (each weight of parts and gestures, "
            "and the odds of two_hands, times a log-uniform factor in its perturb range); ranking of the mountable "
            "parts by contact frames per cm^2 against the unperturbed one"
        ),
        "draws": int(draws),
        "seed": int(seed),
        "ranges": ranges,
        "n_parts_ranked": int(keep.size),
        "top_k": k,
        "unperturbed_top": [str(names[j]) for j in base_order[:k]],
        "tau_median": float(df["tau"].median()),
        "tau_p5": float(df["tau"].quantile(0.05)),
        "top_k_overlap_median": float(df["top_k_overlap"].median()),
        "top_k_overlap_p5": float(df["top_k_overlap"].quantile(0.05)),
        "same_first_share": float(df["same_first"].mean()),
        "ess_share_median": float(df["ess_share"].median()),
    }
    return df, summary
