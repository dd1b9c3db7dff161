"""The study's coded episodes and their gesture labels: one computation for the study and its coding sheet.

:func:`code_episodes` reads a composed study config's sessions and their
whole-body contacts through the stage cache (:func:`load_sessions_and_contacts`,
the ``sessions`` and ``body_contact`` rows of :data:`sphri.stages.STAGES`, whose
compute this module declares in :data:`sphri.pipeline.COMPUTE`), segments the episodes
(:func:`sphri.sessions.episodes.segment_episodes`), keeps each session's coded
one, trains the gesture model in the same job
(:func:`sphri.sessions.gestures.train_gesture_model`, on the synthetic gesture
study with the study's robot) and labels the coded episodes with it
(:func:`sphri.sessions.gestures.label_episodes`); for generated sessions, by
default, each participant's episodes are labelled by a model trained on the
other participants' episodes instead (:mod:`sphri.sessions.episode_coder`). The scenario study
(:func:`sphri.sessions.study.run_study`) maps them; ``sphri code``
(:mod:`sphri.sessions.coding_sheet`) shows them to a person to code by hand.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from sphri.pipeline import COMPUTE, StageCompute

log = logging.getLogger(__name__)

#: Overrides of the study that also set the gesture model's own job (its chain on ``data=synthetic``).
TRAINING_KEYS = (
    "debug",
    "cache.dir",
    "output_dir",
    "cache.enabled",
    "seed",
    "model",
    "noise",
    "filter",
    "encoder",
    "layout",
    "surface",
    "window",
    "contact",
    "hand",
)


def _sessions_config(p) -> dict[str, Any]:
    """The sessions' key config: the data settings and the text of the priors table they are drawn from."""
    from sphri.config import result_config
    from sphri.integrity import stable_hash

    config: dict[str, Any] = {"data": result_config(p.cfg.data)}
    priors = getattr(p.components["data"], "priors", None)
    if priors and Path(priors).is_file():  # an edited table of assumptions regenerates the sessions
        config["priors_table"] = stable_hash(Path(priors).read_text())
    return config


def _sessions(p) -> Any:
    return p.components["data"].load(p.get("hand"), p.get("robot") if p.uses("robot") else None)


def _body_contact(p) -> Any:
    from sphri.sessions.contact import body_contacts

    return body_contacts(p.get("sessions"), p.get("robot"), p.components["contact"])


# the study's rows of sphri.stages.STAGES (their compute_module): declared in the one registry of stage computes
COMPUTE["sessions"] = StageCompute(_sessions, config=_sessions_config)
COMPUTE["body_contact"] = StageCompute(_body_contact)


def robot_overrides(overrides: Sequence[str]) -> list[str]:
    """The study's robot overrides for the gesture model's own job: the same robot (the experiment's default
    ``robot=reachy_full`` unless ``robot=...`` is given), with its ``robot.*`` settings, and where configs are
    found (``hydra.searchpath``: a robot config of one's own) and which packages they may name (``plugins``)."""
    keyed = [(o.lstrip("+~").split("=", 1)[0], o) for o in overrides]
    mine = [o for k, o in keyed if k in ("robot", "hydra.searchpath", "plugins") or k.startswith("robot.")]
    if not any(k == "robot" for k, _ in keyed):
        mine.insert(0, "robot=reachy_full")
    return mine


def load_sessions_and_contacts(cfg, cache, memo=None):
    """(hand, robot, sessions, body contacts, seconds) of a composed study config, through the stage cache."""
    from sphri.pipeline import make_pipeline  # looked up when called (a test may stand in for it)

    p = make_pipeline(cfg, cache, memo=memo)
    hand, robot = p.get("hand"), p.get("robot")
    t0 = time.perf_counter()
    ds = p.get("sessions")
    t1 = time.perf_counter()
    bc = p.get("body_contact")
    return hand, robot, ds, bc, {"sessions": t1 - t0, "contact": time.perf_counter() - t1}


def _override_key(o: str) -> tuple[str, str]:
    """(key, its config group) of a command-line override: ``+noise.p=0.1`` -> (``noise.p``, ``noise``)."""
    key = o.lstrip("+~").split("=")[0]
    return key, key.split(".")[0]


def training_overrides(overrides: Sequence[str], st, n_participants: int) -> list[str]:
    """The gesture model's job: the study's shared overrides (:data:`TRAINING_KEYS`, a group's choice or any of
    its settings: ``noise=gaussian``, ``noise.p=0.05``), its robot, and the synthetic gesture study at the study's
    ``gesture_res`` and ``gesture_repetitions``; without noise (and none of the noise overrides) unless the
    study's ``gesture_noise`` is set."""
    noisy = bool(getattr(st, "gesture_noise", False))
    out = []
    for o in overrides:
        key, group = _override_key(o)
        if (key in TRAINING_KEYS or group in TRAINING_KEYS) and (noisy or group != "noise"):
            out.append(o)
    out += robot_overrides(overrides)
    out += [
        "data=synthetic",
        f"data.participants={max(n_participants, 2)}",
        f"data.repetitions={st.gesture_repetitions}",
        f"layout.res={st.gesture_res}",
        "tracking.enabled=false",
    ]
    if not noisy:
        out.append("noise=none")  # the coding chain's skin is noiseless unless asked (the setting says why)
    return out


