"""Body parts ranked by contact per unit area, and the greedy whole-body placement under a budget.

Units are contact *frames* (a frame counts once for a part however many
capsules touch it). Only *mountable* parts are ranked and placed
(:func:`mountable_parts`): not a joint's rotating shell (``mountable: false``
in the robot's parts), not a rod narrower than ``min_diameter_mm``, not smaller
than ``min_patch_cm2`` of reachable area. :func:`rank_parts`: per part, its
area, the frames that touch it, their share and frames per cm^2 of reachable
surface; mountable parts first. :func:`greedy_parts`: repeatedly add the
mountable part with the most not-yet-captured frames per cm^2 that still fits
the area budget; a frame is captured when it touches any chosen part. Both use
one criterion (contact frames per cm^2 of a mountable part's reachable
surface), so the greedy's first part is the ranking's first.
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


#: Slices along a part's longest principal axis in which its width is measured (m).
WIDTH_SLICE_M = 0.01


def part_width_mm(points_m: np.ndarray, slice_m: float = WIDTH_SLICE_M) -> float:
    """A body part's width (mm) from its surface points (one link's frame, metres): the median, over slices
    ``slice_m`` thick along the points' longest principal axis (weighted by the points in each), of the larger
    extent of the slice's cross-section (its principal extent across that axis). A rod of diameter d measures
    about d; a plate, its width; a ball of diameter D, sqrt(3)/2 D (the chord halfway up a hemisphere)."""
    x = np.asarray(points_m, dtype=np.float64)
    if len(x) < 3:
        return 0.0
    x = x - x.mean(axis=0)
    y = x @ np.linalg.svd(x, full_matrices=False)[2].T
    b = np.floor((y[:, 0] - y[:, 0].min()) / slice_m).astype(np.int64)
    widths, weights = [], []
    for k in np.unique(b):
        c = y[b == k, 1:]
        if len(c) < 3:
            continue
        c = c - c.mean(axis=0)
        axis = np.linalg.svd(c, full_matrices=False)[2][0]
        widths.append(float(np.ptp(c @ axis)))
        weights.append(len(c))
    if not widths:
        return 0.0
    w, n = np.asarray(widths), np.asarray(weights)
    o = np.argsort(w)
    cum = np.cumsum(n[o])
    return float(w[o][np.searchsorted(cum, cum[-1] / 2)] * 1e3)


def mountable_parts(
    body, robot, reach_area_m2: dict[str, float], min_diameter_mm: float, min_patch_cm2: float
) -> pd.DataFrame:
    """Per body part of ``body``: ``part``, ``reachable_cm2``, ``width_mm`` (:func:`part_width_mm` of all its
    elements), ``mountable`` and ``reason`` (why not: 'out of reach', 'rotating joint', 'narrower than ...',
    'smaller than ...'; '' when mountable)."""
    marked = {p.name for p in getattr(robot, "parts", ()) if not getattr(p, "mountable", True)}
    rows = []
    for p in body.parts:
        sel = np.flatnonzero(body.part == p)
        link = np.bincount(body.link_of[sel]).argmax()
        own = sel[body.link_of[sel] == link] - body.offset[link]  # a part lies on one link (merged links are one)
        width = part_width_mm(body.local[link].points_m[own])
        area = float(reach_area_m2.get(p, 0.0)) * 1e4
        if area <= 0:
            reason = "out of reach"
        elif p in marked:
            reason = "rotating joint (mountable: false in the robot's parts)"
        elif width < min_diameter_mm:
            reason = f"narrower than min_diameter_mm={min_diameter_mm:g} ({width:.0f} mm)"
        elif area < min_patch_cm2:
            reason = f"smaller than min_patch_cm2={min_patch_cm2:g} ({area:.1f} cm^2 reachable)"
        else:
            reason = ""
        rows.append(dict(part=p, reachable_cm2=area, width_mm=width, mountable=reason == "", reason=reason))
    return pd.DataFrame(rows, columns=["part", "reachable_cm2", "width_mm", "mountable", "reason"])


def rank_parts(
    m: np.ndarray, parts: list[str], area_m2: np.ndarray, excluded: dict[str, str] | None = None
) -> pd.DataFrame:
    """Per part: area, contact frames, their share and frames per cm^2; mountable parts first by frames per cm^2
    (the greedy's criterion), then the ``excluded`` ones (part -> reason, in column ``excluded``)."""
    excluded = excluded or {}
    n = max(m.shape[0], 1)
    frames = m.sum(axis=0)
    df = pd.DataFrame(
        {
            "part": parts,
            "area_cm2": area_m2 * 1e4,
            "contact_frames": frames,
            "frame_share": frames / n,
            "frames_per_cm2": frames / (area_m2 * 1e4),
            "excluded": [excluded.get(p, "") for p in parts],
        }
    )
    df["_out"] = df["excluded"] != ""
    df = df.sort_values(["_out", "frames_per_cm2", "part"], ascending=[True, False, True])
    return df.drop(columns="_out").reset_index(drop=True)


def greedy_parts(m: np.ndarray, area_m2: np.ndarray, budget_m2: float, allowed: np.ndarray | None = None) -> list[int]:
    """Part indices in the order chosen (see module); only parts where ``allowed`` (default: all)."""
    chosen: list[int] = [j for j in range(m.shape[1]) if allowed is not None and not allowed[j]]
    blocked = len(chosen)
    covered = np.zeros(m.shape[0], dtype=bool)
    left = float(budget_m2)
    while True:
        gain = (m & ~covered[:, None]).sum(axis=0).astype(float)
        ratio = np.where((area_m2 <= left + 1e-12) & (gain > 0), gain / area_m2, -1.0)
        ratio[chosen] = -1.0
        j = int(np.argmax(ratio))
        if ratio[j] <= 0:
            break
        chosen.append(j)
        covered |= m[:, j]
        left -= float(area_m2[j])
    return chosen[blocked:]


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
    allowed: np.ndarray | None = None,
) -> pd.DataFrame:
    """One row per group (``all`` first): chosen parts (among ``allowed``), area, in-sample and held-out capture;
    ``area_share``: of the reachable surface of all ``parts``."""
    total = float(area_m2.sum())
    rows = []
    for g in ["all"] + list(groups):
        sel = np.ones(m.shape[0], bool) if g == "all" else frame_group == g
        mg, ug = m[sel], frame_unit[sel]
        chosen = greedy_parts(mg, area_m2, budget_m2, allowed)
        held = []
        for u in pd.unique(ug):
            tr = ug != u
            if not tr.any():
                continue
            c = greedy_parts(mg[tr], area_m2, budget_m2, allowed)
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
