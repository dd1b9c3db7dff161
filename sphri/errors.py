"""One clean line for expected errors, in every entry point.

An *expected* error is a problem with the user's input or machine, not a bug
in sphri: an invalid config, a bad data file, a broken mesh, an unwritable
cache, a serial port that vanished, a model or recording file that does not
decode, a file the system refuses. Every entry point prints it as one line
``<prog>: <kind>: <message>`` (the message names the key, file or port) and
exits with 2 (:data:`EXIT_2`: a config, or a log ``sphri import`` refuses) or 1
(anything else). The traceback is shown only with
``--verbose`` on the command line or ``HYDRA_FULL_ERROR=1`` in the
environment. Anything else (a bug) keeps its full traceback.
"""

from __future__ import annotations

import functools
import json
import os
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

#: Command-line flag that shows tracebacks (removed from argv before parsing).
VERBOSE_FLAG = "--verbose"


#: (module, class, kind shown to the user), most specific first.
EXPECTED: tuple[tuple[str, str, str], ...] = (
    ("sphri.config", "ConfigError", "invalid config"),
    ("sphri.types", "UnknownRegion", "invalid config"),
    ("sphri.data.vr_gesture", "DatasetError", "data error"),
    ("sphri.data.format", "ManifestError", "data error"),
    ("sphri.sessions.format", "SessionFormatError", "data error"),
    ("sphri.sessions.synthetic", "PriorsError", "data error"),
    ("sphri.evaluate.cv", "CVError", "data error"),
    ("sphri.window.onset", "WindowMemoryError", "memory error"),
    ("sphri.contact.stage", "ContactMemoryError", "memory error"),
    ("sphri.hand.capsules", "HandDefinitionError", "hand error"),
    ("sphri.robots.urdf_tree", "RobotFileError", "robot file error"),
    ("sphri.robots.validate", "MeshError", "mesh error"),
    ("sphri.layout.common", "LayoutFileError", "layout file error"),
    ("sphri.cache", "CorruptEntry", "cache error"),
    ("sphri.hardware.transport", "PortError", "port error"),
    ("sphri.hardware.skin", "StreamMismatch", "port error"),
    ("sphri.export.model_file", "ModelFileError", "model file error"),
    ("sphri.hardware.recording", "RecordingError", "recording error"),
    ("sphri.recordings.logs", "LogError", "log error"),
    ("sphri.report.sweep", "ReportError", "report error"),
    ("sphri.tracking.store", "StoreError", "store error"),
    ("sphri.finite", "NonFiniteError", "numerical error"),
    ("builtins", "OSError", "file error"),
)


#: Kinds that exit with 2 (the input was refused as given); the others exit with 1.
EXIT_2: tuple[str, ...] = ("invalid config", "log error")


def expected_errors() -> list[tuple[type[BaseException], str]]:
    """(exception type, kind) of :data:`EXPECTED` that exist in this sphri (imported lazily)."""
    import importlib

    out = []
    for module, name, kind in EXPECTED:
        try:
            typ = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError):  # a class renamed or not there: nothing to match
            continue
        out.append((typ, kind))
    return out


def kind_of(exc: BaseException) -> str | None:
    """The user-facing kind of an expected error, or None for anything else (a bug)."""
    for typ, kind in expected_errors():
        if isinstance(exc, typ):
            return kind
    return None


def verbose_requested() -> bool:
    return os.environ.get("HYDRA_FULL_ERROR", "") == "1"


def take_verbose_flag(argv: list[str]) -> list[str]:
    """Remove ``--verbose`` from ``argv``; when present, set ``HYDRA_FULL_ERROR=1`` (shown tracebacks)."""
    if VERBOSE_FLAG in argv:
        os.environ["HYDRA_FULL_ERROR"] = "1"
        argv = [a for a in argv if a != VERBOSE_FLAG]
    return argv


def one_line(prog: str, exc: BaseException, kind: str) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if kind == "file error" and isinstance(exc, OSError) and exc.filename and str(exc.filename) not in text:
        text = f"{exc.filename}: {text}"
    return f"{prog}: {kind}: {text}"


def report(prog: str, exc: BaseException) -> int | None:
    """Print ``exc`` as one line (traceback first when verbose); its exit code, or None if not expected."""
    kind = kind_of(exc)
    if kind is None:
        return None
    if verbose_requested():
        traceback.print_exception(exc)
    print(one_line(prog, exc, kind), file=sys.stderr)
    return 2 if kind in EXIT_2 else 1


def clean_errors(prog: str) -> Callable:
    """Decorate an entry point ``main(argv=None) -> int``: ``--verbose`` handling and one-line errors,
    prefixed ``prog``, or the ``prog=`` the entry point is called with (``sphri export`` when
    :func:`sphri.command.call` dispatches the verb), as its usage errors are."""

    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def run(argv: Sequence[str] | None = None, *args: Any, **kwargs: Any) -> int:
            argv = take_verbose_flag(list(sys.argv[1:] if argv is None else argv))
            name = kwargs.get("prog") or prog
            try:
                return main(argv, *args, **kwargs)
            except KeyboardInterrupt:
                print(f"{name}: interrupted", file=sys.stderr)
                return 130
            except BrokenPipeError:  # the reader went away (`| head`): stop quietly, as Python's docs advise
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
                return 1
            except Exception as exc:
                code = report(name, exc)
                if code is None:
                    raise
                return code

        return run

    return wrap


def read_json(
    path: Path, error: type[Exception], not_found: str, missing: type[Exception] = FileNotFoundError, obj: bool = False
) -> Any:
    """The parsed JSON of the file ``path``, for every reader of an input file: ``missing(not_found)``
    when there is no such file, one line ``error("<path>: not valid JSON (...)")`` when it does not
    parse or is nested too deeply to read (a RecursionError) and, with ``obj``, ``error("<path>: expected a JSON object, got <type>")`` when it is not one."""
    if not path.is_file():
        raise missing(not_found)
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{path}: not valid JSON ({exc})") from None
    except RecursionError:
        raise error(f"{path}: not a usable JSON file (nested too deeply for the reader)") from None
    if obj and not isinstance(data, dict):
        raise error(f"{path}: expected a JSON object, got {type(data).__name__}")
    return data
