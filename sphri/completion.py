"""Fast shell completion: Hydra's answers, kept per command-line context.

Hydra answers a TAB (``sphri -sc query=bash``, with the line in ``COMP_LINE``) by importing sphri, registering
every schema and composing the config, for every TAB (how long: docs/BENCHMARKS.md, ``startup.json``). The
answer depends only on the words before the cursor, the current word up to its last ``.``, ``=`` or ``/`` (the
*stem*; bash's ``compgen`` filters the rest), sphri's version and its config and source files. This module
keeps each context's answer in ``$XDG_CACHE_HOME/sphri/completion/`` (else ``~/.cache/sphri/completion/``) and
answers later TABs from there, importing nothing but the standard library; editing a file under ``conf/`` or
``sphri/`` starts afresh, and file paths (``key=./``) always go to Hydra, never kept. Hand-written (no library
offers a completion cache for Hydra apps) for measured speed: ``bench/bench_startup.py`` times both.

The first word completes to a verb (:data:`sphri.command.VERBS`) or to Hydra's overrides (no verb is
``run``); after ``run`` or ``sweep`` Hydra answers; after another verb, its keys and their choices, read from
its argument dataclass or, for the verbs whose ``main`` hands :func:`sphri.args.read_settings` a
``{command word: settings}`` mapping (:attr:`sphri.command.Verb.schema`), its command word then that
command's keys; plus Hydra's overrides where the verb takes them (``validate``, ``show``, ``stats``, ...).

This module is the console script's entry (``sphri``): it must stay light. Anything but a TAB goes to the
verb dispatcher :func:`sphri.command.main`.
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
_QUERY = ("-sc query=bash", "--shell-completion query=bash")


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
    from unittest import mock

    from sphri.__main__ import main

    out = io.StringIO()
    with (
        mock.patch.dict(os.environ, COMP_LINE=line),
        mock.patch.object(sys, "argv", [sys.argv[0], "-sc", "query=bash"]),
        contextlib.redirect_stdout(out),
    ):
        main()
    return out.getvalue()


def _verb_answer(verb: Verb, line: str) -> str:
    """The words a ``key=value`` verb offers after ``line``: the choices of the bare word being typed (a
    positional argument, a command word), its keys (``key=`` and ``key=choice``, as the parser and ``--help``
    read them: :attr:`Verb.schema`) and, where it takes overrides, Hydra's answer for the other words."""
    from sphri.args import keys
    from sphri.command import is_override

    head, _, current = line.rpartition(" ")
    prog, _, after = head.partition(" ")  # "sphri", "VERB word ..."
    context = [w for w in after.split(" ")[1:] if w]  # the words between the verb and the current one
    if verb.kind == "args":
        ks = keys(verb.load(verb.schema))
        overrides = any(k.rest for k in ks)
    else:  # the command word comes first, then the keys of its settings
        commands = verb.load(verb.schema)
        word = context[0] if context and "" not in commands else ""
        if word not in commands:  # nothing fits after a wrong one
            return "\n".join([] if context else commands) + "\n"
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
    ks = [k for k in ks if not k.rest]
    words = [*(slot.choices() if slot else ())]
    for k in ks:
        words += [f"{k.name}=", *(f"{k.name}={c}" for c in k.choices())]
    text = "\n".join(words) + "\n"
    if overrides:  # Hydra sees the words that are not the verb's: no key of it, no command or positional word
        own = tuple(f"{k.name}=" for k in ks)
        rest = [w for w in context if is_override(w) and not w.startswith(own)]
        text += _hydra_answer(" ".join([prog, *rest, "" if current.startswith(own) else current]))
    return text


def _compute(line: str) -> str:
    """The completion output for ``line``: verbs and Hydra's overrides for the first word, then what the
    verb takes (``run`` and ``sweep``: Hydra's answer for the line without the verb, ``sweep`` as ``-m``)."""
    from sphri.command import BY_NAME, VERBS

    words = line.split(" ")
    verb = BY_NAME.get(words[1]) if len(words) > 2 else None  # None: the first word is being typed, or no verb
    if verb is None:
        if len(words) == 2 and not any(c in words[1] for c in "=./") and not words[1].startswith(("+", "~", "-")):
            return "\n".join(v.name for v in VERBS) + "\n" + _hydra_answer(line)  # a verb, or an override of run
        return _hydra_answer(line)
    if verb.kind == "hydra":
        return _hydra_answer(" ".join([words[0], *(["-m"] if verb.name == "sweep" else []), *words[2:]]))
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
    with contextlib.suppress(OSError):
        return path.read_text()
    text = _compute(context + stem)
    with contextlib.suppress(OSError):  # a read-only home: answer without keeping it
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        tmp.replace(path)  # a TAB in another shell never reads half an answer
    return text


def _is_query(args: list[str]) -> bool:
    pairs = zip(args, [*args[1:], ""])
    return any(re.fullmatch(r"(-sc|--shell-completion)=?query=bash", a) or f"{a} {b}" in _QUERY for a, b in pairs)


def main() -> int:
    """The ``sphri`` console script: a bash completion query is answered here, anything else by the verb
    dispatcher :func:`sphri.command.main` (no verb: :func:`sphri.__main__.main`, a Hydra job)."""
    if _is_query(sys.argv[1:]) and "COMP_LINE" in os.environ:
        sys.stdout.write(answer(os.environ["COMP_LINE"]))
        return 0
    from sphri.command import main as dispatch

    return dispatch()
