"""Fast shell completion: Hydra's answers, kept per command-line context.

Hydra answers a TAB (``sphri -sc query=bash``, with the line in ``COMP_LINE``)
by importing sphri, registering every schema and composing the config, for
every TAB (how long: docs/BENCHMARKS.md, ``startup.json``). The answer depends only on the words before the
cursor, the part of the current word up to its last ``.``, ``=`` or ``/`` (the
*stem*; bash's ``compgen`` filters the rest), sphri's version and its config
and schema files. This module keeps Hydra's answer for each such context in
``$XDG_CACHE_HOME/sphri/completion/`` (else ``~/.cache/sphri/completion/``)
and answers later TABs from there, importing nothing but the standard
library; the first TAB in a new context asks Hydra. Editing any file under
sphri's ``conf/`` or ``sphri/`` package starts afresh; file paths (``key=./``)
always go to Hydra. Hand-written (no library offers a completion cache for
Hydra apps) for measured speed: ``bench/bench_startup.py`` times both.

The first word completes to a verb of ``sphri <verb>`` (:data:`sphri.command.VERBS`, read without
importing anything heavy) as well as to Hydra's overrides (no verb is ``run``); after ``run`` or
``sweep`` Hydra answers as before, after a ``key=value`` verb its keys (and their choices) from its
argument dataclass, plus Hydra's overrides where the verb takes them (``validate``, ``show``,
``stats``, ...). The hardware verbs and ``export`` (skin, glove, simulate, export) offer their
command word, then the keys of its settings schema, from the mapping their ``main`` hands
:func:`sphri.args.read_settings` (:attr:`sphri.command.Verb.schema`). Every answer but a
path's is kept the same way.

This module is the console script's entry (``sphri``): it must stay light. Anything but a TAB goes
to the verb dispatcher :func:`sphri.command.main`.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sphri.args import Key
    from sphri.command import Verb

_PACKAGE = Path(__file__).resolve().parent
_PATH_START = (".", "/", "\\", "~")


def cache_dir() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "sphri" / "completion"


def _conf_dirs() -> list[Path]:
    return [d for d in (_PACKAGE.parent / "conf", _PACKAGE / "conf") if (d / "config.yaml").is_file()]


def fingerprint() -> str:
    """sphri's version and the size and mtime of every config and source file (what the answer depends on)."""
    from sphri import __version__

    h = hashlib.sha256(__version__.encode())
    for root in [*_conf_dirs(), _PACKAGE]:
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames[:] = sorted(d for d in dirnames if d != "__pycache__")
            for name in sorted(filenames):
                if name.endswith((".yaml", ".py")):
                    st = os.stat(os.path.join(dirpath, name))
                    h.update(f"{dirpath}/{name}:{st.st_size}:{st.st_mtime_ns};".encode())
    return h.hexdigest()


def split_line(line: str) -> tuple[str, str]:
    """``(context, stem)`` of a completion line: the words before the current one, and the current
    word up to its last ``.``, ``=`` or ``/`` (with a leading ``+``/``~``)."""
    if not line or line[-1].isspace():
        return line, ""
    head, _, word = line.rpartition(" ")
    prefix = word[0] if word[:1] in ("+", "~") else ""
    body = word[len(prefix) :]
    cut = max(body.rfind("."), body.rfind("="), body.rfind("/"))
    return head + " ", prefix + body[: cut + 1]


def is_path_word(line: str) -> bool:
    """The current word is ``key=<a path>``: Hydra completes files there (never cached)."""
    word = "" if not line or line[-1].isspace() else line.rpartition(" ")[2]
    value = word.rpartition("=")[2] if "=" in word else ""
    return value.startswith(_PATH_START)


def _hydra_answer(line: str) -> str:
    """Hydra's own completion output for ``line`` (sphri's full entry point, stdout captured)."""
    from sphri.__main__ import main

    env_line = os.environ.get("COMP_LINE")
    os.environ["COMP_LINE"] = line
    argv = sys.argv
    sys.argv = [argv[0], "-sc", "query=bash"]
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            main()
    finally:
        sys.argv = argv
        if env_line is None:
            os.environ.pop("COMP_LINE", None)
        else:
            os.environ["COMP_LINE"] = env_line
    return out.getvalue()


def _verb_line(line: str) -> tuple[Verb | None, str]:
    """(the verb of ``line`` when its first word is complete and names one, else None; for ``run`` and
    ``sweep``, the line as Hydra would see it: the verb left out, ``sweep`` as ``-m``)."""
    from sphri.command import BY_NAME

    words = line.split(" ")
    if len(words) < 3 or words[1] not in BY_NAME:  # the first word is still being typed, or is an override
        return None, line
    verb = BY_NAME[words[1]]
    return verb, " ".join([words[0], *(["-m"] if verb.name == "sweep" else []), *words[2:]])