@dataclass
class CodedEpisodes:
    """What :func:`code_episodes` computed for a study config."""

    hand: Any
    robot: Any
    ds: Any
    """The sessions (:class:`sphri.sessions.format.SessionDataset`)."""
    bc: Any
    """Their whole-body contacts (:class:`sphri.sessions.contact.BodyContacts`)."""
    row_part: Any
    """(K,) body part of each contact row."""
    episodes: pd.DataFrame
    """Every episode (:data:`sphri.sessions.episodes.EPISODE_COLUMNS`)."""
    coded: pd.DataFrame
    """The coded episodes (each session's first with ``min_episode_frames`` contact frames)."""
    labelled: pd.DataFrame
    """``coded`` with the gesture model's ``p_<gesture>``, ``gesture``, ``confidence``, ``in_training``."""
    gm: Any
    """The gesture model (:class:`sphri.sessions.gestures.GestureModel`)."""
    notes: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)


def segment(cfg, st, cache, memo=None) -> tuple[Any, ...]:
    """(hand, robot, sessions, contacts, row parts, episodes, coded episodes, notes, seconds): the study's
    episodes before any gesture model."""
    from sphri.sessions.episodes import part_of_rows, segment_episodes

    hand, robot, ds, bc, seconds = load_sessions_and_contacts(cfg, cache, memo)
    t = time.perf_counter()
    row_part = part_of_rows(bc, robot)
    episodes = segment_episodes(ds, bc, row_part, st.episode_gap_s, st.min_episode_frames)
    coded = episodes[episodes["coded"]].reset_index(drop=True)
    notes = []
    n_none = len(ds.sessions) - coded["session"].nunique()
    if n_none:
        notes.append(
            f"{n_none} of {len(ds.sessions)} sessions have no coded episode (no contact of >= "
            f"{st.min_episode_frames} frames)"
        )
    seconds["episodes"] = time.perf_counter() - t
    return hand, robot, ds, bc, row_part, episodes, coded, notes, seconds


def training_mode(st, ds) -> str:
    """``trials`` or ``episodes``: the study's ``gesture_training`` with ``auto`` resolved (``episodes`` for
    generated sessions with the generator's drawn gestures, else ``trials``)."""
    if st.gesture_training != "auto":
        return str(st.gesture_training)
    truth = getattr(ds, "truth", None)
    return "episodes" if truth is not None and "gesture" in truth else "trials"


def label(coded: pd.DataFrame, ds, overrides: Sequence[str], st, cache, memo=None) -> tuple[Any, pd.DataFrame, list]:
    """(gesture model, labelled episodes, notes): the coded episodes labelled by a model trained in this job, on the
    synthetic gesture study (``gesture_training=trials``) or on the other participants' episodes (``episodes``,
    :func:`sphri.sessions.episode_coder.code_by_other_participants`); a note warns of episodes on body parts it
    never saw."""
    from sphri.sessions.gestures import label_episodes, train_gesture_model

    n_part = int(ds.sessions["participant"].nunique())
    train = training_overrides(overrides, st, n_part)
    if training_mode(st, ds) == "episodes":
        from sphri.config import compose
        from sphri.sessions.episode_coder import code_by_other_participants

        chain = compose([*train, f"data.regions=[{st.gesture_regions[0]}]"])
        gm, labelled = code_by_other_participants(coded, ds, chain, cache, memo)
        trained_on = "the other participants' episodes"
    else:
        gm = train_gesture_model(train, list(st.gesture_regions), cache, memo)
        labelled = label_episodes(coded, ds, gm, cache, memo)
        trained_on = gm.region
    notes = []
    outside = labelled[~labelled["in_training"].astype(bool)]
    if len(outside):
        parts = outside["dominant_part"].value_counts()
        msg = (
            f"{len(outside)} of {len(labelled)} coded episodes lie on body parts the gesture model never saw "
            f"(trained on {trained_on}): "
            + ", ".join(f"{p} ({n})" for p, n in parts.items())
            + "; their labels are extrapolated"
        )
        log.warning(msg)
        notes.append("WARNING: " + msg)
    return gm, labelled, notes


def code_episodes(cfg, overrides: Sequence[str], st, cache, memo=None) -> CodedEpisodes:
    """The coded episodes of the composed study config ``cfg`` (from ``overrides``) and their labels."""
    hand, robot, ds, bc, row_part, episodes, coded, notes, seconds = segment(cfg, st, cache, memo)
    t = time.perf_counter()
    gm, labelled, more = label(coded, ds, overrides, st, cache, memo)
    seconds["gestures"] = time.perf_counter() - t
    return CodedEpisodes(hand, robot, ds, bc, row_part, episodes, coded, labelled, gm, notes + more, seconds)
