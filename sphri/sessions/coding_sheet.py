"""``sphri code sessions=DIR out=DIR [overrides]``: a sheet to code the scenario study's episodes by hand.

The study's own episodes and suggestions (:func:`sphri.sessions.labelling.code_episodes`:
the same composition ``+experiment=scenario_study data=sessions data.root=DIR`` plus the
overrides, the same segmentation and gesture model) are written to

- ``out/coding_sheet.html``: one self-contained page (no network: data, script and style
  inlined), one section per coded episode: a replay of both hands' capsules on the touched
  link with play and step controls, the contact over time, and the gesture model's
  label marked as a suggestion;
- ``out/codes.csv``: one row per coded episode (:data:`sphri.sessions.codes.SHEET_COLUMNS`),
  ``gesture`` and ``coder`` empty, for a person to fill; the study reads it back with
  ``experiment.scenario_study.codes=PATH`` (:mod:`sphri.sessions.codes`).

An existing ``codes.csv`` that already holds codes is never overwritten.
"""

from __future__ import annotations

import csv
import logging
import shlex
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from sphri.args import ArgsError, arg
from sphri.sessions.codes import SHEET_COLUMNS, episode_ids, session_frames
from sphri.types import GESTURES

log = logging.getLogger(__name__)

SHEET = "coding_sheet.html"
CODES = "codes.csv"


def _folder(value: str) -> str | None:
    return None if value.strip() else "give a folder"


def _rate(value: float) -> str | None:
    return None if 1.0 <= value <= 1000.0 else "must be within [1, 1000] frames per second"


@dataclass
class CodeArgs:
    sessions: str = arg(metavar="DIR", check=_folder, help="the sessions folder: the one holding sessions.json")
    out: str = arg(metavar="DIR", check=_folder, help=f"the folder to write {SHEET} and {CODES} to")
    replay_hz: float = arg(15.0, check=_rate, help="frames per second each replay shows (the recording's, thinned)")
    overrides: list[str] = arg(
        [], rest=True, help="the study's config overrides, e.g. robot=reachy2 experiment.scenario_study.episode_gap_s=1"
    )


def sheet_table(labelled: pd.DataFrame, ds) -> pd.DataFrame:
    """The rows of ``codes.csv``: ids, part, frames within the session, the model's suggestion, empty codes."""
    start, end = session_frames(labelled, ds)
    return pd.DataFrame(
        {
            "episode_id": episode_ids(labelled),
            "participant": labelled["participant"].astype(str).to_numpy(),
            "scenario": labelled["scenario"].astype(str).to_numpy(),
            "repetition": labelled["repetition"].astype(int).to_numpy(),
            "episode": labelled["episode"].astype(int).to_numpy(),
            "part": labelled["dominant_part"].astype(str).to_numpy(),
            "start_frame": start,
            "end_frame": end,
            "duration_s": labelled["duration_s"].round(3).to_numpy(),
            "suggestion": labelled["gesture"].astype(str).to_numpy(),
            "suggestion_confidence": labelled["confidence"].round(3).to_numpy(),
            "gesture": "",
            "coder": "",
        },
        columns=list(SHEET_COLUMNS),
    )


def _holds_codes(path: Path) -> int:
    """How many filled ``gesture`` cells the CSV at ``path`` has (0 when there is none or no such file)."""
    if not path.is_file():
        return 0
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:
            return sum(1 for r in csv.DictReader(f) if (r.get("gesture") or "").strip())
    except (UnicodeDecodeError, csv.Error):
        return 1  # not ours to judge: keep it


def write_sheet(out: Path, coded, study_command: str, replay_hz: float) -> list[Path]:
    """Write ``coding_sheet.html`` and ``codes.csv`` for ``coded`` (a :class:`~sphri.sessions.labelling.CodedEpisodes`)."""
    from sphri.sessions.replay import replay_data
    from sphri.templating import render_page

    labelled, ds = coded.labelled, coded.ds
    table = sheet_table(labelled, ds)
    data = replay_data(labelled, ds, coded.bc, coded.robot, replay_hz)
    for ep, part in zip(data["episodes"], table["part"]):
        ep["part"] = part
    out.mkdir(parents=True, exist_ok=True)
    csv_path, html_path = out / CODES, out / SHEET
    table.to_csv(csv_path, index=False)
    page = render_page(
        "coding_sheet.html.j2",
        name=ds.name,
        synthetic=bool(ds.synthetic),
        rows=table.to_dict("records"),
        hands=[int(h) for h in labelled["dominant_hand"]],
        n_hands=[int(h) for h in labelled["hands"]],
        in_training=[bool(x) for x in labelled["in_training"]],
        gestures=GESTURES,
        model_regions=coded.gm.region,
        model_accuracy=coded.gm.accuracy_mean,
        codes_file=CODES,
        study_command=study_command,
        data=data,
    )
    html_path.write_text(page, encoding="utf-8")
    return [html_path, csv_path]


def command(args: CodeArgs) -> int:
    """Write a coding sheet for the scenario study's episodes of recorded sessions: a self-contained HTML page
    (each episode's replay, the model's label as a suggestion) and codes.csv to fill by hand; the study reads
    it back with experiment.scenario_study.codes=PATH."""
    from sphri.config import check_output_dir, compose
    from sphri.pipeline import Memo, open_cache
    from sphri.sessions.labelling import code_episodes
    from sphri.sessions.schema import study_settings

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    root = Path(args.sessions).expanduser()
    if not (root / "sessions.json").is_file():
        raise ArgsError(
            f"sessions={args.sessions}: no sessions.json there (a sessions folder: sphri/sessions/format.py)"
        )
    check_output_dir(args.out, key="out")
    out = Path(args.out).expanduser()
    held = _holds_codes(out / CODES)
    if held:
        raise ArgsError(f"out={args.out}: {out / CODES} already holds {held} codes; move it or choose another out")
    overrides = ["+experiment=scenario_study", "data=sessions", f"data.root={root}", *args.overrides]
    t = time.perf_counter()
    cfg = compose(overrides)
    st = study_settings(cfg)
    coded = code_episodes(cfg, overrides, st, open_cache(cfg), Memo())
    for note in coded.notes:
        if not note.startswith("WARNING"):  # warnings were logged where they were found
            print("note: " + note)
    study = ["sphri", "coverage", *overrides, f"experiment.scenario_study.codes={(out / CODES).resolve()}"]
    files = write_sheet(out, coded, shlex.join(study), args.replay_hz)
    print(
        f"wrote the coding sheet of {len(coded.labelled)} episodes ({coded.ds.name}) in "
        f"{time.perf_counter() - t:.1f} s: {files[0].resolve()}"
    )
    print(f"fill 'gesture' ({', '.join(GESTURES)}) and 'coder' in {files[1].resolve()}, then run:")
    print("  " + shlex.join(study))
    return 0
