"""Body parts ranked by contact per unit area, and the greedy whole-body placement under a budget.

Units are contact *frames* (a frame counts once for a part however many
capsules touch it). :func:`rank_parts`: per part, its area, the frames that
touch it, their share and frames per cm^2. :func:`greedy_parts`: repeatedly
add the part with the most not-yet-captured frames per cm^2 that still fits
the area budget; a frame is captured when it touches any chosen part.
:func:`placement_table` does it pooled and per scenario, with a
leave-one-participant-out check (choose on the others, score the one left out).
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def frame_part_matrix(
    frames: np.ndarray, elements: np.ndarray, part_index: np.ndarray, n_parts: int
) -> tuple[np.ndarray, np.ndarray]:
    """(unique frames (U,), (U, n_parts) bool) from (frame, element) pairs."""
    uf, inv = np.unique(frames, return_inverse=True)
    m = np.zeros((uf.size, n_parts), dtype=bool)
    m[inv, part_index[elements]] = True
    return uf, m


def rank_parts(m: np.ndarray, parts: list[str], area_m2: np.ndarray) -> pd.DataFrame:
    n = max(m.shape[0], 1)
    frames = m.sum(axis=0)
    df = pd.DataFrame(
        {
            "part": parts,
            "area_cm2": area_m2 * 1e4,
            "contact_frames": frames,
            "frame_share": frames / n,
            "frames_per_cm2": frames / (area_m2 * 1e4),
        }
    )
    return df.sort_values(["frames_per_cm2", "part"], ascending=[False, True]).reset_index(drop=True)


def greedy_parts(m: np.ndarray, area_m2: np.ndarray, budget_m2: float) -> list[int]:
    """Part indices in the order chosen (see module)."""
    chosen: list[int] = []
    covered = np.zeros(m.shape[0], dtype=bool)
    left = float(budget_m2)
    while True:
        gain = (m & ~covered[:, None]).sum(axis=0).astype(float)
        ratio = np.where((area_m2 <= left + 1e-12) & (gain > 0), gain / area_m2, -1.0)
        ratio[chosen] = -1.0
        j = int(np.argmax(ratio))
        if ratio[j] <= 0:
            return chosen
        chosen.append(j)
        covered |= m[:, j]
        left -= float(area_m2[j])


def captured(m: np.ndarray, chosen: list[int]) -> float:
    if m.shape[0] == 0:
        return float("nan")
    return float(m[:, chosen].any(axis=1).mean()) if chosen else 0.0


def placement_table(
    m: np.ndarray,
    frame_group: np.ndarray,
    frame_unit: np.ndarray,
    groups: list[str],
    parts: list[str],
    area_m2: np.ndarray,
    budget_m2: float,
) -> pd.DataFrame:
    """One row per group (``all`` first): chosen parts, area, in-sample and held-out capture."""
    total = float(area_m2.sum())
    rows = []
    for g in ["all"] + list(groups):
        sel = np.ones(m.shape[0], bool) if g == "all" else frame_group == g
        mg, ug = m[sel], frame_unit[sel]
        chosen = greedy_parts(mg, area_m2, budget_m2)
        held = []
        for u in pd.unique(ug):
            tr = ug != u
            if not tr.any():
                continue
            c = greedy_parts(mg[tr], area_m2, budget_m2)
            held.append((captured(mg[~tr], c), int((~tr).sum())))
        hv = np.array([h for h, _ in held]) if held else np.zeros(0)
        rows.append(
            dict(
                group=g,
                n_contact_frames=int(mg.shape[0]),
                parts=";".join(parts[j] for j in chosen),
                area_cm2=float(area_m2[chosen].sum() * 1e4),
                area_share=float(area_m2[chosen].sum() / total),
                captured=captured(mg, chosen),
                heldout_captured=float(hv.mean()) if hv.size else np.nan,
                heldout_min=float(hv.min()) if hv.size else np.nan,
                n_heldout_units=int(hv.size),
            )
        )
    return pd.DataFrame(rows)


def name_parts(parts: list[str], groups: dict[str, tuple[str, ...]]) -> list[str]:
    """Parts in words, whole groups by their group name (largest groups first)."""
    left = list(parts)
    names = []
    for g, members in sorted(groups.items(), key=lambda kv: -len(kv[1])):
        if len(members) > 1 and set(members) <= set(left):
            names.append(g.replace("_", " "))
            left = [p for p in left if p not in members]
    return names + [p.replace("_", " ") for p in left]


def sentence(row: dict | pd.Series, groups: dict[str, tuple[str, ...]]) -> str:
    parts = [p for p in str(row["parts"]).split(";") if p]
    if not parts:
        return f"[{row['group']}] no contact frames: nothing to place"
    names = name_parts(parts, groups)
    words = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    held = row["heldout_captured"]
    held_s = f" ({100 * held:.0f} % on held-out participants)" if held == held else ""
    return (
        f"[{row['group']}] covering the {words} ({row['area_cm2']:.0f} cm^2, {100 * row['area_share']:.0f} % of the "
        f"reachable surface) captures {100 * row['captured']:.0f} % of contact frames{held_s}"
    )
