"""``sphri <verb>``: one command for everything sphri does.

::

    sphri +debug=fast                    # no verb: run one job (Hydra overrides, exactly as before)
    sphri sweep layout.res=2,4          # = sphri -m layout.res=2,4
    sphri report outputs/sweeps/resolution_rf
    sphri list robot
    sphri help                           # every verb with one line; `sphri VERB --help` its arguments

The first word picks the verb of :data:`VERBS`; the words after it go unchanged to the verb's own parser.
``run`` and ``sweep`` hand them to Hydra; every other verb reads ``key=value`` arguments through one parser
(:mod:`sphri.args`), typed by a dataclass beside the verb's code, which also takes the ``--key value``
spellings. ``sphri VERB`` is a verb's one spelling (``python -m sphri VERB`` runs the same where the script
is not on the PATH; no module of sphri is a command of its own). A first word that is not a verb but looks
like an override (``key=value``, ``+group=x``, ``~key``, ``-m``, ``--cfg``) is the ``run`` verb; any other
word is an unknown verb: one line naming the close matches, exit 2.

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


#: name, kind, target, schema (a name in the target's module; "" none): see :class:`Verb`.
_ROWS = (
    ("run", "hydra", "sphri.__main__:main", ""),
    ("sweep", "hydra", "sphri.__main__:main", ""),
    ("report", "args", "sphri.report.command:command", "ReportArgs"),
    ("coverage", "main", "sphri.coverage:main", ""),
    ("code", "args", "sphri.sessions.coding_sheet:command", "CodeArgs"),
    ("list", "args", "sphri.cli:list_command", "ListArgs"),
    ("show", "args", "sphri.cli:show_command", "ShowArgs"),
    ("validate", "args", "sphri.cli:validate_command", "ValidateArgs"),
    ("warmup", "args", "sphri.cli:warmup_command", "WarmupArgs"),
    ("cache", "args", "sphri.cache.command:command", "CacheArgs"),
    ("store", "args", "sphri.tracking.store:command", "StoreArgs"),
    ("synthesize", "args", "sphri.recordings.synthesize:command", "SynthesizeAnyArgs"),
    ("stats", "args", "sphri.data.stats:command", "StatsArgs"),
    ("check-data", "args", "sphri.recordings.command:check_command", "CheckDataArgs"),
    ("import", "args", "sphri.recordings.command:import_command", "ImportArgs"),
    ("export", "main", "sphri.export.train:main", "COMMANDS"),
    ("skin", "main", "sphri.hardware.skin:main", "COMMANDS"),
    ("glove", "main", "sphri.hardware.glove:main", "COMMANDS"),
    ("simulate", "main", "sphri.hardware.simulate:main", "COMMANDS"),
    ("robot", "main", "sphri.sessions.robot_check:main", "COMMANDS"),
    ("derive-reachy2", "args", "sphri.robots.reachy2_derivative:command", "DeriveArgs"),
    ("help", "help", "", ""),
)
#: Each verb's line in ``sphri help``.
_SUMMARIES = {
    "run": "run one job (the default verb: `sphri +debug=fast` is `sphri run +debug=fast`)",
    "sweep": "run a sweep, one job per point (`sphri sweep layout.res=2,4` is `sphri -m layout.res=2,4`)",
    "report": "the report of a finished sweep: figures, tables, the requirement sentence",
    "coverage": "where people touch the robot: coverage maps, the scenario study",
    "code": "a sheet to code the scenario study's episodes by hand: replays (HTML) and codes.csv to fill",
    "list": "the components of each config group",
    "show": "every setting of the chosen components: value, default, meaning",
    "validate": "compose and check a config (every job of a sweep) without running it",
    "warmup": "compile sphri's numba kernels into numba's cache now, so the first job does not wait for them",
    "cache": "see (info) and trim (clear) the stage cache, never the MLflow store",
    "store": "check or repair an MLflow store (mlflow.db)",
    "synthesize": "write a synthetic gesture dataset, the scenario sessions or example OpenXR logs to disk",
    "stats": "contact statistics of a gesture dataset against published references",
    "check-data": "check a recording folder (gesture trials or sessions) against the recording format",
    "import": "convert a hand-tracking log (OpenXR joints, OVR or generic capsules) into a gesture trial",
    "export": "train a model on the configured data and write a model file for live use",
    "skin": "record from or classify live a tactile skin on a serial port",
    "glove": "replay a trial's contacts on the haptic glove (six actuators) over a serial port",
    "simulate": "a simulated skin or glove on a local link, for live sessions without hardware",
    "robot": "check a robot description: its body parts and their areas, skipped links, a picture of the parts",
    "derive-reachy2": "regenerate the packaged Reachy 2 from Pollen Robotics' description",
    "help": "this list; `sphri help VERB` (or `sphri VERB --help`) a verb's arguments",
}
VERBS: tuple[Verb, ...] = tuple(
    Verb(name, _SUMMARIES[name], kind, target, schema and f"{target.partition(':')[0]}:{schema}")
    for name, kind, target, schema in _ROWS
)
BY_NAME: dict[str, Verb] = {v.name: v for v in VERBS}


def parser(prog: str = "sphri") -> argparse.ArgumentParser:
    """``sphri``'s help: one subparser per verb, its help line the verb's summary."""
    top = argparse.ArgumentParser(
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
        if argv and argv[0] not in BY_NAME:
            return unknown_verb(argv[0])
        if argv and argv[0] != "help":
            return call(BY_NAME[argv[0]], ["--help"])
        print_help(parser().format_help())
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

    schema, body = verb.load(verb.schema), verb.load(verb.target)
    summary = first_paragraph(body.__doc__) or verb.summary
    return clean_errors(prog)(lambda args: run(schema, args, body, prog, summary))(argv)


def print_help(text: str) -> None:
    """Print ``text``; ``sphri help | head``: the reader went away, the rest is dropped quietly."""
    try:
        print(text)
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def main(argv: Sequence[str] | None = None) -> int:
    """``sphri [VERB] [arguments]``: the console script's dispatcher (see the module docstring)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] in (["-h"], ["--help"]):
        argv[0] = "help"
    if not argv or is_override(argv[0]):
        return call(BY_NAME["run"], argv)
    if argv[0] not in BY_NAME:
        return unknown_verb(argv[0])
    return call(BY_NAME[argv[0]], argv[1:])


def unknown_verb(word: str) -> int:
    """One line naming ``word`` and the close verbs (``sphri WORD``, ``sphri help WORD``); exit code 2."""
    close = difflib.get_close_matches(word, BY_NAME, n=3, cutoff=0.5)
    hint = f" (did you mean {' or '.join(close)}?)" if close else ""
    print(f"sphri: unknown verb {word!r}{hint}; verbs: {', '.join(BY_NAME)}", file=sys.stderr)
    return 2
