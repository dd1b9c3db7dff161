"""Gesture labels for episodes: a model trained on the gesture dataset in the same job.

:func:`train_gesture_model` runs the classification chain (``data=synthetic``
on one body part of the whole robot at a fixed resolution, the configured
model) through :func:`sphri.pipeline.make_pipeline` (stage cache included),
reports its leave-one-subject-out accuracy, and fits the model on all trials.

:func:`label_episodes` turns each coded episode into a trial of that chain on
the episode's dominant link: the dominant hand's poses moved into the link's
frame make a dataset handed to the same chain (``make_pipeline(cfg, cache,
inputs={"data": ...}, link=...)``: contact, surface, layout, plan, encode,
noise and filter computed and cached as in a job), then the fitted model's
class probabilities (features are in metres, so a Random Forest transfers
between links; episodes on body parts the model never saw are flagged).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from sphri.data.format import make_trials_frame
from sphri.data.handfk import matrix_to_quat
from sphri.hand.kinematics import quat_to_matrix
from sphri.layout.schema import layout_res
from sphri.sessions.format import SessionDataset
from sphri.types import GESTURES, GestureDataset

log = logging.getLogger(__name__)


@dataclass
class GestureModel:
    model: Any
    """The fitted model (made by :func:`sphri.pipeline.model_factory`: ``classes_``, ``geometry``, ``predict_proba``)."""
    regions: list[str]
    """Body parts the model was trained on (one chain each)."""
    res: int
    accuracy_mean: float
    """Mean over the regions of each chain's LOSO accuracy."""
    accuracy_std: float
    n_trials: int
    config: object
    """The composed config of the first region's chain (its components label episodes)."""
    accuracy: dict = field(default_factory=dict)
    """Region -> that chain's LOSO accuracy (``training="episodes"``: participant -> agreement on their episodes)."""
    training: str = "trials"
    """What the model learnt from: ``trials`` (the synthetic gesture study on ``regions``) or ``episodes`` (the
    study's own episodes, each participant's labelled by a model of the others': :mod:`sphri.sessions.episode_coder`;
    ``regions`` are then the body parts touched)."""

    @property
    def region(self) -> str:
        return ", ".join(self.regions)


def train_gesture_model(overrides: list[str], regions: list[str], cache, memo=None) -> GestureModel:
    """Run the chain on each of ``regions`` (LOSO accuracy each) and fit one model on all their trials.

    A model whose input transform is per trial (``TRANSFORM_PER_TRIAL``, the
    Random Forest: features in metres from each skin's own geometry) is fitted
    on the features of every region's trials together; any other model only
    on the first region's windows. ``memo``: a :class:`sphri.pipeline.Memo` shared with the job's other chains.
    """
    from sphri.config import compose
    from sphri.pipeline import make_pipeline, model_factory

    feats: list[np.ndarray] = []
    labels: list[np.ndarray] = []
    accs: dict[str, float] = {}
    first: tuple[Any, Any, Any] | None = None  # the first region's (config, model, windows)
    for region in regions:
        cfg = compose([*overrides, f"data.regions=[{region}]"])
        p = make_pipeline(cfg, cache, memo=memo)
        result, _ = p.get("evaluate")
        accs[region] = float(result.summary()["accuracy_mean"])
        # the windows the model was evaluated on: noise on the windows, then the skin's filter
        windows = p.get("filter")
        model = model_factory(cfg)(geometry=windows.geometry)
        if first is None:
            first = (cfg, model, windows)
        if not getattr(model, "TRANSFORM_PER_TRIAL", False):
            if len(regions) > 1:
                log.warning(
                    "gesture model %s has no per-trial transform: trained on %s only", type(model).__name__, region
                )
            regions = [region]
            break
        feats.append(model.transform(windows.x))
        labels.append(windows.y)
    if first is None:
        raise ValueError("train_gesture_model: no regions to train on")
    cfg, model, windows = first
    if feats:
        model.fit_features(np.concatenate(feats), np.concatenate(labels))
        n = int(sum(len(y) for y in labels))
    else:
        model.fit(windows.x, windows.y, windows.groups)
        n = int(windows.x.shape[0])
    acc = np.array([accs[r] for r in regions])
    return GestureModel(model, list(regions), layout_res(cfg), float(acc.mean()), float(acc.std()), n, cfg, accs)


def _to_link(poses: np.ndarray, link_pose: np.ndarray) -> np.ndarray:
    """(T, C, 7) world poses -> the frame of a link whose world poses are (T, 7)."""
    r = quat_to_matrix(link_pose[:, 3:].astype(np.float64))  # (T, 3, 3)
    t = link_pose[:, :3].astype(np.float64)
    out = np.empty(poses.shape, dtype=np.float64)
    out[..., :3] = np.einsum("tji,tcj->tci", r, poses[..., :3].astype(np.float64) - t[:, None, :])
    out[..., 3:] = matrix_to_quat(np.einsum("tji,tcjk->tcik", r, quat_to_matrix(poses[..., 3:].astype(np.float64))))
    return out


