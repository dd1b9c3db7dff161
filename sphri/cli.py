"""``sphri list|show|validate|warmup``: list components, show and validate configs without running.

::

    sphri list                           # every group and its components
    sphri list robot                     # one group, with each file's summary
    sphri show noise=crosstalk           # every setting of a component: value, default, meaning
    sphri show tracking                  # one group's settings (= group=tracking)
    sphri validate +robot=reachy layout.res=18
    sphri validate -m layout.res=0,4    # a sweep: every job is checked
    sphri validate +experiment=resolution_sweep   # its 100 jobs

``validate`` composes the config exactly as ``sphri run`` would, runs every schema's checks, and prints the
chosen components; it exits 2 with a message naming the key on any problem. Arguments are read by
:mod:`sphri.args`.
"""

from __future__ import annotations

import dataclasses
import re
import sys
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import yaml

from sphri.args import arg
from sphri.config import CONF_DIR, DEFAULT_GROUPS, RENAMED_KEYS, ConfigError, check_inputs, compose, validate
from sphri.stages import PARAM_GROUPS, STAGE_GROUPS


def components(group: str) -> list[tuple[str, str]]:
    """(name, one-line description) of each YAML file in ``conf/<group>/``."""
    folder = CONF_DIR / group
    if not folder.is_dir():
        raise ConfigError(f"unknown config group {group!r}; groups: {', '.join(DEFAULT_GROUPS)}")
    return [(path.stem, _describe(path)) for path in sorted(folder.glob("*.yaml"))]


def _describe(path: Path) -> str:
    """One line about a config file: its first comment block (wherever it starts, e.g. after the defaults
    list), up to the end of its first sentence; else its ``_target_``."""
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
    items = [kv for item in data.get("defaults", []) if isinstance(item, dict) for kv in item.items()]
    return {
        k: v
        for k, v in items
        if isinstance(k, str) and not k.startswith(("override ", "optional ")) and isinstance(v, str)
    }


def help_text() -> str:
    """``python -m sphri --help``: usage, common commands, every group's options (one line each)."""
    defaults = _defaults()
    lines = [
        "sphri: design robot tactile skins from interaction data.",
        "",
        "usage (`python -m sphri ...` is the same as `sphri ...`):",
        "  sphri [run] [group=option ...] [key=value ...]          one job (one MLflow run)",
        "  sphri sweep key=a,b,c [...]   (or sphri -m ...)         a sweep (one MLflow parent run)",
        "",
        "common commands (`sphri help` lists every verb):",
        "  sphri +robot=reachy layout.res=18                      the paper's resolution",
        "  sphri +debug=fast                                       a smoke run at debug size",
        "  sphri sweep +experiment=resolution_sweep model=rf       the 50-resolution curve",
        "  sphri report SWEEP_DIR                                  the sweep's report",
        "  sphri coverage data.regions=[arm,torso] out=DIR         where people touch",
        "  sphri list [GROUP] | sphri validate OVERRIDES           components; check a config",
        "  sphri --cfg job [overrides]                             print the composed config",
        "  sphri --hydra-help                                      Hydra's own flags",
        "",
        "config groups (group=option; * marks the default; `sphri list GROUP` says what each option is,",
        "`sphri show GROUP=OPTION` every setting of it):",
    ]
    for group in DEFAULT_GROUPS:  # each has its folder in conf/ (tests/test_sphri_cli.py reads them all)
        names = [("*" if defaults.get(group) == name else "") + name for name, _ in components(group)]
        lines.append(_row(f"  {group:<12} ", "  ".join(names)))
    lines += ["", "top-level keys: seed, output_dir, resume, cache.enabled, cache.dir (see README.md)"]
    return "\n".join(lines)


def _mapping(node: Any) -> dict[str, Any]:
    """A config group's node (or its schema's) as a plain dict."""
    from omegaconf import OmegaConf

    return cast(dict[str, Any], OmegaConf.to_container(node, resolve=True))


def _group_words(choices: Sequence[str], help: str) -> Any:
    """Config groups named as bare words (``sphri list robot layout``), each one of ``choices``."""
    return arg([], positional=True, choices=choices, metavar="GROUP", help=help)


