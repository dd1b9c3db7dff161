"""The generated reference pages of the documentation site: every config setting and every verb.

::

    python -m sphri.docs_gen OUT_DIR         # writes OUT_DIR/reference/config.md and OUT_DIR/reference/cli.md

A maintainer's tool, not a verb of ``sphri``: the documentation site makes the same pages at build
time (``docs/hooks.py``, ``mkdocs build``); ``python -m sphri.docs_gen`` writes them alone, as Markdown.

The pages are read from what the commands themselves read, so they cannot drift from them:

- the config reference from the schemas ``sphri show`` prints (each component's YAML merged onto
  its schema by :func:`sphri.config.component_node`; a setting's type from its annotation, its range
  from :func:`sphri.config.setting`'s metadata, its meaning from the docstring under the field), one
  section per config group, one table per component;
- the CLI reference from the verb table :data:`sphri.command.VERBS` and each verb's argument dataclass
  or settings schemas, read by :func:`sphri.args.keys` as ``sphri VERB --help`` reads them.

``mkdocs build`` runs it through ``docs/hooks.py``: the pages are added to the site at build time and
never written into ``docs/``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import re
import sys
import typing
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

#: The generated pages, by their path inside the site.
CONFIG_PAGE = "reference/config.md"
CLI_PAGE = "reference/cli.md"

_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")  # :func:`sphri.x.y` -> `sphri.x.y`


def markdown_text(text: str) -> str:
    """A docstring's words as Markdown for a table cell: RST roles and double backticks as code,
    whitespace collapsed, ``|`` escaped."""
    text = _ROLE.sub(r"`\1`", " ".join(str(text).split()))
    return text.replace("``", "`").replace("|", "\\|")


def type_words(t: Any) -> str:
    """A field's type as written in Python (``int``, ``str | None``, ``list[float]``)."""
    if isinstance(t, str):
        return t
    if t is type(None):
        return "None"
    origin = typing.get_origin(t)
    if origin is typing.Union or (origin is not None and getattr(origin, "__name__", "") == "UnionType"):
        return " | ".join(type_words(a) for a in typing.get_args(t))
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(t))
    if origin is not None:
        args = ", ".join(type_words(a) for a in typing.get_args(t))
        name = getattr(origin, "__name__", str(origin))
        return f"{name}[{args}]" if args else name
    if t is Any:
        return "any"
    return getattr(t, "__name__", str(t))


def range_words(rng: Any) -> str:
    """A :class:`sphri.config.Range` in words: ``[1, 1000]``, ``integer in (0, inf)``, ``one of a, b``."""
    if rng is None:
        return ""
    if rng.choices is not None:
        text = "one of " + ", ".join(str(c) for c in rng.choices)
    elif rng.lo is None and rng.hi is None:
        text = "integer" if rng.integer else ""
    else:
        lb = "(" if rng.lo_open or rng.lo is None else "["
        rb = ")" if rng.hi_open or rng.hi is None else "]"
        lo = "-inf" if rng.lo is None else f"{rng.lo:g}"
        hi = "inf" if rng.hi is None else f"{rng.hi:g}"
        text = ("integer in " if rng.integer else "") + f"{lb}{lo}, {hi}{rb}"
    return text + (" or None" if rng.optional and text else "")


def value_words(value: Any, limit: int = 60) -> str:
    """A default value as code, cut to ``limit`` characters (a list or mapping says how many items)."""
    if value is dataclasses.MISSING or value == "???":
        return "(required)"
    if isinstance(value, bool):
        text = str(value).lower()
    elif value is None:
        text = "null"
    else:
        text = repr(value)
    if len(text) > limit:
        size = f" ({len(value)} items)" if isinstance(value, (list, tuple, dict)) else ""
        text = text[: max(limit - 3 - len(size), 8)] + "..." + size
    return "`" + text.replace("|", "\\|").replace("`", "'") + "`"


@dataclasses.dataclass(frozen=True)
class SettingRow:
    """One setting of a schema, as the reference lists it."""

    name: str
    type: str
    range: str
    default: str
    meaning: str
    runtime: bool = False


def setting_rows(schema: type, values: dict[str, Any] | None = None) -> list[SettingRow]:
    """The settings of the schema dataclass ``schema`` (``_target_`` left out): type, range, default
    (``values[name]`` where given: a component's own value, else the schema's default), meaning."""
    from sphri.config import RANGE_META, RUNTIME_META, field_docs

    try:
        hints = typing.get_type_hints(schema)
    except Exception:  # an annotation that does not resolve: its text is shown
        hints = {}
    docs = field_docs(schema)
    out = []
    for f in dataclasses.fields(schema):
        if f.name.startswith("_"):
            continue
        if values is not None and f.name in values:
            default: Any = values[f.name]
        elif f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = dataclasses.MISSING
        if dataclasses.is_dataclass(default) and not isinstance(default, type):
            default = dataclasses.asdict(default)
        out.append(
            SettingRow(
                name=f.name,
                type=type_words(hints.get(f.name, f.type)),
                range=range_words(f.metadata.get(RANGE_META)),
                default=value_words(default),
                meaning=markdown_text(docs.get(f.name, "")),
                runtime=bool(f.metadata.get(RUNTIME_META)),
            )
        )
    return out