def _takes(verb: Verb, context: list[str]) -> tuple[list[Key], tuple[str, ...], bool]:
    """What ``verb`` takes after the words ``context`` (those between the verb and the current word): its
    ``key=value`` keys, what a bare word may be there, and whether it takes Hydra's overrides. An ``args``
    verb's keys come from its argument dataclass; a ``main`` verb's (skin, glove, simulate, export) from
    the settings of its command word, in the mapping its ``main`` hands
    :func:`sphri.args.read_settings` (:attr:`Verb.schema`): one source for the parser, ``--help``
    and TAB."""
    from sphri.args import keys
    from sphri.command import is_override

    if verb.kind == "args":
        ks = keys(verb.load(verb.schema))
        overrides = any(k.rest for k in ks)
    else:
        commands = verb.load(verb.schema)
        word = context[0] if context and "" not in commands else ""
        if word not in commands:  # the command word comes first (nothing fits after a wrong one)
            return [], () if context else tuple(commands), False
        cls, overrides = commands[word]
        ks, context = keys(cls), context[1:] if word else context
    bare = [w for w in context if not is_override(w)]  # the positional arguments so far
    slots = [k for k in ks if k.positional]
    if len(bare) < len(slots):
        slot: Key | None = slots[len(bare)]
    elif slots and slots[-1].is_list:  # a list takes every further word
        slot = slots[-1]
    else:
        slot = None
    return [k for k in ks if not k.rest], slot.choices() if slot else (), overrides


def _verb_answer(verb: Verb, line: str) -> str:
    """The words a ``key=value`` verb offers after ``line``: the choices of the bare word being typed (a
    positional argument, a command word), its keys (``key=`` and ``key=choice``) and, where it takes
    overrides, Hydra's answer for the other words."""
    from sphri.command import is_override

    head, _, current = line.rpartition(" ")
    prog, _, after = head.partition(" ")  # "sphri", "VERB word ..."
    context = [w for w in after.split(" ")[1:] if w]
    ks, bare, overrides = _takes(verb, context)
    words = [*bare]
    for k in ks:
        words.append(f"{k.name}=")
        words += [f"{k.name}={c}" for c in k.choices()]
    text = "\n".join(words) + "\n"
    if overrides:  # Hydra sees the words that are not the verb's: no key of it, no command or positional word
        own = tuple(f"{k.name}=" for k in ks)
        rest = [w for w in context if is_override(w) and not w.startswith(own)]
        text += _hydra_answer(" ".join([prog, *rest, "" if current.startswith(own) else current]))
    return text


def _compute(line: str) -> str:
    """The completion output for ``line``: verbs and Hydra's overrides for the first word, then what the
    verb takes."""
    from sphri.command import VERBS

    verb, hydra_line = _verb_line(line)
    if verb is None:
        words = line.split(" ")
        if len(words) == 2 and not any(c in words[1] for c in "=./") and not words[1].startswith(("+", "~", "-")):
            return "\n".join(v.name for v in VERBS) + "\n" + _hydra_answer(line)  # a verb, or an override of run
        return _hydra_answer(line)
    if verb.kind == "hydra":
        return _hydra_answer(hydra_line)
    if verb.kind == "help":
        return "\n".join(v.name for v in VERBS) + "\n"
    if verb.kind == "args" or verb.schema:
        return _verb_answer(verb, line)
    return ""  # a verb that parses its own arguments: the shell completes file names


def answer(line: str) -> str:
    """The completion output for ``COMP_LINE`` = ``line`` (from the cache when this context was asked before)."""
    if is_path_word(line):
        return _compute(line)
    context, stem = split_line(line)
    key = hashlib.sha256(json.dumps([fingerprint(), context, stem]).encode()).hexdigest()[:32]
    path = cache_dir() / f"{key}.txt"
    try:
        return path.read_text()
    except OSError:
        pass
    text = _compute(context + stem)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        tmp.replace(path)  # a TAB in another shell never reads half an answer
    except OSError:  # a read-only home: answer without keeping it
        pass
    return text


def _is_query(args: list[str]) -> bool:
    for i, a in enumerate(args):
        if re.fullmatch(r"(-sc|--shell-completion)=?query=bash", a):
            return True
        if a in ("-sc", "--shell-completion") and i + 1 < len(args) and args[i + 1] == "query=bash":
            return True
    return False


def main() -> int:
    """The ``sphri`` console script: a bash completion query is answered here, anything else by the verb
    dispatcher :func:`sphri.command.main` (no verb: :func:`sphri.__main__.main`, a Hydra job)."""
    if _is_query(sys.argv[1:]) and "COMP_LINE" in os.environ:
        sys.stdout.write(answer(os.environ["COMP_LINE"]))
        return 0
    from sphri.command import main as dispatch

    return dispatch()