@dataclasses.dataclass
class ListArgs:
    groups: list[str] = _group_words(DEFAULT_GROUPS, "config groups to list (default: every group)")


@dataclasses.dataclass
class ShowArgs:
    overrides: list[str] = arg([], rest=True, help="choices and overrides, e.g. encoder=coverage noise.p=0.05")
    group: list[str] = _group_words(
        STAGE_GROUPS,
        "groups to show, as bare words or group=NAME (default: those named in the overrides, else every group)",
    )


@dataclasses.dataclass
class ValidateArgs:
    overrides: list[str] = arg(
        [],
        rest=True,
        help="overrides as for `sphri run`; a sweep (-m, a,b,c, range(), +experiment=...) checks every job",
    )


@dataclasses.dataclass
class WarmupArgs:
    pass


def list_command(args: ListArgs) -> int:
    """The components of each config group (of the groups named), one line each."""
    for group in args.groups or list(DEFAULT_GROUPS):
        print(f"{group}:")
        for name, desc in components(group):
            print(_row(f"  {name:<20} ", desc))
    return 0


def show_command(args: ShowArgs) -> int:
    """Every setting of the chosen components: its value, the default where it differs, its meaning.

    The default and the meaning are the schema's (its field docstring: defaults and docs live there once). The
    groups are those named (a renamed key's old group and its owner: ``encoder.res`` shows encoder and layout)."""
    from omegaconf import OmegaConf

    from sphri.config import field_docs

    overrides = args.overrides
    cfg = compose(overrides, check=False)
    try:
        validate(cfg)
        problem = ""
    except ConfigError as exc:
        problem = str(exc)
    keys = [o.lstrip("+").split("=", 1)[0] for o in overrides if "=" in o]
    named = [k.split(".", 1)[0] for k in [*keys, *(RENAMED_KEYS[k] for k in keys if k in RENAMED_KEYS)]]
    shown = args.group or [g for g in STAGE_GROUPS if g in named] or list(STAGE_GROUPS)
    for group in shown:  # each of STAGE_GROUPS: the parser checks a group named
        node = cfg[group]
        schema = OmegaConf.get_type(node)
        docs = field_docs(schema) if isinstance(schema, type) else {}
        try:
            default = _mapping(OmegaConf.structured(schema)) if dataclasses.is_dataclass(schema) else {}
        except Exception:  # a schema without defaults for every field
            default = {}
        values = _mapping(node)
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


def validate_command(args: ValidateArgs) -> int:
    """Compose the config exactly as `sphri run` would and run every check without running a stage; a sweep
    checks every job. Exits 2 with a line naming the key on any problem.

    A sweep's jobs are composed and validated through ``hydra/sweeper=sphri`` (the code path a real sweep takes),
    running none of them, in a child process: Hydra's app sets up logging and global state."""
    import os
    import subprocess

    from sphri.pipeline import chain_region

    overrides = args.overrides
    if is_sweep(overrides):
        argv = ["-m", *[a for a in overrides if a not in ("-m", "--multirun")], "hydra/launcher=basic"]
        env = {**os.environ, "SPHRI_VALIDATE_ONLY": "1"}
        return subprocess.run([sys.executable, "-m", "sphri", *argv], env=env).returncode
    cfg = compose(overrides)
    chain_region(cfg)
    check_inputs(cfg)
    print("config OK")
    for group in PARAM_GROUPS:
        node = _mapping(cfg[group])
        target = str(node.pop("_target_", "")).rsplit(".", 1)[-1]
        scalars = ", ".join(f"{k}={v}" for k, v in node.items() if not isinstance(v, (dict, list)))
        print(f"  {group:<8} {target}({scalars})")
    return 0


#: Components whose numba kernels the ``+debug=fast`` chain does not reach: a serial sweep over them
#: compiles the spatial encoders', the Gaussian and crosstalk noise's and the Poisson/density layouts'.
WARMUP_SWEEP = ("encoder=coverage,proximity", "noise=gaussian,crosstalk", "layout=random,density")