def settings_table(rows: Sequence[SettingRow], prefix: str = "") -> str:
    """A Markdown table of ``rows``; ``prefix`` (``encoder.``) is written before each name."""
    if not rows:
        return "No settings.\n"
    lines = ["| setting | type | range | default | meaning |", "| --- | --- | --- | --- | --- |"]
    for r in rows:
        note = " (runtime: never changes a result)" if r.runtime else ""
        lines.append(
            f"| `{prefix}{r.name}` | {markdown_text(r.type)} | {markdown_text(r.range)} | {r.default} | {r.meaning}{note} |"
        )
    return "\n".join(lines) + "\n"


def component_schema(group: str, name: str, conf_dir: Path | None = None) -> tuple[type | None, dict[str, Any]]:
    """The schema of component ``conf/<group>/<name>.yaml`` and its own values (unresolved)."""
    from omegaconf import DictConfig, OmegaConf

    from sphri.config import component_node

    node = component_node(group, name, conf_dir)
    schema = OmegaConf.get_type(node) if isinstance(node, DictConfig) else None
    raw = OmegaConf.to_container(node, resolve=False) if isinstance(node, DictConfig) else {}
    assert isinstance(raw, dict)
    values = {str(k): v for k, v in raw.items()}
    if not (isinstance(schema, type) and dataclasses.is_dataclass(schema)):
        return None, values
    return schema, values


def config_reference(groups: Iterable[str] | None = None, conf_dir: Path | None = None) -> str:
    """The config reference page: the top-level settings, then each group's components and their settings."""
    from sphri import COMPONENTS
    from sphri.cli import _defaults, _describe
    from sphri.config import CONF_DIR, RootConfig

    stage_groups = [c.group for c in COMPONENTS]
    conf = conf_dir or CONF_DIR
    defaults = _defaults() if conf_dir is None else {}
    lines = [
        "# Config reference",
        "",
        "Every setting of every component, generated from the schemas `sphri show` reads (the type, the",
        "range a value is checked against when a config is composed, the component's default and the",
        "meaning written under the field). Pick a component with `group=name` and set a value with",
        "`group.key=value`: `sphri encoder=coverage layout.res=24`. `sphri show group=name` prints the",
        "same table for a composed config, with the values it holds.",
        "",
        "A *runtime* setting (threads, progress display) never changes a job's result: it is left out",
        "of the config hash and every cache key.",
        "",
    ]
    if conf_dir is None:
        root_groups = set(stage_groups) | {"debug", "experiment", "variant"}
        root = [r for r in setting_rows(RootConfig) if r.name not in root_groups]
        lines += ["## Top-level settings", "", settings_table(root), ""]
    for group in stage_groups if groups is None else groups:
        folder = conf / group
        if not folder.is_dir():
            continue
        lines += [f"## {group}", ""]
        names = [p.stem for p in sorted(folder.glob("*.yaml"))]
        if group in defaults:
            lines += [f"Components: {', '.join(f'`{n}`' for n in names)}; the default is `{defaults[group]}`.", ""]
        for name in names:
            schema, values = component_schema(group, name, conf_dir)
            lines += [f"### {group}={name}", "", markdown_text(_describe(folder / f"{name}.yaml")), ""]
            if schema is None:
                lines += ["This component has no schema: its YAML is read as it stands.", ""]
                continue
            target = str(values.get("_target_", ""))
            if target:
                lines += [f"Class: `{target}`; schema: `{schema.__module__}.{schema.__qualname__}`.", ""]
            lines += [settings_table(setting_rows(schema, values), prefix=f"{group}."), ""]
    if conf_dir is None:
        lines += _preset_sections(conf)
    return "\n".join(lines).rstrip() + "\n"


#: Config groups that are presets over the stage groups, not components: (group, title, how they are used).
PRESET_GROUPS = (
    ("experiment", "Experiments", "Picked with `+experiment=NAME` (most are sweeps: `sphri sweep +experiment=NAME`)"),
    (
        "sensitivity",
        "Sensitivity variants",
        "Each changes one assumption from the reference; `+experiment=requirement_sensitivity` sweeps them",
    ),
    ("debug", "Debug presets", "Picked with `+debug=NAME`: small sizes for a quick run"),
)


