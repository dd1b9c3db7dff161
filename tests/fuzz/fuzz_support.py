"""Shared machinery of the fuzz campaign (issue 29, item 5): sizes, verdicts, counts.

Every case ends in one verdict:

- ``named error``: an expected sphri error (``sphri.errors.EXPECTED``), printed as one line;
- ``documented warning``: accepted with a warning (a logged WARNING or a counted repair);
- ``accepted unchanged``: accepted, and the result is the reference's;
- ``traceback``: any other exception (a bug: the test fails and hypothesis shrinks it);
- ``silent change``: accepted without a warning, and the result differs (a bug);
- ``lost frames``: a complete, intact frame of a serial stream not decoded (a bug).

Sizes: ``make test`` runs the small size; ``SPHRI_DEEP_TESTS=1`` (``make test-all``) the large one.
Both are seeded (``derandomize=True``): a run's cases and counts repeat exactly.
``SPHRI_FUZZ_COUNTS=DIR`` writes each target's counts to ``DIR/<target>.json``
(``docs/RELIABILITY.md`` shows them from a large run).
"""

from __future__ import annotations

import collections
import json
import logging
import os
from pathlib import Path

from hypothesis import HealthCheck, settings

from sphri.errors import kind_of, one_line

DEEP = bool(os.environ.get("SPHRI_DEEP_TESTS"))

NAMED = "named error"
WARNED = "documented warning"
UNCHANGED = "accepted unchanged"
TRACEBACK = "traceback"
SILENT = "silent change"
LOST = "lost frames"
VERDICTS = (NAMED, WARNED, UNCHANGED, TRACEBACK, SILENT, LOST)


def fuzz_settings(small: int, large: int) -> settings:
    """Seeded hypothesis settings: ``small`` cases in ``make test``, ``large`` under SPHRI_DEEP_TESTS=1."""
    return settings(
        max_examples=large if DEEP else small,
        derandomize=True,
        database=None,
        deadline=None,
        print_blob=True,
        suppress_health_check=[
            HealthCheck.too_slow,
            HealthCheck.function_scoped_fixture,
            HealthCheck.data_too_large,
            HealthCheck.filter_too_much,
        ],
    )


class Tally:
    """Counts of one target's verdicts (and of its mutation kinds), written at the end of the test."""

    def __init__(self, target: str) -> None:
        self.target = target
        self.verdicts: collections.Counter[str] = collections.Counter()
        self.kinds: collections.Counter[str] = collections.Counter()

    def add(self, kind: str, verdict: str) -> None:
        self.kinds[kind] += 1
        self.verdicts[verdict] += 1

    @property
    def cases(self) -> int:
        return sum(self.verdicts.values())

    def named(self, kind: str, exc: BaseException) -> str:
        """:func:`named_or_raise` of ``exc``, counting a ``traceback`` of ``kind`` before re-raising it."""
        try:
            return named_or_raise(exc)
        except Exception:
            self.add(kind, "traceback")
            raise

    def write(self) -> None:
        out = os.environ.get("SPHRI_FUZZ_COUNTS")
        if not out:
            return
        Path(out).mkdir(parents=True, exist_ok=True)
        doc = {
            "target": self.target,
            "size": "large" if DEEP else "small",
            "cases": self.cases,
            "verdicts": {**{v: self.verdicts.get(v, 0) for v in VERDICTS}, **self.verdicts},
            "kinds": dict(sorted(self.kinds.items())),
        }
        (Path(out) / f"{self.target}.json").write_text(json.dumps(doc, indent=1) + "\n")


def named_or_raise(exc: BaseException) -> str:
    """``NAMED`` for an expected sphri error whose message is one line; re-raises anything else (a traceback)."""
    kind = kind_of(exc)
    if kind is None:
        raise exc
    line = one_line("sphri", exc, kind)
    assert "\n" not in line and len(line) > len(f"sphri: {kind}: ") + 5, line
    return NAMED


class WarningCatcher(logging.Handler):
    """Collects WARNING (and above) records of the ``sphri`` loggers while installed."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)

    def __enter__(self) -> WarningCatcher:
        self.logger = logging.getLogger("sphri")
        self.old_level = self.logger.level
        self.logger.addHandler(self)
        if self.logger.getEffectiveLevel() > logging.WARNING:
            self.logger.setLevel(logging.WARNING)
        return self

    def __exit__(self, *exc) -> None:
        self.logger.removeHandler(self)
        self.logger.setLevel(self.old_level)


# ------------------------------------------------------------------ byte and JSON mutations
from hypothesis import strategies as st  # noqa: E402

#: JSON values of the wrong type or range: what a crafted or damaged field holds.
JSON_JUNK = st.one_of(
    st.none(),
    st.booleans(),
    st.sampled_from(
        [-1, 0, 1, 2**63, -(2**63) - 1, 1e308, -1e-9, float("nan"), float("inf"), "", "nan", "__nd__", "a0", "__META__"]
    ),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.lists(st.integers(-3, 3), max_size=3),
    st.dictionaries(st.sampled_from(["__nd__", "__tuple__", "c", "f", "x"]), st.integers(-1, 3), max_size=2),
)


def json_paths(doc, prefix=()):
    """Every (path) to a node of a JSON document (dict keys and list indices)."""
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from json_paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from json_paths(v, prefix + (i,))


def mutate_json(doc, data) -> str:
    """Replace, delete or duplicate one node of ``doc`` (in place); returns what was done."""
    paths = [p for p in json_paths(doc) if p]
    path = data.draw(st.sampled_from(paths), label="path")
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    what = data.draw(st.sampled_from(["replace", "delete", "wrap"]), label="edit")
    if what == "delete":
        del parent[path[-1]]
    elif what == "wrap":
        parent[path[-1]] = [parent[path[-1]]]
    else:
        parent[path[-1]] = data.draw(JSON_JUNK, label="value")
    return f"{what} {'.'.join(map(str, path))}"


def mutate_bytes(blob: bytes, data, header: bytes = b"") -> tuple[str, bytes]:
    """One raw corruption of ``blob``: ``(kind, new bytes)``. ``header``: another file's first bytes (swap)."""
    kind = data.draw(
        st.sampled_from(
            ["flip byte", "truncate", "append bytes", "insert bytes", "zero range", "swap header", "empty file"]
        ),
        label="corruption",
    )
    b = bytearray(blob)
    if kind == "flip byte":
        for _ in range(data.draw(st.integers(1, 4), label="flips")):
            b[data.draw(st.integers(0, len(b) - 1), label="offset")] ^= data.draw(st.integers(1, 255), label="xor")
    elif kind == "truncate":
        b = b[: data.draw(st.integers(0, len(b) - 1), label="keep")]
    elif kind == "append bytes":
        b += data.draw(st.binary(min_size=1, max_size=64), label="tail")
    elif kind == "insert bytes":
        i = data.draw(st.integers(0, len(b)), label="at")
        b[i:i] = data.draw(st.binary(min_size=1, max_size=16), label="bytes")
    elif kind == "zero range":
        i = data.draw(st.integers(0, len(b) - 1), label="at")
        j = min(len(b), i + data.draw(st.integers(1, 256), label="length"))
        b[i:j] = bytes(j - i)
    elif kind == "swap header":
        n = data.draw(st.integers(1, len(header)), label="header bytes")
        b[:n] = header[:n]
    else:
        b = bytearray()
    return kind, bytes(b)
