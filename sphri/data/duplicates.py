"""Duplicate participants: the same recordings under two participant ids (a copied folder).

A participant copied under another id puts the same person on both sides of
a leave-one-subject-out split and inflates every accuracy. The loaders
(``data=vr_gesture``, ``data=sessions``) fingerprint each trial cheaply: its
length, its label and the hand's centre (mean over capsules) at
:data:`SAMPLES` evenly spaced frames. Two trials of different participants
are *near-identical* when label and length agree and the centres differ by
at most :data:`TOLERANCE_M` (root mean square); two participants are
duplicates when at least :data:`SHARED_FRACTION` of the smaller one's trials
have a near-identical trial in the other. What happens then is
``data.duplicates``: ``refuse`` (default: one line naming both ids),
``warn`` (a warning naming both, counted as ``duplicate_participants``) or
``off``.

Cost: the fingerprints come from poses already in memory (3 x
:data:`SAMPLES` numbers per trial); trials are compared only within a
bucket of equal label and length. The time it takes on the built-in study
and the margin between two participants' closest trials there are in
docs/BENCHMARKS.md ("Costs and margins the code's choices rest on").
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Hashable, Sequence

import numpy as np

#: ``data.duplicates`` values.
DUPLICATE_POLICIES: tuple[str, ...] = ("refuse", "warn", "off")
#: Frames sampled per trial for its fingerprint.
SAMPLES = 16
#: Near-identical trials: hand centres within this RMS distance (m) at the sampled frames.
TOLERANCE_M = 0.002
#: Participants sharing near-identical trials for at least this fraction of the smaller one's trials are duplicates.
SHARED_FRACTION = 0.5


def fingerprint(poses: np.ndarray) -> np.ndarray:
    """(SAMPLES * 3,) float64: the hand's centre (mean over every capsule position) at evenly spaced frames.

    ``poses`` is (F, ..., 7) with the position in ``[..., :3]`` (one hand (F, C, 7) or both (F, 2, C, 7)).
    """
    p = np.asarray(poses)
    f = p.shape[0]
    if f == 0:
        return np.zeros(SAMPLES * 3)
    idx = np.round(np.linspace(0, f - 1, SAMPLES)).astype(np.int64)
    pos = p[idx, ..., :3].reshape(SAMPLES, -1, 3).astype(np.float64)
    with np.errstate(invalid="ignore"):
        centre = np.nanmean(np.where(np.isfinite(pos), pos, np.nan), axis=1)
    return np.nan_to_num(centre, nan=0.0).ravel()


def find_duplicates(
    trials: Sequence[tuple[str, Hashable, np.ndarray]],
) -> list[tuple[str, str, int, int]]:
    """Pairs of duplicate participants among ``trials`` (participant id, bucket key, fingerprint).

    The bucket key holds what must agree exactly (label, length, region). Returns
    ``(participant_a, participant_b, shared, of)`` sorted by ids: ``shared`` trials of the one with
    the smaller share have a near-identical trial in the other, out of ``of`` (its trial count).
    """
    n_trials: dict[str, int] = defaultdict(int)
    buckets: dict[Hashable, list[int]] = defaultdict(list)
    for i, (pid, key, _) in enumerate(trials):
        n_trials[pid] += 1
        buckets[key].append(i)
    # matched[(a, b)] = trials of a with a near-identical trial in b
    matched: dict[tuple[str, str], set[int]] = defaultdict(set)
    tol2 = TOLERANCE_M**2 * SAMPLES * 3
    for members in buckets.values():
        if len(members) < 2:
            continue
        pids = [trials[i][0] for i in members]
        if len(set(pids)) < 2:
            continue
        fp = np.stack([trials[i][2] for i in members])
        d2 = ((fp[:, None, :] - fp[None, :, :]) ** 2).sum(axis=-1)
        close = d2 <= tol2
        for a, b in zip(*np.nonzero(close)):
            pa_, pb_ = pids[a], pids[b]
            if pa_ != pb_:
                matched[(pa_, pb_)].add(members[a])
    out = []
    for a, b in sorted({tuple(sorted(k)) for k in matched}):
        ab, ba = len(matched[(a, b)]), len(matched[(b, a)])
        share_a, share_b = ab / n_trials[a], ba / n_trials[b]
        shared, of = (ab, n_trials[a]) if share_a >= share_b else (ba, n_trials[b])
        if shared / of >= SHARED_FRACTION:
            out.append((a, b, shared, of))
    return out


def describe(pair: tuple[str, str, int, int], what: str = "trials") -> str:
    """``participant_01 and participant_04 hold near-identical recordings (16 of 16 trials match ...)``."""
    a, b, shared, of = pair
    return (
        f"{a} and {b} hold near-identical recordings ({shared} of {of} {what} match: same label and length, "
        f"hand path within {TOLERANCE_M * 1000:g} mm RMS)"
    )
