"""One ``key=value`` parser for sphri's commands (every verb but ``run``/``sweep``, which Hydra parses).

A command declares its arguments once, as a dataclass whose fields are made with :func:`arg`; the
field's type is the value's type and its ``help`` the line ``--help`` prints. :func:`parse` reads

- ``key=value``, ``--key value``, ``--key=value`` (``--some-key`` for ``some_key``), and the
  field's extra spellings (``flags``, e.g. ``--no-log`` for ``mlflow=false``);
- bare words, for the ``positional`` fields in order (a list field takes every remaining word);
- anything else, into the ``rest`` field when there is one (the Hydra overrides of a command that
  composes a config, e.g. ``data.participants=4`` or ``-m``), or returned beside the arguments by
  :func:`parse_known`, else it is an error.

The dataclass may also be a :class:`sphri.config.Schema` (the hardware commands' and the model
export's settings): its fields' docstrings are their help, ``"???"`` marks a required key, a
:func:`sphri.config.setting` range checks the value (naming the key) and lists the choices, and
``Schema.check`` runs on the instance.

Values are converted to the field's type: ``str``, ``int``, ``float``, ``bool`` (true/false, yes/no,
on/off, 1/0), ``Path``, a ``Literal``'s choices, ``X | None`` (``none`` for a non-string ``X``), and
``list[X]`` (comma-separated, or repeated keys, or words). A field's ``check`` returns what the value
must be, or None. Each problem is :class:`ArgsError`: one line naming the key and what it allows
(:func:`run` prints it and returns 2). Standard library only (:mod:`sphri.config` is imported only
for a Schema's fields): the TAB completion reads the schemas.
"""

from __future__ import annotations

import dataclasses
import difflib
import re
import sys
import textwrap
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, TypeVar

T = TypeVar("T")

