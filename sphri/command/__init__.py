"""``sphri <verb>``: one command for everything sphri does.

::

    sphri +debug=fast                    # no verb: run one job (Hydra overrides, exactly as before)
    sphri sweep layout.res=2,4          # = sphri -m layout.res=2,4
    sphri report outputs/sweeps/resolution_rf
    sphri list robot
    sphri help                           # every verb with one line; `sphri VERB --help` its arguments

The verb is picked by argparse (:func:`parser`: one subparser per verb of :data:`VERBS`); the words
after it go unchanged to the verb's own parser. ``run`` and ``sweep`` hand them to Hydra; every other
verb reads ``key=value`` arguments through one parser (:mod:`sphri.args`), typed by a dataclass beside
the verb's code, which also takes the ``--key value`` spellings. ``sphri VERB`` is a verb's one spelling
(``python -m sphri VERB`` runs the same where the script is not on the PATH; no module of sphri is a
command of its own). A first word that is not a verb but looks like an override (``key=value``,
``+group=x``, ``~key``, ``-m``, ``--cfg``) is the ``run`` verb; any other word is an unknown verb: one
line naming the close matches, exit 2.

Standard library only at import: the console script (:mod:`sphri.completion`) reads :data:`VERBS`
to complete the first word on every TAB.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NoReturn


@dataclass(frozen=True)
class Verb:
    """One verb of ``sphri``.

    ``kind`` says who parses its arguments: ``hydra`` (run, sweep: Hydra's overrides), ``args``
    (sphri's ``key=value`` parser: ``schema`` is the argument dataclass, ``target`` the function
    taking an instance of it), or ``main`` (``target`` is a ``main(argv, prog) -> int`` that parses its
    own arguments; where it reads them with :func:`sphri.args.read_settings`, ``schema`` is the
    ``{command word: (settings dataclass, takes overrides)}`` it hands that parser, read by TAB too)."""

    name: str
    summary: str
    kind: str
    target: str
    schema: str = ""

    def load(self, ref: str):
        module, _, attr = ref.partition(":")
        return getattr(importlib.import_module(module), attr)


VERBS: tuple[Verb, ...] = (
    Verb(
        "run",
        "run one job (the default verb: `sphri +debug=fast` is `sphri run +debug=fast`)",
        "hydra",
        "sphri.__main__:main",
    ),
    Verb(
        "sweep",
        "run a sweep, one job per point (`sphri sweep layout.res=2,4` is `sphri -m layout.res=2,4`)",
        "hydra",
        "sphri.__main__:main",
    ),
    Verb(
        "report",
        "the report of a finished sweep: figures, tables, the requirement sentence",
        "args",
        "sphri.report.command:command",
        "sphri.report.command:ReportArgs",
    ),
    Verb(
        "coverage",
        "where people touch the robot: coverage maps, the scenario study",
        "main",
        "sphri.coverage:main",
    ),
    Verb(
        "code",
        "a sheet to code the scenario study's episodes by hand: replays (HTML) and codes.csv to fill",
        "args",
        "sphri.sessions.coding_sheet:command",
        "sphri.sessions.coding_sheet:CodeArgs",
    ),
    Verb("list", "the components of each config group", "args", "sphri.cli:list_command", "sphri.cli:ListArgs"),
    Verb(
        "show",
        "every setting of the chosen components: value, default, meaning",
        "args",
        "sphri.cli:show_command",
        "sphri.cli:ShowArgs",
    ),
    Verb(
        "validate",
        "compose and check a config (every job of a sweep) without running it",
        "args",
        "sphri.cli:validate_command",
        "sphri.cli:ValidateArgs",
    ),
    Verb(
        "warmup",
        "compile sphri's numba kernels into numba's cache now, so the first job does not",
        "args",
        "sphri.cli:warmup_command",
        "sphri.cli:WarmupArgs",
    ),
    Verb(
        "cache",
        "see (info) and trim (clear) the stage cache, never the MLflow store",
        "args",
        "sphri.cache.command:command",
        "sphri.cache.command:CacheArgs",
    ),
    Verb(
        "store",
        "check or repair an MLflow store (mlflow.db)",
        "args",
        "sphri.tracking.store:command",
        "sphri.tracking.store:StoreArgs",
    ),
    Verb(
        "synthesize",
        "write a synthetic gesture dataset, the scenario sessions or example OpenXR logs to disk",
        "args",
        "sphri.recordings.synthesize:command",
        "sphri.recordings.synthesize:SynthesizeAnyArgs",
    ),
    Verb(
        "stats",
        "contact statistics of a gesture dataset against published references",
        "args",
        "sphri.data.stats:command",
        "sphri.data.stats:StatsArgs",
    ),
    Verb(
        "check-data",
        "check a recording folder (gesture trials or sessions) against the recording format",
        "args",
        "sphri.recordings.command:check_command",
        "sphri.recordings.command:CheckDataArgs",
    ),
    Verb(
        "import",
        "convert a hand-tracking log (OpenXR joints, OVR or generic capsules) into a gesture trial",
        "args",
        "sphri.recordings.command:import_command",
        "sphri.recordings.command:ImportArgs",
    ),
    Verb(
        "export",
        "train a model on the configured data and write a model file for live use",
        "main",
        "sphri.export.train:main",
        "sphri.export.train:COMMANDS",
    ),
    Verb(
        "skin",
        "record from or classify live a tactile skin on a serial port",
        "main",
        "sphri.hardware.skin:main",
        "sphri.hardware.skin:COMMANDS",
    ),
    Verb(
        "glove",
        "record from a sensing glove on a serial port",
        "main",
        "sphri.hardware.glove:main",
        "sphri.hardware.glove:COMMANDS",
    ),
    Verb(
        "simulate",
        "a simulated skin or glove on a local link, for live sessions without hardware",
        "main",
        "sphri.hardware.simulate:main",
        "sphri.hardware.simulate:COMMANDS",
    ),
    Verb(
        "robot",
        "check a robot description: its body parts and their areas, skipped links, a picture of the parts",
        "main",
        "sphri.sessions.robot_check:main",
        "sphri.sessions.robot_check:COMMANDS",
    ),
    Verb(
        "derive-reachy2",
        "regenerate the packaged Reachy 2 from Pollen Robotics' description",
        "args",
        "sphri.robots.reachy2_derivative:command",
        "sphri.robots.reachy2_derivative:DeriveArgs",
    ),
    Verb("help", "this list; `sphri help VERB` (or `sphri VERB --help`) a verb's arguments", "help", ""),
)

BY_NAME: dict[str, Verb] = {v.name: v for v in VERBS}


class UnknownVerb(ValueError):
    """A first word that is neither a verb nor an override (argparse's ``invalid choice``)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # the one error here: a first word that is no verb
        raise UnknownVerb(message)


def parser(prog: str = "sphri") -> argparse.ArgumentParser:
    """``sphri``'s parser: one subparser per verb, its help line the verb's summary. A subparser declares no
    argument: :func:`main` takes the words after the verb unchanged from ``parse_known_args`` and the verb's
    own parser reads them (:func:`call`; ``argparse.REMAINDER`` would refuse a first word like ``--help``)."""
    top = _Parser(
        prog=prog,
        usage=f"{prog} [VERB] [arguments]",
        description="sphri: design robot tactile skins from interaction data.",
        epilog=f"No verb is `run` (Hydra overrides: {prog} +debug=fast). {prog} VERB --help: a verb's arguments "
        f"({prog} run --help: the config groups).",
        add_help=False,
        formatter_class=lambda prog: argparse.HelpFormatter(prog, width=100),
    )
    # argparse aligns the verbs' lines by the heading's width (the metavar's): as wide as the longest verb + 2
    verbs = top.add_subparsers(dest="verb", title="verbs", metavar="VERB [arguments]")
    for v in VERBS:
        verbs.add_parser(v.name, help=v.summary, add_help=False)
    return top


def is_override(word: str) -> bool:
    """A word Hydra reads (``key=value``, ``+group=x``, ``~key``, a flag): the ``run`` verb's."""
    return "=" in word or word.startswith(("-", "+", "~"))


def call(verb: Verb, argv: Sequence[str]) -> int:
    """Run ``verb`` with its arguments (``sphri VERB`` prefixes its one-line errors); its exit code."""
    argv, prog = list(argv), f"sphri {verb.name}"
    if verb.kind == "help":
        if argv and argv[0] in BY_NAME and argv[0] != "help":
            return call(BY_NAME[argv[0]], ["--help"])
        _print(parser().format_help())
        return 0
    if verb.kind == "hydra":
        if verb.name == "sweep" and not any(a in ("-m", "--multirun") for a in argv):
            argv = ["-m", *argv]
        sys.argv = [sys.argv[0] if sys.argv else "sphri", *argv]
        verb.load(verb.target)()  # sphri.__main__.main: exits non-zero itself on a failure (one line)
        return 0
    if verb.kind == "main":  # main(argv, prog): its own subcommands, or settings and config overrides
        return int(verb.load(verb.target)(argv, prog=prog) or 0)
    from sphri.args import first_paragraph, run
    from sphri.errors import clean_errors

    schema = verb.load(verb.schema)
    body = verb.load(verb.target)
    summary = first_paragraph(body.__doc__) or verb.summary

    @clean_errors(prog)
    def main(args: list[str]) -> int:
        return run(schema, args, body, prog, summary)

    return main(argv)


def _print(text: str) -> None:
    try:
        print(text)
    except BrokenPipeError:  # `sphri help | head`: the reader went away
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def main(argv: Sequence[str] | None = None) -> int:
    """``sphri [VERB] [arguments]``: the console script's dispatcher (see the module docstring)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] in (["-h"], ["--help"]):
        argv[0] = "help"
    if not argv or is_override(argv[0]):
        return call(BY_NAME["run"], argv)
    try:
        verb, rest = parser().parse_known_args(argv)
    except UnknownVerb:  # one line with the close matches, not argparse's usage block
        close = difflib.get_close_matches(argv[0], BY_NAME, n=3, cutoff=0.5)
        hint = f" (did you mean {' or '.join(close)}?)" if close else ""
        print(f"sphri: unknown verb {argv[0]!r}{hint}; verbs: {', '.join(BY_NAME)}", file=sys.stderr)
        return 2
    return call(BY_NAME[verb.verb], rest)
