"""Gestures coded by people: the coding sheet's CSV read back into the study, and the coders' agreement.

``sphri code`` (:mod:`sphri.sessions.coding_sheet`) writes ``codes.csv``, one
row per coded episode (:data:`SHEET_COLUMNS`) with empty ``gesture`` and
``coder`` cells. A person fills them; the study reads the file with
``experiment.scenario_study.codes=PATH`` and uses those codes instead of the
gesture model's labels for the gesture histogram, the counts and the
``by=gesture`` maps (the model's label stays beside them as ``suggestion``).

Two or more coders code the same episodes in one file: one row per episode and
coder (copy the rows, fill ``coder`` with each name). The study uses the codes
of ``experiment.scenario_study.coder`` (default: the coder of the first row),
who must have coded every episode; every pair of coders gets Cohen's kappa
(:func:`sklearn.metrics.cohen_kappa_score`) over the episodes both coded, and
the model's suggestions get theirs against the study's coder.

Rows are counted as a spreadsheet shows them (the header is row 1). Each
defect is one :class:`CodesError` naming the file, the row and the field: an
unknown gesture, an empty cell, an episode the study does not code, frames that
are not the study's, a coder coding an episode twice, an episode the study's
coder left out.
"""

from __future__ import annotations

import csv
import difflib
import itertools
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri.config import ConfigError
from sphri.types import GESTURES

#: Columns of the coding sheet's CSV, in order (frames count from 0 within the session, as the session files do).
SHEET_COLUMNS: tuple[str, ...] = (
    "episode_id",
    "participant",
    "scenario",
    "repetition",
    "episode",
    "part",
    "start_frame",
    "end_frame",
    "duration_s",
    "suggestion",
    "suggestion_confidence",
    "gesture",
    "coder",
)
#: The columns the study reads back.
REQUIRED_COLUMNS: tuple[str, ...] = ("episode_id", "start_frame", "end_frame", "gesture", "coder")


class CodesError(ConfigError):
    """A codes file (``experiment.scenario_study.codes``) is malformed or does not match the study's episodes;
    the message names the file, the row and the field."""


def episode_ids(coded: pd.DataFrame) -> list[str]:
    """``participant/scenario/r<repetition>/e<episode>`` of each episode: its key in the coding sheet."""
    return [
        f"{p}/{s}/r{int(r)}/e{int(e)}"
        for p, s, r, e in zip(coded["participant"], coded["scenario"], coded["repetition"], coded["episode"])
    ]


def session_frames(coded: pd.DataFrame, ds) -> tuple[np.ndarray, np.ndarray]:
    """(start, end) frame of each episode within its session (0-based, the session files' ``frame``)."""
    first = ds.sessions["start"].to_numpy(np.int64)[coded["session"].to_numpy(np.int64)]
    return coded["start_frame"].to_numpy(np.int64) - first, coded["end_frame"].to_numpy(np.int64) - first


