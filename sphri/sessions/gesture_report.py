"""The gesture coding reported against the generator and with intervals.

:func:`confusion_against_generator`: the coded episodes' labels against the
gesture the generator drew for their session (synthetic sessions only), as a
truth x label count matrix (``unlabelled``: no label) with per-gesture recall.
:func:`gesture_counts`: per scenario and gesture, the episode count (argmax
labels) and the expected count (sum of class probabilities), each with a
participant-bootstrap interval (participants resampled with replacement,
``n_boot`` times; the 2.5 and 97.5 percentiles).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sphri.types import GESTURES

UNLABELLED = "unlabelled"


def confusion_against_generator(coded: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Rows: the generator's gesture; columns: the episode label (and ``unlabelled``), plus ``n`` and ``recall``."""
    tr = truth.reset_index(drop=True)["gesture"].to_numpy()[coded["session"].to_numpy()]
    lab = np.where(coded["gesture"].astype(str).to_numpy() == "", UNLABELLED, coded["gesture"].astype(str).to_numpy())
    cols = list(GESTURES) + [UNLABELLED]
    rows = sorted(set(tr.tolist()), key=lambda g: (g not in GESTURES, GESTURES.index(g) if g in GESTURES else 0, g))
    mat = pd.DataFrame(0, index=pd.Index(rows, name="generator"), columns=cols, dtype=np.int64)
    for t, l in zip(tr, lab):
        mat.loc[t, l if l in cols else UNLABELLED] += 1
    mat["n"] = mat[cols].sum(axis=1)
    mat["recall"] = [mat.loc[g, g] / mat.loc[g, "n"] if g in cols and mat.loc[g, "n"] else np.nan for g in mat.index]
    return mat


def gesture_counts(labelled: pd.DataFrame, scenarios: list[str], n_boot: int = 1000, seed: int = 0) -> pd.DataFrame:
    """Per scenario and gesture: ``count``/``expected`` with ``*_lo``/``*_hi`` (95 % participant bootstrap) and
    ``share`` of the scenario's labelled episodes with its interval."""
    ok = labelled[labelled["gesture"].astype(str) != ""]
    units = np.asarray(sorted(pd.unique(labelled["participant"])))
    scen_idx = {s: i for i, s in enumerate(scenarios)}
    g_idx = {g: i for i, g in enumerate(GESTURES)}
    # per participant: (scenarios, gestures) hard counts and expected counts
    hard = np.zeros((units.size, len(scenarios), len(GESTURES)))
    soft = np.zeros_like(hard)
    u_idx = {u: i for i, u in enumerate(units)}
    pcols = [f"p_{g}" for g in GESTURES]
    for r in ok.itertuples(index=False):
        k = scen_idx.get(r.scenario)
        if k is None:
            continue
        u = u_idx[r.participant]
        hard[u, k, g_idx[r.gesture]] += 1
        soft[u, k] += np.nan_to_num(np.array([getattr(r, c) for c in pcols], dtype=float))
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, units.size, size=(n_boot, units.size)) if units.size else np.zeros((0, 0), int)
    bh, bs = hard[draws].sum(axis=1), soft[draws].sum(axis=1)  # (B, S, G); (0, S, G) without participants
    tot = bh.sum(axis=2, keepdims=True)
    bshare = np.divide(bh, tot, out=np.full_like(bh, np.nan), where=tot > 0)
    q = lambda a: (np.nanpercentile(a, 2.5, axis=0), np.nanpercentile(a, 97.5, axis=0))  # noqa: E731
    (hl, hh), (sl, sh) = q(bh), q(bs)
    with np.errstate(all="ignore"):
        shl, shh = q(bshare)
    H, S = hard.sum(axis=0), soft.sum(axis=0)
    rows = []
    for s, si in scen_idx.items():
        n = H[si].sum()
        for g, gi in g_idx.items():
            rows.append(
                dict(
                    scenario=s,
                    gesture=g,
                    n_episodes=int(n),
                    count=int(H[si, gi]),
                    count_lo=hl[si, gi],
                    count_hi=hh[si, gi],
                    expected=S[si, gi],
                    expected_lo=sl[si, gi],
                    expected_hi=sh[si, gi],
                    share=H[si, gi] / n if n else np.nan,
                    share_lo=shl[si, gi],
                    share_hi=shh[si, gi],
                    n_participants=int(units.size),
                    n_boot=int(n_boot),
                )
            )
    return pd.DataFrame(rows)