_TRUE = ("true", "yes", "on", "1")
_FALSE = ("false", "no", "off", "0")
_KEY = re.compile(r"[A-Za-z_][\w.\-]*")
HELP_FLAGS = ("-h", "--help")


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
    flags: dict[str, str | None] | None = None,
    check: Callable[[Any], str | None] | None = None,
    metavar: str = "",
    choices: Sequence[str] = (),
) -> Any:
    """A field of a command's argument dataclass.

    ``flags`` maps extra spellings to a fixed value (``{"--no-log": "false"}``) or to None (the
    spelling takes the next word as its value). ``check(value)`` returns what a valid value must
    be (``"must be >= 0"``) or None. ``choices`` are the values a text key (or each item of a list key)
    may take: checked (an unknown one is named, with the close matches) and offered by the TAB completion.
    ``rest`` marks a ``list[str]`` field that collects every argument that is not one of the command's
    keys (for Hydra overrides)."""
    meta = {
        "help": help,
        "positional": positional,
        "rest": rest,
        "flags": dict(flags or {}),
        "check": check,
        "metavar": metavar,
        "choices": tuple(choices),
    }
    if isinstance(default, (list, tuple)):
        items = list(default)
        return dataclasses.field(default_factory=lambda: list(items), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


@dataclasses.dataclass(frozen=True)
class Key:
    """One argument of a command, read from its dataclass field."""

    name: str
    type: Any
    default: Any
    required: bool
    help: str
    positional: bool
    rest: bool
    flags: dict[str, str | None]
    check: Callable[[Any], str | None] | None
    metavar: str
    allowed: tuple[str, ...] = ()  # arg(choices=...), or a Schema setting's choices

    @property
    def is_list(self) -> bool:
        return _is_list(self.type)

    @property
    def is_bool(self) -> bool:
        return _base(self.type) is bool

    def choices(self) -> tuple[str, ...]:
        """The allowed values of a ``Literal`` (or bool) key, or its declared choices, else ()."""
        if self.allowed:
            return self.allowed
        t = _base(_item(self.type) if self.is_list else self.type)
        if typing.get_origin(t) is Literal:
            return tuple(str(c) for c in typing.get_args(t))
        if t is bool:
            return ("true", "false")
        return ()

    def spellings(self) -> list[str]:
        dashed = "--" + self.name.replace("_", "-")
        return list(dict.fromkeys([f"--{self.name}", dashed, *self.flags]))


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
        m = f.metadata
        rng = ranges.get(f.name)
        allowed = tuple(m.get("choices", ())) or tuple(str(c) for c in getattr(rng, "choices", None) or ())
        if f.default == "???":  # OmegaConf's MISSING: a Schema's required setting
            default, required = None, True
        elif f.default is not dataclasses.MISSING:
            default, required = f.default, False
        elif f.default_factory is not dataclasses.MISSING:
            default, required = f.default_factory(), False
        else:
            default, required = None, True
        out.append(
            Key(
                name=f.name,
                type=hints[f.name],
                default=default,
                required=required,
                help=m.get("help", docs.get(f.name, "")),
                positional=m.get("positional", False),
                rest=m.get("rest", False),
                flags=m.get("flags", {}),
                check=m.get("check") or _choice_check(m, f.name) or _range_check(f.name, rng),
                metavar=m.get("metavar", ""),
                allowed=allowed,
            )
        )
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


def _range_check(name: str, rng: Any) -> Callable[[Any], str | None] | None:
    """A Schema setting's range (:class:`sphri.config.Range`) as a key's ``check`` (its ConfigError names the key)."""
    if rng is None:
        return None

    def check(value: Any) -> None:
        rng.check(name, value)

    return check


def _is_optional(t: Any) -> bool:
    return typing.get_origin(t) in (typing.Union, types.UnionType) and type(None) in typing.get_args(t)


def _base(t: Any) -> Any:
    """``X`` of ``X | None``."""
    if _is_optional(t):
        (inner,) = [a for a in typing.get_args(t) if a is not type(None)]
        return inner
    return t


def _is_list(t: Any) -> bool:
    return typing.get_origin(_base(t)) in (list, tuple)


def _item(t: Any) -> Any:
    args = typing.get_args(_base(t))
    return args[0] if args else str


def _type_words(t: Any) -> str:
    """What a value of type ``t`` must be, in words."""
    t = _base(t)
    if typing.get_origin(t) is Literal:
        return "one of " + ", ".join(str(c) for c in typing.get_args(t))
    return {int: "an integer", float: "a number", bool: "true or false", Path: "a path", str: "text"}.get(t, str(t))


def _scalar(key: Key, t: Any, text: str, shown: str) -> Any:
    """``text`` as a value of type ``t`` (``shown`` is how the argument is quoted in an error)."""
    if _is_optional(t):
        inner = _base(t)
        if inner is not str and text.lower() in ("none", "null", ""):
            return None
        t = inner
    bad = ArgsError(f"{shown} is invalid: must be {_type_words(t)}")
    if typing.get_origin(t) is Literal:
        for choice in typing.get_args(t):
            if text == str(choice):
                return choice
        close = difflib.get_close_matches(text, [str(c) for c in typing.get_args(t)], n=1)
        raise ArgsError(str(bad) + (f" (did you mean {close[0]}?)" if close else ""))
    if t is bool:
        if text.lower() in _TRUE:
            return True
        if text.lower() in _FALSE:
            return False
        raise bad
    if t is int:
        try:
            return int(text)
        except ValueError:
            raise bad from None
    if t is float:
        try:
            value = float(text)
        except ValueError:
            raise bad from None
        if value != value:  # nan passes every range check
            raise bad
        return value
    if t is Path:
        return Path(text)
    return text


def _convert(key: Key, words: list[str], shown: str) -> Any:
    """The value of ``key`` from its words (one word unless the key is a list)."""
    if key.is_list:
        if not key.positional:  # Hydra's spelling plugins=[a,b] too
            words = [w[1:-1] if w.startswith("[") and w.endswith("]") else w for w in words]
        items = [w.strip() for word in words for w in (word.split(",") if not key.positional else [word])]
        items = [w for w in items if w]
        value: Any = [_scalar(key, _item(key.type), w, f"{key.name}={w}") for w in items]
        if typing.get_origin(_base(key.type)) is tuple:
            value = tuple(value)
    else:
        value = _scalar(key, key.type, words[-1], shown)
    if key.check is not None:
        try:
            problem = key.check(value)
        except ValueError as exc:  # a validator's own message (it names the value)
            raise ArgsError(" ".join(str(exc).split())) from None
        if problem:
            raise ArgsError(f"{shown} is invalid: {problem}")
    return value


def _usage_word(key: Key) -> str:
    name = key.metavar or key.name.upper()
    if key.positional:
        word = f"{name} ..." if key.is_list else name
        return word if key.required else f"[{word}]"
    return f"{key.name}={_metavar(key)}"


def _metavar(key: Key) -> str:
    """How a key's value is shown in the usage and help: its metavar, choices, or type."""
    if key.metavar:
        return key.metavar
    if key.choices():
        return "|".join(key.choices()) + (",..." if key.is_list else "")
    t = _base(_item(key.type) if key.is_list else key.type)
    word = {int: "INT", float: "NUMBER", bool: "BOOL", Path: "PATH"}.get(t, "TEXT")
    return f"{word},..." if key.is_list else word


def usage(cls: type, prog: str, overrides: bool = False) -> str:
    """``usage: PROG POSITIONAL [key=value ...]`` of a command (``overrides``: it takes Hydra's too)."""
    ks = keys(cls)
    words = [_usage_word(k) for k in ks if k.positional]
    words += [_usage_word(k) for k in ks if k.required and not k.positional and not k.rest]
    if any(not k.positional and not k.rest and not k.required for k in ks):
        words.append("[key=value ...]")
    words += [f"[{k.metavar or 'overrides'} ...]" for k in ks if k.rest]
    words += ["[overrides ...]"] if overrides else []
    return " ".join(["usage:", prog, *words])


def help_text(cls: type, prog: str, summary: str = "", overrides: bool = False) -> str:
    """``--help`` of a command: usage, summary, then one line per key (type, default, meaning);
    ``overrides``: it passes the other ``key=value`` arguments to the config (a closing line says so)."""
    lines = [usage(cls, prog, overrides)]
    if summary:
        lines += ["", textwrap.fill(" ".join(summary.split()), width=100)]
    ks = keys(cls)
    if ks:
        lines += ["", "arguments (key=value, or --key value):"]
    for k in ks:
        if k.rest:
            head = f"  {k.metavar or 'overrides'}"
        elif k.positional:
            head = f"  {k.metavar or k.name.upper()}"
        else:
            head = f"  {k.name}={_metavar(k)}"
        if k.required:
            tail = " (required)"
        elif k.rest or k.default in (None, "", [], ()):
            tail = ""
        else:
            d = ",".join(map(str, k.default)) if isinstance(k.default, (list, tuple)) else k.default
            tail = f" (default {str(d).lower() if isinstance(d, bool) else d})"
        extra = [s for s in k.flags if k.flags[s] is not None]
        alias = f"; {', '.join(extra)} for {k.name}={'/'.join(str(k.flags[s]) for s in extra)}" if extra else ""
        text = (k.help + tail + alias).strip()
        if len(head) > 28:
            lines.append(head)
            head = ""
        lines.append(
            textwrap.fill(
                text, width=100, initial_indent=f"{head:<30}", subsequent_indent=" " * 30, break_on_hyphens=False
            )
        )
    if overrides:
        lines += ["  overrides                   any other key=value: a config override (+debug=fast, robot=nao_child)"]
    return "\n".join(lines)


def parse(cls: type[T], argv: Sequence[str], prog: str = "sphri", summary: str = "") -> T:
    """The arguments ``argv`` as an instance of ``cls`` (raises :class:`ArgsError`, or
    :class:`HelpRequested` for ``-h``/``--help``)."""
    return _parse(cls, argv, prog, summary, known=False)[0]


def parse_known(cls: type[T], argv: Sequence[str], prog: str = "sphri", summary: str = "") -> tuple[T, list[str]]:
    """Like :func:`parse`, for a command that composes a config: the arguments that are not keys of
    ``cls`` (``+debug=fast``, ``data.seed=3``) are returned beside the instance, for Hydra."""
    return _parse(cls, argv, prog, summary, known=True)


def _parse(cls: type[T], argv: Sequence[str], prog: str, summary: str, known: bool) -> tuple[T, list[str]]:
    ks = keys(cls)
    by_name = {k.name: k for k in ks}
    by_flag: dict[str, tuple[Key, str | None]] = {}
    for k in ks:
        if not k.rest:
            for s in k.spellings():
                by_flag[s] = (k, k.flags.get(s))
    rest_key = next((k for k in ks if k.rest), None)
    collect = rest_key is not None or known
    positional = [k for k in ks if k.positional]
    words: dict[str, list[str]] = {}
    shown: dict[str, str] = {}
    rest: list[str] = []

    def put(k: Key, value: str, spelled: str) -> None:
        words[k.name] = [*words.get(k.name, []), value] if k.is_list else [value]  # a repeated key: last wins
        shown[k.name] = spelled

    args = list(argv)
    if any(a in HELP_FLAGS for a in args):
        raise HelpRequested(help_text(cls, prog, summary, known))
    i = 0
    while i < len(args):
        a = args[i]
        i += 1
        if a.startswith("--") or a in by_flag:
            flag, eq, inline = a.partition("=")
            if flag in by_flag:
                k, fixed = by_flag[flag]
                if fixed is not None and not eq:
                    put(k, fixed, f"{flag}")
                    continue
                if eq:
                    put(k, inline, f"{k.name}={inline}")
                    continue
                if k.is_bool and not (i < len(args) and args[i].lower() in (*_TRUE, *_FALSE)):
                    put(k, "true", flag)
                    continue
                if i >= len(args) or args[i].partition("=")[0] in by_flag:  # at the end, or another flag follows
                    raise ArgsError(f"{flag} needs a value ({k.help or _type_words(k.type)})")
                put(k, args[i], f"{k.name}={args[i]}")
                i += 1
                continue
            if collect:
                rest.append(a)
                continue
            raise ArgsError(_unknown(flag, ks))
        key, eq, value = a.partition("=")
        if eq and _KEY.fullmatch(key) and key in by_name and not by_name[key].rest:
            put(by_name[key], value, a)
            continue
        if eq and _KEY.fullmatch(key.lstrip("+~")):
            if collect:
                rest.append(a)
                continue
            raise ArgsError(_unknown(key, ks))
        if a.startswith(("-", "+", "~")) and collect:
            rest.append(a)
            continue
        slot = next((k for k in positional if k.is_list or k.name not in words), None)
        if slot is not None:
            put(slot, a, f"{slot.name}={a}")
            continue
        if collect:
            rest.append(a)
            continue
        raise ArgsError(f"unexpected argument {a!r}: {usage(cls, prog).removeprefix('usage: ')}")

    values: dict[str, Any] = {}
    for k in ks:
        if k.rest:
            values[k.name] = rest
        elif k.name in words:
            values[k.name] = _convert(k, words[k.name], shown[k.name])
        elif k.required:
            what = f" ({k.help})" if k.help else ""
            raise ArgsError(f"missing {_usage_word(k).strip('[]')}{what}; {usage(cls, prog)}")
    try:
        return cls(**values), ([] if rest_key is not None else rest)
    except ArgsError:
        raise
    except (TypeError, ValueError) as exc:  # a __post_init__ check across keys
        raise ArgsError(" ".join(str(exc).split())) from None


def _unknown(key: str, ks: list[Key]) -> str:
    name = key.lstrip("-").replace("-", "_")
    names = [k.name for k in ks if not k.rest]
    close = difflib.get_close_matches(name, names, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    return f"unknown argument {key!r}{hint}; keys: {', '.join(names) or 'none'}"


def run(
    cls: type[T],
    argv: Sequence[str],
    body: Callable[[T], int],
    prog: str,
    summary: str = "",
    usage_prog: str = "",
) -> int:
    """Parse ``argv`` into ``cls`` and call ``body`` with it. A bad argument (:class:`ArgsError`, from
    the parser or raised by ``body``) is one line on stderr (``<prog>: <problem>``) and exit code 2;
    ``--help`` prints the help and returns 0."""
    args = _or_exit_code(prog, lambda: parse(cls, argv, usage_prog or prog, summary))
    if isinstance(args, int):
        return args
    try:
        return body(args)
    except ArgsError as exc:  # found by the command itself (a folder or stage that is not there)
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2


def _or_exit_code(prog: str, parse_call: Callable[[], T]) -> T | int:
    """``parse_call()``'s value (never an int), or the exit code after printing the help (0) or one
    line ``<prog>: <problem>`` on stderr (2)."""
    try:
        return parse_call()
    except HelpRequested as h:
        print(h)
        return 0
    except ArgsError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return 2


def first_paragraph(doc: str | None) -> str:
    """The first paragraph of a docstring, joined to one line."""
    return " ".join((doc or "").strip().split("\n\n")[0].split())


def settings_main(
    module: str, commands: Mapping[str, tuple[type, bool]]
) -> Callable[[Callable[[str, Any, list[str]], int]], Callable[..., int]]:
    """Make ``run(command, settings, overrides) -> int`` a module's ``main(argv=None, prog="")`` (the
    hardware commands, the model export): ``--verbose`` and one-line errors
    (:func:`sphri.errors.clean_errors`), the settings read by :func:`read_settings` from ``argv``
    (None: ``sys.argv[1:]``), help or a bad argument answered with its exit code, INFO logging on.
    Without ``prog`` (``sphri VERB`` when dispatched) errors name ``module`` and usage says
    ``python -m module``."""
    import logging

    from sphri.errors import clean_errors

    def wrap(run: Callable[[str, Any, list[str]], int]) -> Callable[..., int]:
        @clean_errors(module)
        def main(argv: Sequence[str] | None = None, prog: str = "") -> int:
            got = read_settings(commands, list(argv or ()), prog or module, prog or f"python -m {module}")
            if isinstance(got, int):
                return got
            logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
            return run(*got)

        main.__doc__, main.__qualname__ = run.__doc__, run.__qualname__
        return main

    return wrap


def read_settings(
    commands: Mapping[str, tuple[type, bool]], argv: Sequence[str], prog: str, usage_prog: str = ""
) -> tuple[str, Any, list[str]] | int:
    """``PROG [COMMAND] key=value ...`` of a command whose settings are dataclasses (the hardware
    commands, the model export): ``commands`` maps each command word to its dataclass and whether it
    takes config overrides (``""``: no command word). Returns (command, settings, overrides), or
    the exit code after printing the help (0) or one line ``<prog>: <problem>`` on stderr (2)."""
    argv, usage_prog = list(argv), usage_prog or prog
    words = [w for w in commands if w]

    def summary(cls: type) -> str:  # "``python -m sphri.hardware.skin record``: save ..." -> "save ..."
        text = first_paragraph(cls.__doc__)
        return text.split("``: ", 1)[1] if text.startswith("``") and "``: " in text else text

    if words and (not argv or argv[0] in (*HELP_FLAGS, "help")):
        texts = [help_text(c, f"{usage_prog} {w}", summary(c), k) for w, (c, k) in commands.items()]
        print("\n\n".join(texts), file=sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    word = argv.pop(0) if words else ""
    if word not in commands:
        close = difflib.get_close_matches(word, words, n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        print(f"{prog}: unknown command {word!r}{hint}; commands: {', '.join(words)}", file=sys.stderr)
        return 2
    cls, known = commands[word]
    parsed: tuple[Any, list[str]] | int = _or_exit_code(
        prog, lambda: _parse(cls, argv, f"{usage_prog} {word}".strip(), summary(cls), known)
    )
    if isinstance(parsed, int):
        return parsed
    settings, overrides = parsed
    return word, settings, overrides