def _preset_sections(conf: Path) -> list[str]:
    """One section per preset group of :data:`PRESET_GROUPS`: each file with its first sentence."""
    from sphri.cli import _describe

    lines: list[str] = []
    for group, title, how in PRESET_GROUPS:
        folder = conf / group
        files = sorted(folder.glob("*.yaml")) if folder.is_dir() else []
        if not files:
            continue
        lines += [f"## {title}", "", f"{how}.", "", "| name | what it is |", "| --- | --- |"]
        lines += [f"| `{p.stem}` | {markdown_text(_describe(p))} |" for p in files]
        lines.append("")
    return lines


def argument_table(cls: type) -> str:
    """A Markdown table of the arguments of a verb's dataclass, as ``sphri VERB --help`` reads them."""
    from sphri.args import _metavar, keys

    ks = keys(cls)
    if not ks:
        return "No arguments.\n"
    lines = ["| argument | value | default | meaning |", "| --- | --- | --- | --- |"]
    for k in ks:
        if k.rest:
            head = k.metavar or "overrides"
        elif k.positional:
            head = k.metavar or k.name.upper()
        else:
            head = f"{k.name}="
        if k.required:
            default = "(required)"
        elif k.rest or k.default in (None, "", [], ()):
            default = ""
        else:
            default = value_words(k.default)
        value = markdown_text(_metavar(k))
        lines.append(f"| `{head}` | {value} | {default} | {markdown_text(k.help)} |")
    return "\n".join(lines) + "\n"


def _help_output(verb: Any) -> str:
    """What ``sphri VERB --help`` prints (for a verb that reads its own arguments without a schema)."""
    from sphri.command import call

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        try:
            call(verb, ["--help"])
        except SystemExit:
            pass
    return out.getvalue().strip()


def cli_reference(verbs: Sequence[Any] | None = None) -> str:
    """The CLI reference page: every verb of :data:`sphri.command.VERBS` with its arguments."""
    from sphri.args import first_paragraph
    from sphri.command import VERBS

    lines = [
        "# CLI reference",
        "",
        "Every verb of `sphri VERB`, generated from the verb table and each verb's argument dataclass or",
        "settings schemas: the same source `sphri VERB --help` and TAB completion read. Arguments are",
        "`key=value` (or `--key value`); a bad value is one line naming the key and what it allows, exit 2.",
        "`python -m sphri VERB` is the same command where the `sphri` script is not on the PATH.",
        "",
        "| verb | what it does |",
        "| --- | --- |",
    ]
    verbs = list(VERBS if verbs is None else verbs)
    lines += [f"| [`{v.name}`](#{v.name}) | {markdown_text(v.summary)} |" for v in verbs]
    lines.append("")
    for v in verbs:
        summary = markdown_text(v.summary)
        lines += [f"## {v.name}", "", summary[:1].upper() + summary[1:] + ".", ""]
        if v.kind == "hydra":
            lines += [
                "Takes Hydra's overrides: `group=name`, `group.key=value`, `+experiment=NAME`, `-m` for a sweep;",
                "every setting is in the [config reference](config.md).",
                "",
            ]
        elif v.kind == "args":
            schema = v.load(v.schema)
            body = v.load(v.target)
            doc = first_paragraph(body.__doc__)
            if doc:
                lines += [markdown_text(doc), ""]
            lines += [argument_table(schema), ""]
        elif v.kind == "main" and v.schema:
            commands = v.load(v.schema)
            for word, (cls, overrides) in commands.items():
                title = f"sphri {v.name} {word}".strip()
                lines += [f"### {title}", ""]
                doc = first_paragraph(cls.__doc__)
                if doc:
                    lines += [markdown_text(doc.split("``: ", 1)[-1]), ""]
                lines += [argument_table(cls), ""]
                if overrides:
                    lines += ["Any other `key=value` is a config override (see the [config reference](config.md)).", ""]
        elif v.kind == "main":
            text = _help_output(v)
            if text:
                lines += ["```text", text, "```", ""]
    return "\n".join(lines).rstrip() + "\n"


def pages() -> dict[str, str]:
    """The generated pages: ``{path inside the site: Markdown}``."""
    return {CONFIG_PAGE: config_reference(), CLI_PAGE: cli_reference()}


def write(out_dir: Path) -> list[Path]:
    """Write :func:`pages` under ``out_dir``; the paths written."""
    written = []
    for rel, text in pages().items():
        path = Path(out_dir) / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        written.append(path)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) != 1 or argv[0] in ("-h", "--help"):
        print("usage: python -m sphri.docs_gen OUT_DIR   (writes reference/config.md and reference/cli.md)")
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    for path in write(Path(argv[0])):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
