"""``python -m sphri.cli``: list components and validate configs without running.

::

    python -m sphri.cli list                 # every group and its components
    python -m sphri.cli list robot           # one group, with each file's summary
    python -m sphri.cli show noise=crosstalk # every setting of a component: value, default, meaning
    python -m sphri.cli validate +robot=reachy encoder.res=18
    python -m sphri.cli validate -m encoder.res=0,4           # a sweep: every job is checked
    python -m sphri.cli validate +experiment=resolution_sweep # its 100 jobs

``validate`` composes the config exactly as ``python -m sphri`` would, runs
every schema's checks, and prints the chosen components; it exits 2 with a
message naming the key on any problem.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
import textwrap
from pathlib import Path

import yaml

from sphri.config import CONF_DIR, DEFAULT_GROUPS, ConfigError, check_inputs, compose, validate
from sphri.errors import clean_errors
from sphri.stages import PARAM_GROUPS, STAGE_GROUPS


def components(group: str) -> list[tuple[str, str]]:
    """(name, one-line description) of each YAML file in ``conf/<group>/``."""
    folder = CONF_DIR / group
    if not folder.is_dir():
        raise ConfigError(f"unknown config group {group!r}; groups: {', '.join(DEFAULT_GROUPS)}")
    out = []
    for path in sorted(folder.glob("*.yaml")):
        out.append((path.stem, _describe(path)))
    return out


def _describe(path: Path) -> str:
    """One line about a config file: its first comment block (wherever it
    starts, e.g. after the defaults list), up to the end of its first
    sentence; else its ``_target_``."""
    text = path.read_text()
    block: list[str] = []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#") and not s.startswith("# @package"):
            block.append(s.lstrip("#").strip())
        elif block:
            break
    if block:
        words = " ".join(w for w in block if w)
        end = re.search(r"(?<!e\.g)(?<!i\.e)[.!?](\s|$)", words)
        return words[: end.start() + 1] if end else words
    # no comment block: fall through to the target
    try:
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as exc:
        return f"(unreadable: {exc})"
    return str(data.get("_target_", "")) if isinstance(data, dict) else ""


WIDTH = 100  # columns of every wrapped line `cli` prints (list, show, --help)


def _row(head: str, text: str, width: int = WIDTH) -> str:
    """``head`` then ``text`` wrapped to ``width`` columns, continuation lines under the text.

    The text's whitespace is collapsed first, and a head that leaves fewer than 30 columns for
    the text puts the text on the lines below it (indented by 8): CPython's ``textwrap`` never
    returns when the indent is not shorter than the width and the text starts with a space
    (``textwrap.fill(' a', width=10, initial_indent='x' * 20)``), so neither reaches it.
    """
    text = " ".join(str(text).split())
    if not text:
        return head.rstrip()
    if len(head) > width - 30:
        body = textwrap.fill(text, width=width, initial_indent=" " * 8, subsequent_indent=" " * 8)
        return head.rstrip() + "\n" + body
    return textwrap.fill(text, width=width, initial_indent=head, subsequent_indent=" " * len(head))


def _short(value: object, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters (a list or mapping says how many items it has)."""
    text = repr(value)
    if len(text) <= limit:
        return text
    size = f" ({len(value)} items)" if isinstance(value, (list, tuple, dict)) else ""
    return text[: max(limit - 3 - len(size), 8)] + "..." + size


def _defaults() -> dict[str, str]:
    """The default option of each group, from ``conf/config.yaml``'s defaults list."""
    data = yaml.safe_load((CONF_DIR / "config.yaml").read_text()) or {}
    out = {}
    for item in data.get("defaults", []):
        if isinstance(item, dict):
            for k, v in item.items():
                if isinstance(k, str) and not k.startswith(("override ", "optional ")) and isinstance(v, str):
                    out[k] = v
    return out


