"""How well the scenario study's coded episodes can be labelled with gestures, per gesture, against the generator.

For each skin (the study's default for coding: ``gesture_res`` 12 without noise; with the chain's noise, 2 %
salt-and-pepper, with and without a filter; 24 taxels), the coded episodes of the full built-in study
(``robot=reachy2``, 12 participants x 5 scenarios x 3 repetitions, sessions and contacts from the stage cache
in ``--cache``) are turned into windows by the gesture chain on each episode's dominant link
(:func:`sphri.sessions.gestures.episode_windows`), and a Random Forest (the chain's ``model=rf``, its 32
features) is trained on the episodes of the other participants and scores the ones left out
(leave-one-participant-out over every part touched). The scenario is not a feature. Agreement with the
generator's drawn gesture, overall and per gesture (recall), and the number of episodes.

    python bench/bench_study_gesture_coding.py --cache DIR          # full study (sessions from DIR's cache)
    python bench/bench_study_gesture_coding.py --cache DIR --quick  # +debug=fast

Writes ``outputs/bench/study_gesture_coding.json`` (``_quick`` with --quick).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import machine, write_json  # noqa: E402

#: name -> (the study's overrides of the skin, what it is)
SKINS = {
    "default": ([], "the study's default for coding: gesture_res 12, no noise (gesture_noise false)"),
    "res12_noise": (["experiment.scenario_study.gesture_noise=true"], "gesture_res 12, the chain's noise (2 % s&p)"),
    "res24": (["experiment.scenario_study.gesture_res=24"], "24 taxels along the link, no noise"),
    "res24_noise": (
        ["experiment.scenario_study.gesture_res=24", "experiment.scenario_study.gesture_noise=true"],
        "24 taxels, the chain's noise",
    ),
    "res12_noise_despeckle": (
        ["experiment.scenario_study.gesture_noise=true", "filter=despeckle"],
        "gesture_res 12, the chain's noise, despeckle filter",
    ),
    "res24_noise_despeckle": (
        [
            "experiment.scenario_study.gesture_res=24",
            "experiment.scenario_study.gesture_noise=true",
            "filter=despeckle",
        ],
        "24 taxels, the chain's noise, despeckle filter",
    ),
    "res12_noise_persistence": (
        ["experiment.scenario_study.gesture_noise=true", "filter=persistence"],
        "gesture_res 12, the chain's noise, persistence filter",
    ),
}


def lopo_agreement(feats: np.ndarray, y: np.ndarray, groups: np.ndarray, seed: int) -> np.ndarray:
    """Leave-one-participant-out predictions of a Random Forest (sphri's model=rf settings) on features."""
    from sphri.models.rf import RandomForest

    pred = np.empty(len(y), dtype=y.dtype)
    for g in np.unique(groups):
        test = groups == g
        model = RandomForest(seed=seed).fit_features(feats[~test], y[~test])
        pred[test] = model.predict_features(feats[test])
    return pred


def touch_episodes(ds, robot) -> pd.DataFrame:
    """One episode per generated touch, cut where the generator drew it (the drawing hand, the drawn part's link,
    the touch's frames): the segmentation an oracle would give, in the columns of the study's coded episodes."""
    truth, sess = ds.truth.reset_index(drop=True), ds.sessions.reset_index(drop=True)
    link_of = {p.name: p.link for p in robot.parts}
    start = sess["start"].to_numpy(np.int64) + truth["touch_start_frame"].to_numpy(np.int64)
    return pd.DataFrame(
        {
            "session": np.arange(len(sess)),
            "participant": sess["participant"].to_numpy(),
            "start_frame": start,
            "end_frame": start + truth["touch_frames"].to_numpy(np.int64) - 1,
            "dominant_hand": 1,
            "dominant_link": [link_of[p] for p in truth["part"]],
        }
    )


def episode_features(overrides: list[str], cache, memo, segmentation: str = "episodes"):
    """(features, drawn gestures, participants, coded episodes) of a study config's coded episodes, windows from
    the gesture chain on each episode's dominant link; ``segmentation="touch"``: of the generator's touches
    instead (:func:`touch_episodes`)."""
    from sphri.config import compose
    from sphri.pipeline import model_factory
    from sphri.sessions.gestures import episode_windows
    from sphri.sessions.labelling import segment, training_overrides
    from sphri.sessions.schema import study_settings

    cfg = compose(overrides)
    st = study_settings(cfg)
    _, robot, ds, _, _, _, coded, _, _ = segment(cfg, st, cache, memo)
    if segmentation == "touch":
        coded = touch_episodes(ds, robot)
    n_part = int(ds.sessions["participant"].nunique())
    chain = compose([*training_overrides(overrides, st, n_part), f"data.regions=[{st.gesture_regions[0]}]"])
    feats, index, links = [], [], []
    for link, idx, windows in episode_windows(coded, ds, chain, cache, memo):
        model = model_factory(chain)(geometry=windows.geometry)
        feats.append(model.transform(windows.x))
        index.append(idx)
        links.append(np.full(len(idx), str(link), dtype=object))
    idx = np.concatenate(index)
    sess = coded.loc[idx, "session"].to_numpy()
    y = ds.truth.reset_index(drop=True)["gesture"].to_numpy()[sess].astype(str)
    groups = coded.loc[idx, "participant"].to_numpy().astype(str)
    return np.concatenate(feats), y, groups, coded, np.concatenate(links)


def mixed_agreement(feats: np.ndarray, y: np.ndarray, seed: int, folds: int = 4) -> float:
    """Agreement of the same Random Forest under stratified k-fold with participants mixed (a participant's
    episodes on both sides): compared with leave-one-participant-out it shows how much of the gap is the
    shift between participants rather than gestures the features cannot tell apart."""
    from sklearn.model_selection import StratifiedKFold

    from sphri.models.rf import RandomForest

    pred = np.empty(len(y), dtype=y.dtype)
    k = min(folds, int(np.unique(y, return_counts=True)[1].min()))
    for train, test in StratifiedKFold(n_splits=max(k, 2), shuffle=True, random_state=seed).split(feats, y):
        pred[test] = RandomForest(seed=seed).fit_features(feats[train], y[train]).predict_features(feats[test])
    return float((pred == y).mean())


def per_link(pred: np.ndarray, y: np.ndarray, links: np.ndarray) -> dict:
    """Agreement and episode count per dominant link, the most episodes first."""
    names, counts = np.unique(links, return_counts=True)
    return {
        str(n): {"n": int(c), "agreement": float((pred[links == n] == y[links == n]).mean())}
        for n, c in sorted(zip(names, counts), key=lambda t: -t[1])
    }


def measure(base: list[str], extra: list[str], train: list[str] | None = None, segmentation: str = "episodes") -> dict:
    from sphri.config import compose
    from sphri.models.rf import RandomForest
    from sphri.pipeline import Memo, open_cache
    from sphri.types import GESTURES

    overrides = [*base, *extra]
    cfg = compose(overrides)
    cache, memo = open_cache(cfg), Memo()
    t0 = time.perf_counter()
    x, y, groups, coded, links = episode_features(overrides, cache, memo, segmentation)
    if train is None:
        pred = lopo_agreement(x, y, groups, int(cfg.seed))
        n_train = None
    else:  # trained on the episodes of other generated participants (another data.seed), scored on the study's
        xt, yt, _, _, _ = episode_features([*overrides, *train], cache, memo)
        pred = RandomForest(seed=int(cfg.seed)).fit_features(xt, yt).predict_features(x)
        n_train = len(yt)
    per = {
        g: {"n": int((y == g).sum()), "recall": float((pred[y == g] == g).mean())} for g in GESTURES if (y == g).any()
    }
    return {
        "overrides": extra,
        "training": "leave-one-participant-out on the study's episodes" if train is None else train,
        "training_episodes": n_train,
        "segmentation": segmentation,
        "episodes": len(coded),
        "windows": len(y),
        "agreement": float((pred == y).mean()),
        "balanced_agreement": float(np.mean([v["recall"] for v in per.values()])),
        "per_gesture": per,
        "per_link": per_link(pred, y, links),
        "mixed_participants_agreement": mixed_agreement(x, y, int(cfg.seed)),
        "majority_share": float(max((y == g).mean() for g in np.unique(y))),
        "seconds": time.perf_counter() - t0,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", required=True, help="stage cache with the study's sessions and contacts")
    ap.add_argument("--quick", action="store_true", help="+debug=fast")
    ap.add_argument("--skins", nargs="*", default=list(SKINS), choices=list(SKINS))
    ap.add_argument(
        "--train-participants",
        type=int,
        default=0,
        help="train instead on the episodes of this many other generated participants (data.seed=1)",
    )
    ap.add_argument(
        "--segmentation",
        choices=("episodes", "touch"),
        default="episodes",
        help="episodes: the study's coded episodes; touch: the generator's touches, cut where it drew them",
    )
    args = ap.parse_args()
    base = ["+experiment=scenario_study", "robot=reachy2", f"cache.dir={args.cache}", "tracking.enabled=false"]
    if args.quick:
        base.append("+debug=fast")
    out = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "method": (
            "coded episodes of the built-in study (robot=reachy2) as windows of the gesture chain on their dominant "
            "link; Random Forest (model=rf, 32 features) trained on the other participants' episodes, "
            "leave-one-participant-out, every part touched; no scenario feature; agreement with the generator's "
            "drawn gesture"
        ),
        "command": "python bench/bench_study_gesture_coding.py --cache DIR"
        + (" --quick" if args.quick else "")
        + (f" --train-participants {args.train_participants}" if args.train_participants else "")
        + (" --segmentation touch" if args.segmentation == "touch" else ""),
        "skins": {},
    }
    for name in args.skins:
        extra, what = SKINS[name]
        train = [f"data.participants={args.train_participants}", "data.seed=1"] if args.train_participants else None
        r = measure(base, extra, train, args.segmentation)
        r["skin"] = what
        out["skins"][name] = r
        print(f"{name}: agreement {100 * r['agreement']:.1f} % over {r['windows']} episodes ({r['seconds']:.0f} s)")
        print("   " + ", ".join(f"{g} {100 * v['recall']:.0f} % (n {v['n']})" for g, v in r["per_gesture"].items()))
        print("   " + ", ".join(f"{k} {100 * v['agreement']:.0f} % (n {v['n']})" for k, v in r["per_link"].items()))
        print(
            f"   participants mixed (stratified folds): {100 * r['mixed_participants_agreement']:.1f} %; "
            f"most drawn gesture's share {100 * r['majority_share']:.1f} %"
        )
    out["loadavg_after"] = list(__import__("os").getloadavg())
    name = "study_gesture_coding" + (f"_train{args.train_participants}" if args.train_participants else "")
    name += "_touch" if args.segmentation == "touch" else ""
    print(write_json(name + ("_quick" if args.quick else ""), out))


if __name__ == "__main__":
    main()
