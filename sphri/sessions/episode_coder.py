"""Gesture labels for generated sessions from the other participants' episodes (leave-one-participant-out).

``experiment.scenario_study.gesture_training=episodes`` (and ``auto`` for generated sessions, which carry the
generator's truth table): each coded episode becomes a window of the gesture chain on its dominant link, as in
:func:`sphri.sessions.gestures.label_episodes` (:func:`sphri.sessions.gestures.episode_windows`, the chain's
contact, surface, layout, encoding, noise and filter), and the chain's model (a per-trial transform: features in
metres, so one model spans every link) is trained on the episodes of every other participant, on every body
part touched, with the generator's drawn gesture as the label, and scores the left-out participant's. The
scenario is not a feature.

Why not the default for every study: recorded sessions have no drawn gesture to train on; there the model is
trained on the synthetic gesture study (``gesture_training=trials``) or a person codes the episodes
(``codes=PATH``). Why for generated sessions: the model trained on synthetic arm trials agreed with the generator
on 8 % of the full study's episodes (it called 108 of 157 poke), the one trained on other participants' episodes
on 46 % (``outputs/bench/study_gesture_coding.json``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sphri.sessions.format import SessionDataset
from sphri.sessions.gestures import GestureModel, argmax_labels, episode_windows
from sphri.types import GESTURES


class EpisodeTrainingError(ValueError):
    """Episodes cannot train the gesture model (no drawn gestures, one participant, a model without features)."""


def episode_features(coded: pd.DataFrame, ds: SessionDataset, chain, cache, memo=None):
    """(features (n, k), the row label in ``coded`` of each feature row) of the coded episodes' windows on their
    dominant links (``chain``: the gesture chain's composed config), link by link."""
    from sphri.pipeline import model_factory

    feats, rows = [], []
    for _link, idx, windows in episode_windows(coded, ds, chain, cache, memo):
        model = model_factory(chain)(geometry=windows.geometry)
        if not getattr(model, "TRANSFORM_PER_TRIAL", False):
            raise EpisodeTrainingError(
                f"experiment.scenario_study.gesture_training=episodes needs a model with per-trial features "
                f"(model=rf); model {type(model).__name__} has none"
            )
        feats.append(model.transform(windows.x))
        rows.append(idx)
    if not feats:
        return np.zeros((0, 0)), np.zeros(0, dtype=np.int64)
    return np.concatenate(feats), np.concatenate(rows)


def code_by_other_participants(
    coded: pd.DataFrame, ds: SessionDataset, chain, cache, memo=None
) -> tuple[GestureModel, pd.DataFrame]:
    """(model summary, ``coded`` with ``p_<gesture>``, ``gesture``, ``confidence``, ``in_training``): each
    participant's coded episodes labelled by the chain's model trained on every other participant's (see module).
    ``in_training``: the episode's body part (or its mirror image) is among the training episodes' parts."""
    from sphri.layout.schema import layout_res
    from sphri.pipeline import model_factory
    from sphri.sessions.synthetic import mirror_part

    if ds.truth is None or "gesture" not in ds.truth:
        raise EpisodeTrainingError(
            "experiment.scenario_study.gesture_training=episodes needs generated sessions (the generator's drawn "
            "gestures); recorded sessions: gesture_training=trials, or codes=PATH"
        )
    out = coded.copy()
    for g in GESTURES:
        out[f"p_{g}"] = np.nan
    out["in_training"] = False
    x, rows = episode_features(coded, ds, chain, cache, memo)
    drawn = ds.truth.reset_index(drop=True)["gesture"].astype(str).to_numpy()
    y = np.array([GESTURES.index(g) for g in drawn[coded.loc[rows, "session"].to_numpy(np.int64)]], dtype=np.int64)
    who = coded.loc[rows, "participant"].astype(str).to_numpy()
    part = coded.loc[rows, "dominant_part"].astype(str).to_numpy()
    if np.unique(who).size < 2:
        raise EpisodeTrainingError(
            f"experiment.scenario_study.gesture_training=episodes needs episodes of 2 participants or more, got "
            f"{np.unique(who).size}"
        )
    proba = np.full((len(rows), len(GESTURES)), np.nan)
    seen = np.zeros(len(rows), dtype=bool)
    per: dict[str, float] = {}
    for p in np.unique(who):
        test = who == p
        model = model_factory(chain)(geometry=None).fit_features(x[~test], y[~test])
        proba[np.ix_(test, model.classes_.astype(np.int64))] = model.predict_proba_features(x[test])
        trained = set(part[~test]) | {mirror_part(q) for q in part[~test]}
        seen[test] = [q in trained for q in part[test]]
        per[str(p)] = float((np.nan_to_num(proba[test], nan=-1.0).argmax(axis=1) == y[test]).mean())
    proba = np.nan_to_num(proba, nan=0.0)
    for j, g in enumerate(GESTURES):
        out.loc[rows, f"p_{g}"] = proba[:, j]
    out.loc[rows, "in_training"] = seen
    argmax_labels(out)
    acc = np.array(list(per.values()))
    final = model_factory(chain)(geometry=None).fit_features(x, y)
    gm = GestureModel(
        final,
        sorted(set(part)),
        layout_res(chain),
        float(acc.mean()),
        float(acc.std()),
        int(len(rows)),
        chain,
        per,
        training="episodes",
    )
    return gm, out
