"""The ``key=value`` command line of the commands beside the pipeline (hardware, simulators, model export).

Keys that are fields of a settings dataclass set them (typed by OmegaConf, range-checked by the
dataclass's ``__post_init__``); everything else (``+debug=fast``, ``robot=nao_child``, ``data.seed=3``)
is returned as pipeline overrides for :func:`sphri.config.compose`, or refused.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, TypeVar

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from sphri.config import ConfigError

T = TypeVar("T")


def field_names(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def parse_cli(argv: Sequence[str], cls: type[T], pipeline: bool) -> tuple[T, list[str]]:
    """Split ``key=value`` arguments into ``cls`` settings and pipeline overrides.

    Keys that are fields of ``cls`` set them (typed and range-checked); the
    rest are returned as pipeline overrides when ``pipeline`` is true, and
    refused otherwise. Raises :class:`ConfigError` naming the key.
    """
    names = field_names(cls)
    mine: list[str] = []
    rest: list[str] = []
    for arg in argv:
        if "=" not in arg:
            raise ConfigError(f"argument {arg!r} is invalid: expected key=value (settings: {', '.join(names)})")
        key = arg.split("=", 1)[0]
        (mine if key in names else rest).append(arg)
    if rest and not pipeline:
        raise ConfigError(
            f"unknown setting(s) {', '.join(a.split('=', 1)[0] for a in rest)}; settings: {', '.join(names)}"
        )
    try:
        node = OmegaConf.merge(OmegaConf.structured(cls), OmegaConf.from_dotlist(mine))
        settings = OmegaConf.to_object(node)
    except ConfigError:
        raise
    except OmegaConfBaseException as exc:
        key = getattr(exc, "full_key", None) or "?"
        first = str(exc).strip().splitlines()[0]
        raise ConfigError(f"{key}: {first}") from None
    return settings, rest  # type: ignore[return-value]


def describe(settings: Any) -> str:
    """``key=value`` of every setting (for logs)."""
    return " ".join(f"{f.name}={getattr(settings, f.name)}" for f in dataclasses.fields(settings))
