"""``python -m sphri.cli``: list components and validate configs without running.

::

    python -m sphri.cli list                 # every group and its components
    python -m sphri.cli list robot           # one group, with each file's summary
    python -m sphri.cli validate +robot=reachy encoder.res=18

``validate`` composes the config exactly as ``python -m sphri`` would, runs
every schema's checks, and prints the chosen components; it exits 2 with a
message naming the key on any problem.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from sphri.config import CONF_DIR, DEFAULT_GROUPS, ConfigError, compose
from sphri.errors import clean_errors

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
    """The file's first comment line, else its ``_target_``."""
    text = path.read_text()
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#") and not s.startswith("# @package"):
            return s.lstrip("# ").strip()
        if s and not s.startswith("#"):
            break
    try:
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as exc:
        return f"(unreadable: {exc})"
    return str(data.get("_target_", "")) if isinstance(data, dict) else ""


def cmd_list(groups: list[str]) -> int:
    for group in groups or list(DEFAULT_GROUPS):
        print(f"{group}:")
        for name, desc in components(group):
            print(f"  {name:<20} {desc}")
    return 0


def cmd_validate(overrides: list[str]) -> int:
    from omegaconf import OmegaConf

    from sphri.pipeline import chain_region

    cfg = compose(overrides)
    chain_region(cfg)
    print("config OK")
    for group in ("data", "robot", "contact", "surface", "layout", "encoder", "noise", "window", "model", "cv"):
        node = OmegaConf.to_container(cfg[group], resolve=True)
        target = str(node.pop("_target_", "")).rsplit(".", 1)[-1]
        scalars = ", ".join(f"{k}={v}" for k, v in node.items() if not isinstance(v, (dict, list)))
        print(f"  {group:<8} {target}({scalars})")
    return 0


@clean_errors("sphri")
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sphri.cli", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    p_list = sub.add_parser("list", help="list the components of each config group")
    p_list.add_argument("groups", nargs="*", help="groups to list (default: all)")
    p_val = sub.add_parser("validate", help="compose and check a config without running it")
    p_val.add_argument("overrides", nargs="*", help="overrides as for python -m sphri")
    args = parser.parse_args(argv)
    try:
        if args.cmd == "list":
            return cmd_list(args.groups)
        return cmd_validate(args.overrides)
    except ConfigError as exc:
        print(f"sphri: invalid config: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