def help_text() -> str:
    """``python -m sphri --help``: usage, common commands, every group's options (one line each)."""
    defaults = _defaults()
    lines = [
        "sphri: design robot tactile skins from interaction data.",
        "",
        "usage:",
        "  python -m sphri [group=option ...] [key=value ...]      one job (one MLflow run)",
        "  python -m sphri -m key=a,b,c [...]                      a sweep (one MLflow parent run)",
        "",
        "common commands:",
        "  python -m sphri +robot=reachy encoder.res=18            the paper's resolution",
        "  python -m sphri +debug=fast                             a seconds-long smoke run",
        "  python -m sphri -m +experiment=resolution_sweep model=rf   the 50-resolution curve",
        "  python -m sphri.report SWEEP_DIR                        the sweep's report",
        "  python -m sphri.coverage data.regions=[arm,torso] out=DIR   where people touch",
        "  python -m sphri.cli list [GROUP] | validate OVERRIDES   components; check a config",
        "  python -m sphri --cfg job [overrides]                   print the composed config",
        "  python -m sphri --hydra-help                            Hydra's own flags",
        "",
        "config groups (group=option; * marks the default; `python -m sphri.cli list GROUP` says what each",
        "option is, `python -m sphri.cli show GROUP=OPTION` every setting of it):",
    ]
    for group in DEFAULT_GROUPS:
        if not (CONF_DIR / group).is_dir():
            continue
        names = [("*" if defaults.get(group) == name else "") + name for name, _ in components(group)]
        lines.append(_row(f"  {group:<12} ", "  ".join(names)))
    lines += ["", "top-level keys: seed, output_dir, resume, cache.enabled, cache.dir (see README.md)"]
    return "\n".join(lines)


def cmd_list(groups: list[str]) -> int:
    for group in groups or list(DEFAULT_GROUPS):
        print(f"{group}:")
        for name, desc in components(group):
            print(_row(f"  {name:<20} ", desc))
    return 0


def cmd_show(overrides: list[str], groups: list[str] | None = None) -> int:
    """Print each setting of the chosen components: its value, the schema default when the value
    differs, and its meaning (the schema's field docstring: defaults and docs live there once)."""
    from omegaconf import OmegaConf

    from sphri.config import field_docs

    cfg = compose(overrides, check=False)
    try:
        validate(cfg)
        problem = ""
    except ConfigError as exc:
        problem = str(exc)
    named = [o.lstrip("+").split("=", 1)[0].split(".", 1)[0] for o in overrides if "=" in o]
    shown = groups or [g for g in STAGE_GROUPS if g in named] or list(STAGE_GROUPS)
    for group in shown:
        if group not in STAGE_GROUPS:
            raise ConfigError(f"unknown config group {group!r}; groups: {', '.join(STAGE_GROUPS)}")
        node = cfg[group]
        schema = OmegaConf.get_type(node)
        docs = field_docs(schema) if isinstance(schema, type) else {}
        try:
            default = OmegaConf.to_container(OmegaConf.structured(schema)) if dataclasses.is_dataclass(schema) else {}
        except Exception:  # a schema without defaults for every field
            default = {}
        values = OmegaConf.to_container(node, resolve=True)
        print(f"{group}: {str(values.pop('_target_', '')).rsplit('.', 1)[-1]}")
        for key, value in values.items():
            mark = "" if key not in default or default[key] == value else f" [changed; default {_short(default[key])}]"
            print(_row(f"  {key:<24} {_short(value):<14} ", docs.get(key, "") + mark))
    if problem:
        print(_row("note: ", f"this config does not run as it stands: {problem}"))
    return 0


def is_sweep(overrides: list[str]) -> bool:
    """True for the arguments of a multirun: ``-m``, a comma list, ``range()``/``choice()``, or an experiment
    (experiments sweep through ``hydra.sweeper.params``)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    if any(a in ("-m", "--multirun") for a in overrides):
        return True
    plain = [a for a in overrides if not a.startswith("-")]
    try:
        parsed = OverridesParser.create().parse_overrides(plain)
    except Exception:  # composition reports the bad override with its key
        return False
    return any(o.is_sweep_override() or o.key_or_group == "experiment" for o in parsed)


def cmd_validate_sweep(overrides: list[str]) -> int:
    """Compose and validate every job of the sweep through ``hydra/sweeper=sphri`` (the code path a real
    sweep takes), running none of them. In a child process: Hydra's app sets up logging and global state."""
    import os
    import subprocess

    argv = ["-m", *[a for a in overrides if a not in ("-m", "--multirun")], "hydra/launcher=basic"]
    env = {**os.environ, "SPHRI_VALIDATE_ONLY": "1"}
    return subprocess.run([sys.executable, "-m", "sphri", *argv], env=env).returncode


