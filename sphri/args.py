"""One ``key=value`` parser for sphri's commands (every verb but ``run``/``sweep``, which Hydra parses).

A command declares its arguments once, as a dataclass whose fields are made with :func:`arg` (or a
:class:`sphri.config.Schema`: field docstrings are the help, ``"???"`` a required key, a
:func:`sphri.config.setting` range the check). :func:`parse` builds an :class:`argparse.ArgumentParser`
from the fields, which tokenises, matches ``--key value``, ``--key=value``, ``--some-key`` and the extra
``flags`` (``--no-log``), fills the ``positional`` fields with the bare words and lays out ``--help``;
``key=value`` reaches it as ``--key=value``. What is not a key goes to the ``rest`` field (a command's
Hydra overrides), or beside the instance (:func:`parse_known`), else it is an error.

Values are converted here, to the field's type: ``str``, ``int``, ``float``, ``bool`` (true/false,
yes/no, on/off, 1/0), ``Path``, a ``Literal``'s choices, ``X | None`` (``none``), ``list[X]``
(comma-separated, repeated keys, or words); then the field's ``check``. Every problem is one line naming
the key and the value (:class:`ArgsError`; :func:`run` prints it and returns 2). Standard library only:
the TAB completion reads the schemas.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import functools
import re
import sys
import textwrap
import types
import typing
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, TypeVar

T = TypeVar("T")

_BOOL = {**dict.fromkeys(("true", "yes", "on", "1"), True), **dict.fromkeys(("false", "no", "off", "0"), False)}
_CONVERT: dict[Any, Callable[[str], Any]] = {bool: lambda w: _BOOL[w.lower()], int: int, float: float, Path: Path}
_KEY = re.compile(r"[A-Za-z_][\w.\-]*")
HELP_FLAGS = ("-h", "--help")
_META = ("help", "positional", "rest", "flags", "check", "metavar", "choices")  # what arg() records


class ArgsError(ValueError):
    """A bad command-line argument: one line naming the key and what it allows."""


class HelpRequested(Exception):
    """``-h``/``--help`` was given: the message is the help text."""


def arg(
    default: Any = dataclasses.MISSING,
    *,
    help: str = "",
    positional: bool = False,
    rest: bool = False,
    flags: dict[str, str] | None = None,
    check: Callable[[Any], str | None] | None = None,
    metavar: str = "",
    choices: Sequence[str] = (),
) -> Any:
    """A field of a command's argument dataclass.

    ``flags`` maps extra spellings to a fixed value (``{"--no-log": "false"}``). ``check(value)`` returns
    what a valid value must be (``"must be >= 0"``) or None. ``choices`` are the values a text key (or each
    item of a list key) may take: checked (an unknown one is named, with the close matches) and offered by the
    TAB completion. ``rest`` marks a ``list[str]`` field that collects every argument that is not one of the
    command's keys (for Hydra overrides)."""
    meta = dict(zip(_META, (help, positional, rest, dict(flags or {}), check, metavar, tuple(choices))))
    if isinstance(default, (list, tuple)):
        items = list(default)
        return dataclasses.field(default_factory=lambda: list(items), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _base(t: Any) -> Any:
    """``X`` of ``X | None``."""
    if typing.get_origin(t) in (typing.Union, types.UnionType) and type(None) in typing.get_args(t):
        (inner,) = [a for a in typing.get_args(t) if a is not type(None)]
        return inner
    return t


@dataclasses.dataclass(frozen=True)
class Key:
    """One argument of a command, read from its dataclass field."""

    name: str
    type: Any
    default: Any
    required: bool
    help: str = ""
    positional: bool = False
    rest: bool = False
    flags: dict[str, str] = dataclasses.field(default_factory=dict)
    check: Callable[[Any], str | None] | None = None
    metavar: str = ""
    allowed: tuple[str, ...] = ()  # arg(choices=...), or a Schema setting's choices

    @property
    def is_list(self) -> bool:
        return typing.get_origin(_base(self.type)) is list

    @property
    def is_bool(self) -> bool:
        return _base(self.type) is bool

    @property
    def item(self) -> Any:
        """The type of the value (of each item of a list)."""
        return (typing.get_args(_base(self.type)) or (str,))[0] if self.is_list else self.type

    def choices(self) -> tuple[str, ...]:
        """The allowed values of a ``Literal`` (or bool) key, or its declared choices, else ()."""
        t = _base(self.item)
        if self.allowed:
            return self.allowed
        if typing.get_origin(t) is Literal:
            return tuple(str(c) for c in typing.get_args(t))
        return ("true", "false") if t is bool else ()

    def spellings(self) -> list[str]:
        """``--key`` and ``--some-key``."""
        return list(dict.fromkeys([f"--{self.name}", "--" + self.name.replace("_", "-")]))


def keys(cls: type) -> list[Key]:
    """The arguments of the command whose dataclass is ``cls``."""
    hints = typing.get_type_hints(cls)
    fields = [f for f in dataclasses.fields(cls) if not f.name.startswith("_")]  # a Schema's _target_
    docs: dict[str, str] = {}
    ranges: dict[str, Any] = {}
    if any("help" not in f.metadata for f in fields):  # fields not made by arg(): a Schema's
        from sphri.config import RANGE_META, field_docs

        docs = field_docs(cls)
        ranges = {f.name: f.metadata[RANGE_META] for f in fields if RANGE_META in f.metadata}
    out = []
    for f in fields:
        rng = ranges.get(f.name)
        m = {"help": docs.get(f.name, ""), **{k: v for k, v in f.metadata.items() if k in _META}}
        allowed = tuple(m.pop("choices", ())) or tuple(str(c) for c in getattr(rng, "choices", None) or ())
        check = (
            m.pop("check", None) or _choice_check(f.metadata, f.name) or (rng and functools.partial(rng.check, f.name))
        )
        default = f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
        required = default is dataclasses.MISSING or isinstance(default, str) and default == "???"  # a Schema's
        default = None if required else default
        out.append(Key(f.name, hints[f.name], default, required, check=check, allowed=allowed, **m))
    return out


def _choice_check(meta: Mapping[str, Any], name: str) -> Callable[[Any], str | None] | None:
    """``arg(choices=...)`` as a key's ``check``: an unknown value (or list item) is named (as the key's metavar,
    else its name), with its close matches."""
    choices: tuple[str, ...] = meta.get("choices", ())
    if not choices:
        return None
    name = (meta.get("metavar") or name).lower()

    def check(value: Any) -> None:
        for item in value if isinstance(value, (list, tuple)) else [value]:
            if str(item) not in choices:
                close = difflib.get_close_matches(str(item), choices, n=3)
                hint = f" (did you mean {' or '.join(close)}?)" if close else ""
                raise ValueError(f"unknown {name} {item!r}{hint}; {name} is one of: {', '.join(choices)}")

    return check


def _type_words(t: Any) -> str:
    """What a value of type ``t`` must be, in words."""
    t = _base(t)
    if typing.get_origin(t) is Literal:
        return "one of " + ", ".join(str(c) for c in typing.get_args(t))
    return {int: "an integer", float: "a number", bool: "true or false", Path: "a path", str: "text"}.get(t, str(t))


def _scalar(t: Any, text: str, shown: str) -> Any:
    """``text`` as a value of type ``t`` (``shown`` is how the argument is quoted in an error)."""
    if _base(t) is not t:  # X | None
        t = _base(t)
        if t is not str and text.lower() in ("none", "null", ""):
            return None
    bad = f"{shown} is invalid: must be {_type_words(t)}"
    if typing.get_origin(t) is Literal:
        for choice in typing.get_args(t):
            if text == str(choice):
                return choice
        close = difflib.get_close_matches(text, [str(c) for c in typing.get_args(t)], n=1)
        raise ArgsError(bad + (f" (did you mean {close[0]}?)" if close else ""))
    try:
        value = _CONVERT.get(t, str)(text)
    except (KeyError, ValueError):
        raise ArgsError(bad) from None
    if value != value:  # nan passes every range check
        raise ArgsError(bad)
    return value


def _convert(key: Key, words: list[str]) -> Any:
    """The value of ``key`` from its words (the last one unless the key is a list), checked."""
    shown = f"{key.name}={words[-1] if words else ''}"
    if key.is_list:
        value: Any = [_scalar(key.item, w, f"{key.name}={w}") for w in words]
    else:
        value = _scalar(key.type, words[-1], shown)
    if key.check is not None:
        try:
            problem = key.check(value)
        except ValueError as exc:  # a validator's own message (it names the value)
            raise ArgsError(" ".join(str(exc).split())) from None
        if problem:
            raise ArgsError(f"{shown} is invalid: {problem}")
    return value


def _metavar(key: Key) -> str:
    """How a key's value is shown in the usage and help: its metavar, choices, or type."""
    word = "|".join(key.choices()) or {int: "INT", float: "NUMBER", bool: "BOOL", Path: "PATH"}.get(
        _base(key.item), "TEXT"
    )
    return key.metavar or word + (",..." if key.is_list else "")


def _head(key: Key) -> str:
    """How a key is written in the usage and help: ``n=INT``, ``SOURCE``, ``overrides``."""
    if key.rest or key.positional:
        return key.metavar or ("overrides" if key.rest else key.name.upper())
    return f"{key.name}={_metavar(key)}"


def _usage_word(key: Key) -> str:
    word = f"{_head(key)} ..." if key.positional and key.is_list else _head(key)
    return word if key.required or not key.positional else f"[{word}]"


def usage(cls: type, prog: str, overrides: bool = False) -> str:
    """``PROG POSITIONAL [key=value ...]`` of a command (``overrides``: it takes Hydra's too)."""
    ks = keys(cls)
    words = [_usage_word(k) for k in ks if k.positional]
    words += [_usage_word(k) for k in ks if k.required and not k.positional and not k.rest]
    words += ["[key=value ...]"] if any(not (k.positional or k.rest or k.required) for k in ks) else []
    words += [f"[{_head(k)} ...]" for k in ks if k.rest] + (["[overrides ...]"] if overrides else [])
    return " ".join([prog, *words])


def _help_line(k: Key) -> str:
    """A key's meaning in ``--help``: its help, its default and its fixed spellings."""
    if k.required:
        tail = " (required)"
    elif k.rest or k.default in (None, "", [], ()):
        tail = ""
    else:
        d = ",".join(map(str, k.default)) if isinstance(k.default, (list, tuple)) else k.default
        tail = f" (default {str(d).lower() if isinstance(d, bool) else d})"
    alias = f"; {', '.join(k.flags)} for {k.name}={'/'.join(k.flags.values())}" if k.flags else ""
    return (k.help + tail + alias).strip()


class _Formatter(argparse.HelpFormatter):
    """sphri's ``--help`` layout: each argument as it is written (``n=INT``), its meaning from column 30."""

    def __init__(self, prog: str) -> None:
        super().__init__(prog, width=100, max_help_position=30)
        self._action_max_length = 28  # the meaning starts at column 30 however short the keys

    def _format_action_invocation(self, action: argparse.Action) -> str:
        return str(action.metavar)

    def _split_lines(self, text: str, width: int) -> list[str]:
        return textwrap.wrap(text, width, break_on_hyphens=False)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> typing.NoReturn:
        raise ArgsError(message)


def _parser(
    ks: list[Key], cls: type, prog: str, summary: str, overrides: bool, named: Collection[str] = ()
) -> argparse.ArgumentParser:
    """The argparse parser of the keys ``ks`` of ``cls``: ``--key`` (``dest`` the key) for every key, a
    positional (``dest`` ``_key``) for each positional one (not a one-word key ``named`` by ``--key``/``key=``);
    ``rest`` keys and ``overrides`` are lines of ``--help`` only."""
    parser = _Parser(
        prog=prog,
        usage=usage(cls, prog, overrides),
        description=" ".join(summary.split()) or None,
        formatter_class=_Formatter,
        add_help=False,
        allow_abbrev=False,
        exit_on_error=False,
        argument_default=argparse.SUPPRESS,
    )
    group = parser.add_argument_group("arguments (key=value, or --key value)")
    for k in ks:
        kw: dict[str, Any] = {"metavar": _head(k), "help": _help_line(k).replace("%", "%%")}
        if k.rest:
            group._group_actions.append(argparse.Action([], k.name, **kw))
            continue
        if k.positional and (k.is_list or k.name not in named):
            group.add_argument(f"_{k.name}", nargs="*" if k.is_list else "?", **kw)
            kw["help"] = argparse.SUPPRESS
        how: dict[str, Any] = (
            {"action": "append"} if k.is_list else {"nargs": "?", "const": "true"} if k.is_bool else {}
        )
        group.add_argument(*k.spellings(), dest=k.name, **how, **kw)
        for flag, value in k.flags.items():
            const = "append_const" if k.is_list else "store_const"
            group.add_argument(flag, dest=k.name, action=const, const=value, help=argparse.SUPPRESS)
    if overrides:
        line = "any other key=value: a config override (+debug=fast, robot=nao_child)"
        group._group_actions.append(argparse.Action([], "overrides", metavar="overrides", help=line))
    return parser


def help_text(cls: type, prog: str, summary: str = "", overrides: bool = False) -> str:
    """``--help`` of a command: usage, summary, then one line per key (type, default, meaning);
    ``overrides``: it passes the other ``key=value`` arguments to the config (a closing line says so)."""
    return _parser(keys(cls), cls, prog, summary, overrides).format_help().rstrip()


def parse(cls: type[T], argv: Sequence[str], prog: str = "sphri", summary: str = "") -> T:
    """The arguments ``argv`` as an instance of ``cls`` (raises :class:`ArgsError`, or
    :class:`HelpRequested` for ``-h``/``--help``)."""
    return _parse(cls, argv, prog, summary, known=False)[0]


def parse_known(cls: type[T], argv: Sequence[str], prog: str = "sphri", summary: str = "") -> tuple[T, list[str]]:
    """Like :func:`parse`, for a command that composes a config: the arguments that are not keys of
    ``cls`` (``+debug=fast``, ``data.seed=3``) are returned beside the instance, for Hydra."""
    return _parse(cls, argv, prog, summary, known=True)


def _parse(cls: type[T], argv: Sequence[str], prog: str, summary: str, known: bool) -> tuple[T, list[str]]:
    if any(a in HELP_FLAGS for a in argv):
        raise HelpRequested(help_text(cls, prog, summary, known))
    ks = keys(cls)
    collect = known or any(k.rest for k in ks)
    names = {k.name for k in ks if not k.rest}
    spelled = {s: k.name for k in ks if not k.rest for s in [*k.spellings(), *k.flags]}
    bools = {s for k in ks if k.is_bool for s in k.spellings()}
    takes = {s for k in ks if not k.rest and not k.is_bool for s in k.spellings()}  # --key VALUE
    tokens: list[tuple[int, str]] = []  # (index in argv, the word argparse reads)
    aside: list[int] = []  # overrides that are not keys (argparse would take them for words)
    for i, a in enumerate(argv):
        key, eq, value = a.partition("=")
        if i and argv[i - 1] in takes:
            pass  # the value of --key, as it is
        elif eq and _KEY.fullmatch(key.lstrip("+~")) and not a.startswith("-"):
            if key not in names:
                if not collect:
                    raise ArgsError(_unknown(key, ks))
                aside.append(i)
                continue
            a = f"--{key}={value}"
        elif collect and a.startswith(("-", "+", "~")) and key not in spelled:  # -m, --cfg, +x
            aside.append(i)
            continue
        elif a in bools and (i + 1 == len(argv) or argv[i + 1].lower() not in _BOOL):
            a += "=true"  # a bool flag alone is true (never takes the next word)
        tokens.append((i, a))
    named = {spelled.get(t.partition("=")[0]) for _, t in tokens}  # a positional named so takes no words
    parser = _parser(ks, cls, prog, summary, known, {n for n in named if n})
    try:
        ns, extras = parser.parse_known_intermixed_args([t for _, t in tokens])
    except argparse.ArgumentError as exc:
        k = next((k for k in ks if exc.argument_name in ("/".join(k.spellings()), k.spellings()[0])), None)
        raise ArgsError(
            f"{k.spellings()[0]} needs a value ({k.help or _type_words(k.type)})" if k else str(exc)
        ) from None
    if extras and not collect:
        a = extras[0]
        raise ArgsError(
            _unknown(a.partition("=")[0], ks) if a.startswith("-") else f"unexpected argument {a!r}: {usage(cls, prog)}"
        )
    values = _values(ks, vars(ns), prog, cls)
    left = set(aside)  # the argv indices of the rest: put aside, or left by argparse
    for i, token in tokens:
        if extras and extras[0] == token:
            left.add(i)
            extras.pop(0)
    rest = [argv[i] for i in sorted(left)]
    values.update({k.name: rest for k in ks if k.rest})
    try:
        return cls(**values), ([] if any(k.rest for k in ks) else rest)
    except ArgsError:
        raise
    except (TypeError, ValueError) as exc:  # a __post_init__ check across keys
        raise ArgsError(" ".join(str(exc).split())) from None


def _values(ks: list[Key], ns: dict[str, Any], prog: str, cls: type) -> dict[str, Any]:
    """Each given key's value, converted and checked, from argparse's words (``--key`` words are split at
    commas for a list key; a positional's words are not); a required key not given is an error."""
    values: dict[str, Any] = {}
    for k in ks:
        given, bare = ns.get(k.name), ns.get(f"_{k.name}")
        if given is not None:  # Hydra's spelling plugins=[a,b] too
            given = [i.strip() for w in given for i in w.strip("[]").split(",") if i.strip()] if k.is_list else [given]
        bare = [bare] if isinstance(bare, str) else bare or []
        if given is not None or bare:
            values[k.name] = _convert(k, [*bare, *(given or [])])
        elif k.required and not k.rest:
            what = f" ({k.help})" if k.help else ""
            raise ArgsError(f"missing {_usage_word(k)}{what}; usage: {usage(cls, prog)}")
    return values


def _unknown(key: str, ks: list[Key]) -> str:
    name = key.lstrip("-").replace("-", "_")
    names = [k.name for k in ks if not k.rest]
    close = difflib.get_close_matches(name, names, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    return f"unknown argument {key!r}{hint}; keys: {', '.join(names) or 'none'}"


def run(cls: type[T], argv: Sequence[str], body: Callable[[T], int], prog: str, summary: str = "") -> int:
    """Parse ``argv`` into ``cls`` and call ``body`` with it. A bad argument (:class:`ArgsError`, from
    the parser or raised by ``body``: a folder or stage that is not there) is one line on stderr
    (``<prog>: <problem>``) and exit code 2; ``--help`` prints the help and returns 0."""
    try:
        return body(parse(cls, argv, prog, summary))
    except (HelpRequested, ArgsError) as exc:
        return _exit_code(prog, exc)


def _exit_code(prog: str, exc: HelpRequested | ArgsError) -> int:
    """0 after printing the help, or 2 after one line ``<prog>: <problem>`` on stderr."""
    if isinstance(exc, HelpRequested):
        print(exc)
        return 0
    print(f"{prog}: {exc}", file=sys.stderr)
    return 2


def first_paragraph(doc: str | None) -> str:
    """The first paragraph of a docstring, joined to one line."""
    return " ".join((doc or "").strip().split("\n\n")[0].split())


def settings_main(
    prog: str, commands: Mapping[str, tuple[type, bool]]
) -> Callable[[Callable[[str, Any, list[str]], int]], Callable[..., int]]:
    """Make ``run(command, settings, overrides) -> int`` a verb's ``main(argv=None, prog=prog)`` (the
    hardware commands, the model export, the robot check): ``--verbose`` and one-line errors
    (:func:`sphri.errors.clean_errors`), the settings read by :func:`read_settings` from ``argv``
    (None: ``sys.argv[1:]``), help or a bad argument answered with its exit code, INFO logging on.
    ``prog`` (the verb, ``sphri skin``) names the command in its errors and its usage."""
    import logging

    from sphri.errors import clean_errors

    def wrap(run: Callable[[str, Any, list[str]], int]) -> Callable[..., int]:
        @clean_errors(prog)
        def main(argv: Sequence[str] | None = None, prog: str = prog) -> int:
            got = read_settings(commands, list(argv or ()), prog)
            if isinstance(got, int):
                return got
            logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
            return run(*got)

        main.__doc__, main.__qualname__ = run.__doc__, run.__qualname__
        return main

    return wrap


def read_settings(
    commands: Mapping[str, tuple[type, bool]], argv: Sequence[str], prog: str
) -> tuple[str, Any, list[str]] | int:
    """``PROG [COMMAND] key=value ...`` of a command whose settings are dataclasses (the hardware
    commands, the model export): ``commands`` maps each command word to its dataclass and whether it
    takes config overrides (``""``: no command word). Returns (command, settings, overrides), or
    the exit code after printing the help (0) or one line ``<prog>: <problem>`` on stderr (2)."""
    argv = list(argv)
    words = [w for w in commands if w]

    def summary(cls: type) -> str:  # "``sphri skin record``: save ..." -> "save ..."
        text = first_paragraph(cls.__doc__)
        return text.split("``: ", 1)[1] if text.startswith("``") and "``: " in text else text

    if words and (not argv or argv[0] in (*HELP_FLAGS, "help")):
        texts = [help_text(c, f"{prog} {w}", summary(c), k) for w, (c, k) in commands.items()]
        print("\n\n".join(texts), file=sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    word = argv.pop(0) if words else ""
    try:
        if word not in commands:
            close = difflib.get_close_matches(word, words, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise ArgsError(f"unknown command {word!r}{hint}; commands: {', '.join(words)}")
        cls, known = commands[word]
        settings: Any  # an instance of cls (commands' classes are not one type)
        settings, overrides = _parse(cls, argv, f"{prog} {word}".strip(), summary(cls), known)
        return word, settings, overrides
    except (HelpRequested, ArgsError) as exc:
        return _exit_code(prog, exc)