def warm_analysis_kernels() -> None:
    """Call the scenario study's numba kernels (sliced Wasserstein, placement, winding number) once on
    tiny inputs of the dtypes the study passes, so that they compile into numba's cache."""
    import numpy as np
    import trimesh

    from sphri.analysis.placement import _min_rank_per_frame
    from sphri.analysis.swd import SharedSupportSW, sliced_wasserstein, wasserstein_1d
    from sphri.contact.query import winding_number

    rng = np.random.default_rng(0)
    a, b, w = rng.random((5, 3)), rng.random((6, 3)), rng.random((2, 5)) + 0.1
    sliced_wasserstein(a, b, n_projections=4)
    wasserstein_1d(a[:, 0], b[:, 0])
    SharedSupportSW(a, n_projections=4).distances(w, w[::-1])
    SharedSupportSW(a, n_projections=4, p=2.0).distances(w, w[::-1])
    _min_rank_per_frame(np.arange(5, dtype=np.int64), np.array([0, 3, 1], dtype=np.int64), np.array([0, 2, 3]))
    box = trimesh.creation.box()  # a closed, outward-wound unit cube
    winding_number(box.vertices, box.faces, np.array([[0.0, 0.0, 0.0], [2.0, 2.0, 2.0]]))


def warmup_lanes(tmp: str) -> list[list[list[str]]]:
    """The commands of :func:`warmup_command`, in two lanes that run side by side (each lane's commands one
    after the other, each in a process of its own, like a job): the ``+debug=fast`` chain then the
    study's analysis kernels, and a serial sweep over the components that chain does not use
    (:data:`WARMUP_SWEEP`); tracking off, everything written under ``tmp``."""
    sphri, chain = [sys.executable, "-m", "sphri"], ["+debug=fast", "tracking.enabled=false", f"output_dir={tmp}"]
    return [
        [
            [*sphri, *chain, f"hydra.run.dir={tmp}/run"],
            [sys.executable, "-c", "from sphri.cli import warm_analysis_kernels; warm_analysis_kernels()"],
        ],
        [[*sphri, "-m", *chain, "hydra/launcher=serial", *WARMUP_SWEEP, f"hydra.sweep.dir={tmp}/sweep"]],
    ]


def warmup_command(args: WarmupArgs) -> int:
    """Run the +debug=fast chain once (tracking off, in a temporary folder) so that every numba kernel is
    compiled into numba's cache; later jobs load them (`make install` runs it).

    The commands of :func:`warmup_lanes` run in their two lanes side by side (numba's compiler runs on one core;
    numba writes its cache files whole, so two processes may store the same kernel). Says what it compiled; a
    failed command is one line (the first failure in the lanes' order), exit 1."""
    import subprocess
    import tempfile
    import time
    from concurrent.futures import ThreadPoolExecutor

    from sphri.progress import bar

    print("compiling sphri's numba kernels into numba's cache (once per machine and sphri version)...", flush=True)
    t0 = time.perf_counter()

    with tempfile.TemporaryDirectory(prefix="sphri-warmup-") as tmp:
        lanes = warmup_lanes(tmp)
        shown = bar(sum(len(lane) for lane in lanes), "warmup", unit="command")

        def run_lane(lane: list[list[str]]) -> list[subprocess.CompletedProcess]:
            done = []
            for cmd in lane:
                done.append(subprocess.run(cmd, cwd=tmp, capture_output=True, text=True))
                shown.update(1)
                if done[-1].returncode != 0:
                    break
            return done

        with shown, ThreadPoolExecutor(len(lanes)) as pool:
            runs = [run for lane_runs in pool.map(run_lane, lanes) for run in lane_runs]
    seconds = time.perf_counter() - t0
    for run in runs:
        if run.returncode != 0:
            tail = (run.stderr or run.stdout).strip().splitlines()[-1:] or ["no output"]
            print(f"sphri: warmup failed after {seconds:.0f} s: {tail[0]}", file=sys.stderr)
            return 1
    chain_output = runs[0].stdout + runs[0].stderr
    compiled = [line.split("compiled ", 1)[1] for line in chain_output.splitlines() if "numba kernels in" in line]
    print(
        f"done in {seconds:.1f} s: "
        + (f"compiled {compiled[-1]}" if compiled else "the chain's kernels were already in the cache")
        + "; the other components' and the study's kernels compiled or loaded"
    )
    return 0
