"""Episodes: continuous contact that ends after ``gap_s`` without any contact (the study's rule).

Per session, the frames with any contact (either hand, any link) are cut
wherever ``ceil(gap_s * frame_rate)`` or more consecutive frames have none;
each run from its first to its last contact frame is an episode. Episodes
shorter than ``min_frames`` contact frames are kept but not coded. The
*coded* episode of a session is its first episode with at least
``min_frames`` contact frames (the study ends a scenario after its first
coded gesture).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sphri.sessions.contact import BodyContacts
from sphri.sessions.format import SessionDataset

EPISODE_COLUMNS = (
    "session",
    "participant",
    "scenario",
    "repetition",
    "episode",
    "start_frame",
    "end_frame",
    "n_frames",
    "duration_s",
    "n_contact_frames",
    "hands",
    "dominant_hand",
    "dominant_link",
    "dominant_part",
    "parts",
    "coded",
)


def part_of_rows(bc: BodyContacts, robot) -> np.ndarray:
    """(K,) body part of each contact row (``robot.part_labels`` on the row's link; the link name where no part matches)."""
    out = np.empty(bc.n_contacts, dtype=object)
    for li, name in enumerate(bc.links):
        rows = np.flatnonzero(bc.link == li)
        if rows.size == 0:
            continue
        lab = robot.part_labels(name, bc.point_m[rows], bc.normal[rows]) if hasattr(robot, "part_labels") else None
        lab = np.full(rows.size, name, dtype=object) if lab is None else np.where(lab == "", name, lab)
        out[rows] = lab
    return out


def segment_episodes(
    ds: SessionDataset, bc: BodyContacts, row_part: np.ndarray, gap_s: float = 2.0, min_frames: int = 2
) -> pd.DataFrame:
    """One row per episode (columns :data:`EPISODE_COLUMNS`)."""
    if not gap_s > 0:
        raise ValueError(f"gap_s={gap_s} is invalid: must be > 0 seconds")
    gap = int(np.ceil(gap_s * ds.frame_rate_hz - 1e-9))
    sess = ds.frame_session_index()
    rows = []
    row_session = sess[bc.frame]
    order = np.argsort(row_session, kind="stable")
    bounds = np.searchsorted(row_session[order], np.arange(len(ds.sessions) + 1))
    for si, s in enumerate(ds.sessions.itertuples(index=False)):
        r = order[bounds[si] : bounds[si + 1]]
        frames = np.unique(bc.frame[r])
        if frames.size == 0:
            continue
        cut = np.flatnonzero(np.diff(frames) - 1 >= gap) + 1
        coded_done = False
        for k, run in enumerate(np.split(frames, cut), 1):
            a, b = int(run[0]), int(run[-1])
            er = r[(bc.frame[r] >= a) & (bc.frame[r] <= b)]
            hands = np.bincount(bc.hand[er].astype(np.int64), minlength=2)
            dh = int(np.argmax(hands))
            dr = er[bc.hand[er] == dh]
            link_counts = np.bincount(bc.link[dr].astype(np.int64), minlength=len(bc.links))
            parts = pd.Series(row_part[er]).value_counts()
            dparts = pd.Series(row_part[dr]).value_counts()
            coded = (not coded_done) and run.size >= min_frames
            coded_done |= coded
            rows.append(
                dict(
                    session=si,
                    participant=s.participant,
                    scenario=s.scenario,
                    repetition=int(s.repetition),
                    episode=k,
                    start_frame=a,
                    end_frame=b,
                    n_frames=b - a + 1,
                    duration_s=(b - a + 1) / ds.frame_rate_hz,
                    n_contact_frames=int(run.size),
                    hands=int((hands > 0).sum()),
                    dominant_hand=dh,
                    dominant_link=bc.links[int(np.argmax(link_counts))],
                    dominant_part=str(dparts.index[0]),
                    parts=";".join(str(p) for p in parts.index),
                    coded=coded,
                )
            )
    return pd.DataFrame(rows, columns=list(EPISODE_COLUMNS))
