"""HTML pages from the Jinja2 templates in ``sphri/templates/`` (package data: they ship in the wheel).

One environment serves every report (``sweep_report.html.j2``: :mod:`sphri.report.render`;
``scenario_study.html.j2``: :mod:`sphri.sessions.study`). Autoescape is on, so every value a
template prints (scenario names, overrides, notes) is escaped; undefined names are errors, not
blanks. The templates share these filters: ``png_data`` (a PNG file as a ``data:`` URI, so a
page is self-contained), ``num`` (a number in a format spec, an en dash when it is not finite),
and the test ``finite``.
"""

from __future__ import annotations

import base64
import math
from functools import lru_cache
from pathlib import Path

from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape
from markupsafe import Markup, escape


def png_data(path: str | Path) -> str:
    """The PNG at ``path`` as a ``data:image/png;base64,...`` URI."""
    return "data:image/png;base64," + base64.b64encode(Path(path).read_bytes()).decode("ascii")


def _number(x: object) -> float | None:
    try:
        return float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None


def num(x: object, fmt: str = ".3f") -> str:
    """``x`` formatted with ``fmt``; an en dash when not finite; escaped text when not a number."""
    v = _number(x)
    if v is None:
        return escape(x)
    return format(v, fmt) if math.isfinite(v) else Markup("&ndash;")


def finite(x: object) -> bool:
    """Whether ``x`` is a finite number."""
    v = _number(x)
    return v is not None and math.isfinite(v)


@lru_cache(maxsize=1)
def environment() -> Environment:
    env = Environment(
        loader=PackageLoader("sphri", "templates"),
        autoescape=select_autoescape(["html", "html.j2"]),
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.filters.update(png_data=png_data, num=num)
    env.tests["finite"] = finite
    return env


def render_page(template: str, **context: object) -> str:
    """The page ``template`` (a file in ``sphri/templates/``) rendered with ``context``."""
    return environment().get_template(template).render(**context)
