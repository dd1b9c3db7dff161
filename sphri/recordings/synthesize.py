"""``sphri synthesize``: synthetic data of each kind sphri reads, written to disk.

``what=gestures`` (the default) writes a gesture-trial dataset (:mod:`sphri.data.synthesize`),
``what=sessions`` the scenario sessions (:mod:`sphri.sessions.synthesize`) and ``what=openxr`` example
OpenXR logs for ``sphri import`` (:mod:`sphri.recordings.examples`).
"""

from __future__ import annotations

import dataclasses
from typing import Literal

from sphri.args import arg
from sphri.data.synthesize import SynthesizeArgs, write_dataset
from sphri.data.synthesize import command as write_gestures


@dataclasses.dataclass
class SynthesizeAnyArgs(SynthesizeArgs):
    what: Literal["gestures", "sessions", "openxr"] = arg(
        "gestures",
        help="gestures: a gesture dataset (loads with data=vr_gesture data.root=DIR); sessions: the scenario "
        "sessions (data=synthetic_sessions; loads with data=sessions data.root=DIR); openxr: example OpenXR "
        "logs for sphri import, one per trial of a small synthetic study (3 participants x 8 gestures x 1 "
        "repetition unless overridden) with manifest.csv and README.txt, into a new or empty folder",
    )


def command(args: SynthesizeAnyArgs) -> int:
    """Write synthetic data to out=DIR, generated exactly as a run generates it: a gesture dataset (the
    default), with what=sessions the scenario sessions, with what=openxr one OpenXR log per trial."""
    if args.what == "sessions":
        from sphri.sessions.synthesize import write_sessions

        return write_sessions(args)
    if args.what == "openxr":
        from sphri.recordings.examples import write_example_logs

        return write_dataset(write_example_logs, args, "logs")
    return write_gestures(args)