def episode_windows(episodes: pd.DataFrame, ds: SessionDataset, cfg, cache, memo=None):
    """Per dominant link of ``episodes``: (link name, the episodes' index labels per window, the windows).

    Each link's episodes (the dominant hand's poses, 0.5 s either side, moved into the link's frame) are a
    dataset handed to the chain of ``cfg`` (a gesture chain's config) on that link: contact, surface, layout,
    plan, encode, noise and filter computed and cached as in a job. Links whose episodes give no window are
    left out."""
    from sphri.pipeline import make_pipeline

    pad = int(round(0.5 * ds.frame_rate_hz))
    li = {n: i for i, n in enumerate(ds.links)}
    for link_name, eps in episodes.groupby("dominant_link", sort=True):
        chunks: list[np.ndarray] = []
        records: list[dict[str, Any]] = []
        start = 0
        for _k, e in eps.iterrows():
            a = max(int(ds.sessions["start"].iat[e.session]), int(e.start_frame) - pad)
            b = int(e.end_frame) + pad + 1
            b = min(b, int(ds.sessions["start"].iat[e.session] + ds.sessions["n_frames"].iat[e.session]))
            chunks.append(_to_link(ds.hand_poses[a:b, int(e.dominant_hand)], ds.link_poses[a:b, li[link_name]]))
            records.append(
                dict(
                    participant=e.participant,
                    region=link_name,
                    trial_ordinal=len(records) + 1,
                    trial_id=f"{len(records) + 1:04d}_hit",
                    gesture="hit",
                    start=start,
                    n_frames=b - a,
                )
            )
            start += b - a
        gd = GestureDataset(
            name=ds.name,
            synthetic=ds.synthetic,
            hand=ds.hand,
            trials=make_trials_frame(records),
            poses=np.concatenate(chunks).astype(np.float32),
            frame_rate_hz=ds.frame_rate_hz,
        )
        windows = make_pipeline(cfg, cache, inputs={"data": gd}, link=str(link_name), memo=memo).get("filter")
        if windows.x.shape[0] == 0:
            continue
        yield str(link_name), eps.index.to_numpy()[windows.trial_row], windows


def label_episodes(episodes: pd.DataFrame, ds: SessionDataset, gm: GestureModel, cache, memo=None) -> pd.DataFrame:
    """Class probabilities (columns ``p_<gesture>``), ``gesture``, ``confidence``, ``in_training`` per episode.

    Each link's episodes are a dataset handed to the gesture model's chain (its config, seed included),
    which computes their windows as it computed the training windows (:func:`episode_windows`): one wiring,
    one cache.
    """
    classes = [GESTURES[int(c)] for c in gm.model.classes_]
    out = episodes.copy()
    for g in GESTURES:
        out[f"p_{g}"] = np.nan
    for _link, idx, windows in episode_windows(episodes, ds, gm.config, cache, memo):
        gm.model.geometry = windows.geometry
        proba = gm.model.predict_proba(windows.x)
        for j, g in enumerate(classes):
            out.loc[idx, f"p_{g}"] = proba[:, j]
    argmax_labels(out)
    # a part counts as seen when the model was trained on it or on its mirror image (same geometry)
    from sphri.sessions.synthetic import mirror_part

    seen = set(gm.regions) | {mirror_part(r) for r in gm.regions}
    out["in_training"] = out["dominant_part"].astype(str).isin(seen)
    return out


def argmax_labels(out: pd.DataFrame) -> None:
    """Set ``gesture`` (the most probable, "" where any ``p_<gesture>`` is missing) and ``confidence`` (its
    probability) of episodes ``out`` in place, from their ``p_<gesture>`` columns."""
    p = out[[f"p_{g}" for g in GESTURES]].to_numpy(float)
    ok = np.isfinite(p).all(axis=1)
    out["gesture"] = np.where(ok, np.array(GESTURES, dtype=object)[np.nan_to_num(p, nan=-1).argmax(axis=1)], "")
    out["confidence"] = np.where(ok, np.nanmax(np.where(ok[:, None], p, 0.0), axis=1), np.nan)


def gesture_histogram(labelled: pd.DataFrame, scenarios: list[str]) -> pd.DataFrame:
    """Per scenario and gesture: hard count (argmax), expected count (sum of probabilities) and its SD
    (Poisson-binomial: sqrt(sum p (1 - p))), share, mean confidence of the episodes labelled so."""
    rows = []
    for s in scenarios:
        e = labelled[(labelled["scenario"] == s) & (labelled["gesture"] != "")]
        n = len(e)
        for g in GESTURES:
            p = e[f"p_{g}"].to_numpy(float) if n else np.zeros(0)
            hard = int((e["gesture"] == g).sum()) if n else 0
            rows.append(
                dict(
                    scenario=s,
                    gesture=g,
                    n_episodes=n,
                    count=hard,
                    expected=float(p.sum()),
                    expected_sd=float(np.sqrt((p * (1 - p)).sum())),
                    share=hard / n if n else np.nan,
                    mean_confidence=float(e.loc[e["gesture"] == g, "confidence"].mean()) if hard else np.nan,
                )
            )
    return pd.DataFrame(rows)
