"""Generated sessions' episodes are coded by a model of the other participants' episodes (leave-one-participant-out).

The model trained on synthetic arm trials agreed with the generator on 8 % of the full study's episodes; trained on
the other participants' episodes, 46 % (``outputs/bench/study_gesture_coding.json``). These tests check the fold
structure (no participant's episodes ever train the model that scores them), the routing of
``experiment.scenario_study.gesture_training`` and its refusal without the generator's gestures.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sphri.config import compose
from sphri.models.rf import RandomForest
from sphri.pipeline import Memo, open_cache
from sphri.sessions import episode_coder as coder
from sphri.sessions.contact import body_contacts
from sphri.sessions.episode_coder import EpisodeTrainingError, code_by_other_participants
from sphri.sessions.episodes import part_of_rows, segment_episodes
from sphri.sessions.labelling import training_mode, training_overrides
from sphri.types import GESTURES
from tests.sessions.conftest import SMALL


@pytest.fixture(scope="module")
def coded_small(small, tmp_path_factory):
    cfg, _, robot, ds = small
    from hydra.utils import instantiate

    bc = body_contacts(ds, robot, instantiate(cfg.contact))
    eps = segment_episodes(ds, bc, part_of_rows(bc, robot))
    coded = eps[eps["coded"]].reset_index(drop=True)
    cache_dir = tmp_path_factory.mktemp("cache")
    st = SimpleNamespace(gesture_repetitions=2, gesture_res=8)
    chain = compose([*training_overrides([*SMALL, f"cache.dir={cache_dir}"], st, 2), "data.regions=[shoulder_r]"])
    return ds, coded, chain, open_cache(chain), Memo()


def test_no_participant_is_scored_by_a_model_that_saw_their_episodes(coded_small, monkeypatch):
    ds, coded, chain, cache, memo = coded_small
    fits: list[np.ndarray] = []
    real = RandomForest.fit_features

    def spy(self, feats, y, groups=None):
        fits.append(np.asarray(feats).copy())
        return real(self, feats, y, groups)

    seen: dict = {}
    real_features = coder.episode_features

    def rows_spy(*a, **kw):
        x, rows = real_features(*a, **kw)
        seen["rows"] = rows
        return x, rows

    monkeypatch.setattr(RandomForest, "fit_features", spy)
    monkeypatch.setattr(coder, "episode_features", rows_spy)
    gm, out = code_by_other_participants(coded, ds, chain, cache, memo)
    people = sorted(coded["participant"].astype(str).unique())
    assert len(fits) == len(people) + 1  # one fold per participant, then the final model on every episode
    allx = fits[-1]  # in the order of seen["rows"] (coded's row labels, link by link)
    assert len(allx) == gm.n_trials == len(coded)
    who = coded.loc[seen["rows"], "participant"].astype(str).to_numpy()
    for p, x in zip(people, fits[:-1]):
        mine = who == p
        # the fold's training rows are exactly the other participants' rows (features compared row by row)
        assert len(x) == len(coded) - mine.sum()
        held = {r.tobytes() for r in allx[mine]}
        assert not any(r.tobytes() in held for r in x)
    assert gm.training == "episodes" and set(gm.accuracy) == set(people)
    drawn = ds.truth.reset_index(drop=True)["gesture"].to_numpy()[coded["session"].to_numpy()]
    for p in people:
        mine = coded["participant"].astype(str).to_numpy() == p
        assert gm.accuracy[p] == pytest.approx(float((out["gesture"].to_numpy()[mine] == drawn[mine]).mean()))
    probs = out[[f"p_{g}" for g in GESTURES]].to_numpy(float)
    assert np.allclose(probs.sum(axis=1), 1.0) and set(out["gesture"]) <= set(GESTURES)


def test_auto_codes_generated_sessions_by_episodes_and_recorded_ones_by_trials(small):
    _, _, _, ds = small
    auto = SimpleNamespace(gesture_training="auto")
    assert training_mode(auto, ds) == "episodes"
    assert training_mode(auto, SimpleNamespace(truth=None)) == "trials"
    assert training_mode(SimpleNamespace(gesture_training="trials"), ds) == "trials"
    assert compose(["+experiment=scenario_study"]).experiment.scenario_study.gesture_training == "auto"


def test_episodes_without_the_generator_gestures_are_refused(coded_small):
    ds, coded, chain, cache, memo = coded_small
    recorded = SimpleNamespace(**{k: getattr(ds, k) for k in ("sessions", "links", "hand_poses", "link_poses")})
    recorded.truth = None
    with pytest.raises(EpisodeTrainingError, match="gesture_training=episodes needs generated sessions"):
        code_by_other_participants(coded, recorded, chain, cache, memo)
    one = coded[coded["participant"] == coded["participant"].iloc[0]]
    with pytest.raises(EpisodeTrainingError, match="2 participants or more, got 1"):
        code_by_other_participants(one, ds, chain, cache, memo)


def test_a_wrong_training_mode_fails_at_composition():
    from sphri.config import ConfigError

    with pytest.raises(ConfigError, match="gesture_training"):
        compose(["+experiment=scenario_study", "experiment.scenario_study.gesture_training=people"])


def test_the_coding_chain_is_noiseless_unless_asked_and_gets_the_skin_settings():
    st = SimpleNamespace(gesture_repetitions=2, gesture_res=8, gesture_noise=False)
    given = ["+experiment=scenario_study", "noise.p=0.05", "filter=despeckle", "model.n_estimators=50"]
    quiet = training_overrides(given, st, 3)
    assert quiet[-1] == "noise=none" and "noise.p=0.05" not in quiet
    cfg = compose([*quiet, "data.regions=[shoulder_r]"])
    assert cfg.noise._target_.endswith("NoNoise")
    # a setting inside a group reaches the coding chain, not only the group's choice
    assert cfg.filter._target_.endswith("DespeckleFilter") and cfg.model.n_estimators == 50
    st.gesture_noise = True
    noisy = training_overrides(given, st, 3)
    assert "noise=none" not in noisy and compose([*noisy, "data.regions=[shoulder_r]"]).noise.p == 0.05