def _gesture(path: Path, row: int, text: str, episode: str) -> str:
    g = text.strip().lower()
    if not g:
        raise CodesError(
            f"{path}: row {row}: field 'gesture' is empty (episode {episode}); code it as one of {', '.join(GESTURES)}"
        )
    if g not in GESTURES:
        close = difflib.get_close_matches(g, GESTURES, n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise CodesError(
            f"{path}: row {row}: field 'gesture' is {text!r}: not a gesture{hint}; one of {', '.join(GESTURES)}"
        )
    return g


def _frame(path: Path, row: int, field: str, text: str, expected: int, episode: str) -> None:
    try:
        value = int(text.strip())
    except ValueError:
        raise CodesError(f"{path}: row {row}: field {field!r} is {text!r}: not a frame number") from None
    if value != expected:
        raise CodesError(
            f"{path}: row {row}: field {field!r} is {value}, but episode {episode} of this study has {field}="
            f"{expected} (a sheet of other sessions, or of other episode_gap_s / min_episode_frames?)"
        )


def _read_rows(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        raise CodesError(f"experiment.scenario_study.codes={str(path)!r}: no such file")
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:  # utf-8-sig: a spreadsheet's byte-order mark
            reader = csv.DictReader(f)
            header = list(reader.fieldnames or [])
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise CodesError(f"{path}: not a UTF-8 CSV file ({exc})") from None
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        raise CodesError(f"{path}: missing column(s) {missing}; the coding sheet's columns: {', '.join(SHEET_COLUMNS)}")
    for i, r in enumerate(rows):
        if None in r:  # more cells than the header has columns
            raise CodesError(f"{path}: row {i + 2}: {len(header) + len(r[None])} cells, the header has {len(header)}")
    if not rows:
        raise CodesError(
            f"{path}: no rows; code each episode (fill 'gesture' and 'coder') of the sheet sphri code wrote"
        )
    return rows


@dataclass
class HumanCodes:
    """The codes read from a file: one row per (episode, coder); ``coder`` is the one the study uses."""

    path: Path
    table: pd.DataFrame
    """Columns ``episode_id``, ``coder``, ``gesture``, ``row`` (the spreadsheet row)."""
    coder: str

    @property
    def coders(self) -> list[str]:
        """Every coder, in the order of their first row."""
        return list(dict.fromkeys(self.table["coder"]))

    def of(self, coder: str) -> pd.Series:
        """episode_id -> gesture of ``coder``."""
        t = self.table[self.table["coder"] == coder]
        return pd.Series(t["gesture"].to_numpy(), index=t["episode_id"].to_numpy())

    def apply(self, labelled: pd.DataFrame) -> pd.DataFrame:
        """``labelled`` with the study coder's gestures: ``gesture`` (``p_<gesture>`` one-hot on it, ``confidence``
        1: a person's code has no probability), ``coder``; the model's label and confidence move to ``suggestion``
        and ``suggestion_confidence``."""
        out = labelled.copy()
        code = self.of(self.coder).reindex(episode_ids(out)).to_numpy()
        out["suggestion"] = out["gesture"]
        out["suggestion_confidence"] = out["confidence"]
        out["gesture"] = code
        out["coder"] = self.coder
        for g in GESTURES:
            out[f"p_{g}"] = (code == g).astype(float)
        out["confidence"] = 1.0
        return out

    def agreement(self, labelled: pd.DataFrame) -> list[dict[str, Any]]:
        """Per pair of coders (and the model's suggestions against the study's coder): the episodes both coded,
        the share they agree on, Cohen's kappa (NaN where it is undefined: both used one and the same gesture)."""
        pairs = [(a, b, self.of(a), self.of(b)) for a, b in itertools.combinations(self.coders, 2)]
        model = labelled[labelled["suggestion"].astype(str) != ""]
        pairs.append(
            (
                self.coder,
                "model",
                self.of(self.coder),
                pd.Series(model["suggestion"].to_numpy(), index=episode_ids(model)),
            )
        )
        rows = []
        for a, b, ga, gb in pairs:
            shared = ga.index.intersection(gb.index)
            x, y = ga[shared].to_numpy(), gb[shared].to_numpy()
            rows.append(
                dict(
                    coder_a=a,
                    coder_b=b,
                    n_episodes=int(len(shared)),
                    agreement=float((x == y).mean()) if len(shared) else float("nan"),
                    kappa=_kappa(x, y),
                )
            )
        return rows

    def summary(self, labelled: pd.DataFrame) -> dict[str, Any]:
        return {
            "file": str(self.path),
            "coder": self.coder,
            "coders": self.coders,
            "n_episodes": int((self.table["coder"] == self.coder).sum()),
            "agreement": [  # NaN (undefined kappa, no shared episode) as null: summary.json stays strict JSON
                {k: (None if isinstance(v, float) and v != v else v) for k, v in r.items()}
                for r in self.agreement(labelled)
            ],
        }

    def notes(self, labelled: pd.DataFrame) -> list[str]:
        """One line on whose codes the study uses, one per pair of coders with their Cohen's kappa."""
        n = int((self.table["coder"] == self.coder).sum())
        out = [
            f"gestures coded by hand: the {n} codes of coder {self.coder!r} in {self.path} (the model's labels are "
            "suggestions)"
        ]
        for r in self.agreement(labelled):
            who = "the model's suggestions" if r["coder_b"] == "model" else f"coder {r['coder_b']!r}"
            if not r["n_episodes"]:
                out.append(f"coder {r['coder_a']!r} and {who} share no episode: no agreement measured")
                continue
            k = r["kappa"]
            kappa = f"Cohen's kappa {k:.2f}" if k == k else "Cohen's kappa undefined (one and the same gesture only)"
            out.append(
                f"coder {r['coder_a']!r} and {who} agree on {round(r['agreement'] * r['n_episodes'])} of "
                f"{r['n_episodes']} episodes ({r['agreement']:.0%}), {kappa}"
            )
        return out


def _kappa(x: np.ndarray, y: np.ndarray) -> float:
    from sklearn.metrics import cohen_kappa_score

    if len(x) == 0:
        return float("nan")
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")  # 0/0 when both raters used one and the same gesture: NaN, said so
        return float(cohen_kappa_score(x, y, labels=list(GESTURES)))


def read_codes(path: str | Path, coded: pd.DataFrame, ds, coder: str | None = None) -> HumanCodes:
    """The codes in ``path`` for the study's ``coded`` episodes of the sessions ``ds``, checked row by row
    (:class:`CodesError`); ``coder``: whose codes the study uses (None: the first row's)."""
    path = Path(path)
    rows = _read_rows(path)
    ids = episode_ids(coded)
    start, end = session_frames(coded, ds)
    known = {e: (int(a), int(b)) for e, a, b in zip(ids, start, end)}
    seen: dict[tuple[str, str], int] = {}
    table = []
    for i, r in enumerate(rows):
        row = i + 2
        eid = (r["episode_id"] or "").strip()
        if not eid:
            raise CodesError(f"{path}: row {row}: field 'episode_id' is empty")
        if eid not in known:
            close = difflib.get_close_matches(eid, ids, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise CodesError(
                f"{path}: row {row}: field 'episode_id' is {eid!r}: not an episode this study codes{hint} "
                f"({len(ids)} coded episodes; a sheet of other sessions or other episode settings?)"
            )
        _frame(path, row, "start_frame", r["start_frame"] or "", known[eid][0], eid)
        _frame(path, row, "end_frame", r["end_frame"] or "", known[eid][1], eid)
        gesture = _gesture(path, row, r["gesture"] or "", eid)
        who = (r["coder"] or "").strip()
        if not who:
            raise CodesError(f"{path}: row {row}: field 'coder' is empty (episode {eid}); name who coded it")
        if (eid, who) in seen:
            raise CodesError(
                f"{path}: row {row}: field 'coder': {who!r} codes episode {eid} a second time "
                f"(first in row {seen[eid, who]})"
            )
        seen[eid, who] = row
        table.append(dict(episode_id=eid, coder=who, gesture=gesture, row=row))
    frame = pd.DataFrame(table)
    coders = list(dict.fromkeys(frame["coder"]))
    chosen = coders[0] if coder is None else coder
    if chosen not in coders:
        raise CodesError(
            f"experiment.scenario_study.coder={chosen!r}: no row of {path} is coded by them; coders: {', '.join(coders)}"
        )
    missing = [e for e in ids if (e, chosen) not in seen]
    if missing:
        raise CodesError(
            f"{path}: field 'coder': {chosen!r}, whose codes the study uses, has no row for {len(missing)} of the "
            f"{len(ids)} coded episodes, e.g. {missing[0]}; code every episode"
        )
    return HumanCodes(path, frame, chosen)
