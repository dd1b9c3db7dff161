"""Reading a hand-tracking log (CSV or JSON lines) into a typed table, refusing what is malformed.

Every refusal is one :class:`LogError` line naming the file, the line and the field. The table's
columns are those of a log spec of :mod:`sphri.data.recording_schema` (``OPENXR_LOG``,
``OVR_CAPSULE_LOG``, ``CAPSULE_LOG``); ``line`` holds each row's line number in the file.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from sphri.data.recording_schema import Column


class LogError(ValueError):
    """A hand-tracking log ``sphri import`` cannot take; the message names the file, line and field."""


def _spec(columns: Sequence[Column]) -> dict[str, str]:
    """{column name: dtype} of a log spec (``px, py, pz`` is three float columns)."""
    return {n.strip(): c.dtype for c in columns for n in c.name.split(",")}


def _lines(path: Path) -> tuple[list[str], bool]:
    """The file's lines (a byte-order mark dropped) and whether its last line ends with a newline."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise LogError(f"{path}: not a text file ({exc})") from None
    if not text.strip():
        raise LogError(f"{path}: empty file (no rows)")
    lines = text.split("\n")
    ends = text.endswith("\n")
    if ends:
        lines.pop()
    return lines, ends


def _truncated(path: Path, lineno: int, n_lines: int, text_ends_line: bool, what: str) -> LogError:
    if lineno == n_lines and not text_ends_line:
        return LogError(f"{path}: line {lineno}: truncated file: the last line stops mid-row ({what})")
    return LogError(f"{path}: line {lineno}: {what}")


def _read_csv(path: Path, names: Sequence[str], optional: Sequence[str]) -> tuple[dict[str, list], list[int]]:
    lines, ends = _lines(path)
    header = [h.strip() for h in next(csv.reader([lines[0]]))]
    missing = [n for n in names if n not in header and n not in optional]
    if missing:
        raise LogError(f"{path}: line 1: missing column(s) {missing} (the header has {header})")
    where = {n: header.index(n) for n in names if n in header}
    raw: dict[str, list] = {n: [] for n in where}
    linenos: list[int] = []
    for i, row in enumerate(csv.reader(lines[1:]), 2):
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(header):
            raise _truncated(path, i, len(lines), ends, f"{len(row)} fields, the header has {len(header)}")
        for n, j in where.items():
            raw[n].append(row[j].strip())
        linenos.append(i)
    if not linenos:
        raise LogError(f"{path}: empty file (a header, no rows)")
    return raw, linenos


def _read_jsonl(path: Path, names: Sequence[str], optional: Sequence[str]) -> tuple[dict[str, list], list[int]]:
    lines, ends = _lines(path)
    raw: dict[str, list] = {n: [] for n in names}
    linenos: list[int] = []
    for i, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except json.JSONDecodeError as exc:
            raise _truncated(path, i, len(lines), ends, f"not valid JSON ({exc.msg})") from None
        except RecursionError:
            raise LogError(f"{path}: line {i}: nested too deeply for the JSON reader") from None
        if not isinstance(rec, dict):
            raise LogError(f"{path}: line {i}: expected a JSON object, got {type(rec).__name__}")
        for key, parts in (("position", ("px", "py", "pz")), ("orientation", ("qx", "qy", "qz", "qw"))):
            if key in rec and parts[0] in names:
                v = rec.pop(key)
                if not isinstance(v, list) or len(v) != len(parts):
                    raise LogError(f"{path}: line {i}: field {key}={v!r} must be a list of {len(parts)} numbers")
                rec.update(zip(parts, v))
        for n in names:
            if n not in rec:
                if n in optional and not linenos:  # an optional field: the first row says whether the log has it
                    raw.pop(n, None)
                if n in raw:
                    raise LogError(f"{path}: line {i}: missing field {n!r}")
            elif n in raw:
                raw[n].append(rec[n])
        linenos.append(i)
    if not linenos:
        raise LogError(f"{path}: empty file (no rows)")
    return raw, linenos


def _number(v: object, text: bool) -> float | None:
    """The value as a float, or None when it is not a number (a JSON null or a CSV empty field is NaN); a
    string is read as a number only where the file is ``text`` (CSV), not in JSON."""
    if v is None or v == "":
        return math.nan
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str) and text:
        try:
            return float(v)
        except ValueError:
            return None
    return None


def read_log(path: str | Path, columns: Sequence[Column], optional: Sequence[str] = ()) -> pd.DataFrame:
    """The log at ``path`` (``.jsonl``/``.json``: JSON lines, anything else: CSV with a header) as a table with
    the spec's columns (floats float64, integers int64, text str) plus ``line``.

    Refuses (:class:`LogError`, naming the line and field): an empty file, a truncated last line, a missing
    column, a value of the wrong type, and a NaN or infinite number."""
    path = Path(path)
    if not path.is_file():
        raise LogError(f"{path}: no such log file")
    spec = _spec(columns)
    names = list(spec)
    reader = _read_jsonl if path.suffix.lower() in (".jsonl", ".json", ".ndjson") else _read_csv
    raw, linenos = reader(path, names, optional)
    lines = np.asarray(linenos, dtype=np.int64)
    out: dict[str, np.ndarray] = {}
    for n, values in raw.items():
        dtype = spec[n]
        if dtype == "string":
            bad = [i for i, v in enumerate(values) if not isinstance(v, (str, int)) or isinstance(v, bool) or v == ""]
            if bad:
                i = bad[0]
                raise LogError(f"{path}: line {lines[i]}: field {n}={values[i]!r} must be a name")
            out[n] = np.asarray([str(v) for v in values], dtype=object)
            continue
        nums = [_number(v, reader is _read_csv) for v in values]
        bad = [i for i, v in enumerate(nums) if v is None]
        if bad:
            i = bad[0]
            what = "an integer" if dtype == "integer" else "a number"
            raise LogError(
                f"{path}: line {lines[i]}: field {n}={values[i]!r} is not {what} "
                f"(wrong column type; {len(bad)} such value(s))"
            )
        arr = np.asarray(nums, dtype=np.float64)
        nan = ~np.isfinite(arr)
        if nan.any():
            i = int(np.flatnonzero(nan)[0])
            raise LogError(
                f"{path}: line {lines[i]}: field {n} is {values[i]!r}: NaN or infinite values are not poses "
                f"({int(nan.sum())} such value(s) in column {n})"
            )
        if dtype == "integer":
            frac = arr != np.round(arr)
            if frac.any():
                i = int(np.flatnonzero(frac)[0])
                raise LogError(f"{path}: line {lines[i]}: field {n}={values[i]!r} is not an integer")
            out[n] = arr.astype(np.int64)
        else:
            out[n] = arr
    df = pd.DataFrame(out)
    df["line"] = lines
    return df