def cmd_validate(overrides: list[str]) -> int:
    from omegaconf import OmegaConf

    from sphri.pipeline import chain_region

    if is_sweep(overrides):
        return cmd_validate_sweep(overrides)
    cfg = compose(overrides)
    chain_region(cfg)
    check_inputs(cfg)
    print("config OK")
    for group in PARAM_GROUPS:
        node = OmegaConf.to_container(cfg[group], resolve=True)
        target = str(node.pop("_target_", "")).rsplit(".", 1)[-1]
        scalars = ", ".join(f"{k}={v}" for k, v in node.items() if not isinstance(v, (dict, list)))
        print(f"  {group:<8} {target}({scalars})")
    return 0


def cmd_warmup() -> int:
    """Run the ``+debug=fast`` chain once (tracking off, in a temporary folder): every kernel the
    chain calls compiles into numba's on-disk cache, so later jobs load them. Says what it compiled."""
    import subprocess
    import tempfile
    import time

    print("compiling sphri's numba kernels into numba's cache (once per machine and sphri version)...", flush=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="sphri-warmup-") as tmp:
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "sphri",
                "+debug=fast",
                "tracking.enabled=false",
                f"output_dir={tmp}",
                f"hydra.run.dir={tmp}/run",
            ],
            cwd=tmp,
            capture_output=True,
            text=True,
        )
    seconds = time.perf_counter() - t0
    if run.returncode != 0:
        tail = (run.stderr or run.stdout).strip().splitlines()[-1:] or ["no output"]
        print(f"sphri: warmup failed after {seconds:.0f} s: {tail[0]}", file=sys.stderr)
        return 1
    compiled = [
        line.split("compiled ", 1)[1] for line in (run.stdout + run.stderr).splitlines() if "numba kernels in" in line
    ]
    print(
        f"done in {seconds:.1f} s: "
        + (f"compiled {compiled[-1]}" if compiled else "every kernel was already in the cache")
    )
    return 0


@clean_errors("sphri")
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sphri.cli", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p_list = sub.add_parser("list", help="list the components of each config group")
    p_list.add_argument("groups", nargs="*", help="groups to list (default: all)")
    p_show = sub.add_parser("show", help="every setting of the chosen components: value, default, meaning")
    p_show.add_argument("overrides", nargs="*", help="choices and overrides, e.g. encoder=coverage noise.p=0.05")
    p_show.add_argument(
        "--group",
        action="append",
        default=None,
        help="groups to show (default: those named in the overrides, else every group)",
    )
    p_val = sub.add_parser("validate", help="compose and check a config without running it")
    p_val.add_argument(
        "overrides",
        nargs="*",
        help="overrides as for python -m sphri; a sweep (-m, a,b,c, range(), +experiment=...) checks every job",
    )
    sub.add_parser(
        "warmup",
        help="compile sphri's numba kernels into numba's cache now (make install runs it), so the first job does not",
    )
    args, extra = parser.parse_known_args(argv)
    if extra and args.cmd != "validate":
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    if extra:  # `-m` (a sweep) is sphri's option, not this parser's
        args.overrides = [*extra, *args.overrides]
    try:
        if args.cmd == "list":
            return cmd_list(args.groups)
        if args.cmd == "show":
            return cmd_show(args.overrides, args.group)
        if args.cmd == "warmup":
            return cmd_warmup()
        return cmd_validate(args.overrides)
    except ConfigError as exc:
        print(f"sphri: invalid config: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
