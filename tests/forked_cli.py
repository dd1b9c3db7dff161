"""``python -m sphri ...`` for the tests, in a new process that skips the interpreter's imports.

Each call forks a child from a server process (``multiprocessing``'s forkserver, one per pytest worker)
that imported sphri's heavy dependencies once (MLflow, scikit-learn, SciPy, numba, trimesh, torch,
Hydra: 3.7 s of a fully cached ``python -m sphri +debug=fast`` job by ``python -X importtime``, 2-core
AMD EPYC). The child is a process of its own, as with ``subprocess.run``: its own globals, cwd,
environment, stdout and stderr (files, read back as text), and an exit code from ``runpy`` the way the
interpreter gives one (``SystemExit``'s code, 1 and the traceback on stderr for an exception; threading's
exit hooks and atexit handlers run). The server only imports: no job runs in it, so a fork inherits no
open store or cache. What differs from a fresh interpreter: modules are already imported (a module
that reads the environment at import time reads the server's), and the pytest worker's ``sys.path``
entries stay behind ``cwd`` and ``PYTHONPATH``.

Where the process itself is what a test checks (what gets imported, the interpreter's start-up, a
signal, the installed wheel, the console script, ``-c`` code in a fresh process), the test keeps
``subprocess``. ``SPHRI_TEST_SUBPROCESS=1`` sends every call through ``subprocess.run`` too (to compare).
"""

from __future__ import annotations

import atexit
import multiprocessing
import os
import runpy
import subprocess
import sys
import tempfile
import threading
import traceback
from pathlib import Path

#: What a job, a sweep or a report imports; imported once in the server, before any fork.
PRELOAD = [
    "numpy",
    "scipy.optimize",
    "sklearn.ensemble",
    "numba",
    "trimesh",
    "torch",
    "hydra",
    "omegaconf",
    "mlflow",
    "mlflow.tracking",
    "mlflow.store.tracking.sqlalchemy_store",
    "sphri.config",
    "sphri.pipeline",
    "sphri.__main__",
]

_CONTEXT: multiprocessing.context.BaseContext | None = None


def _context() -> multiprocessing.context.BaseContext:
    global _CONTEXT
    if _CONTEXT is None:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(PRELOAD)
        _CONTEXT = ctx
    return _CONTEXT


def _exit_code(exc: SystemExit) -> int:
    """The interpreter's exit status for ``SystemExit(code)``: None is 0, an int itself, anything else
    printed to stderr and 1."""
    if exc.code is None:
        return 0
    if isinstance(exc.code, int):
        return exc.code
    print(exc.code, file=sys.stderr)
    return 1


def _child(module: str, args: list[str], cwd: str, env: dict[str, str], out: str, err: str) -> None:
    """Runs in the forked child: ``python -m module *args`` in ``cwd`` with ``env``, output into files."""
    os.chdir(cwd)
    os.environ.clear()
    os.environ.update(env)
    extra = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    sys.path[:0] = [cwd, *(str(Path(cwd, p)) for p in extra)]  # what `python -m` adds at start-up
    for fd, path in ((1, out), (2, err)):
        target = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(target, fd)
        os.close(target)
    sys.stdout = open(1, "w", encoding="utf-8", errors="backslashreplace", closefd=False)  # noqa: SIM115
    sys.stderr = open(2, "w", encoding="utf-8", errors="backslashreplace", closefd=False)  # noqa: SIM115
    if env.get("PYTHONUNBUFFERED"):
        sys.stdout.reconfigure(line_buffering=True)
        sys.stderr.reconfigure(line_buffering=True)
    sys.argv = [module, *args]
    sys.modules.pop(f"{module}.__main__", None)  # preloaded for its imports; run afresh, as `python -m` does
    code = 0
    try:
        runpy.run_module(module, run_name="__main__", alter_sys=True)
    except SystemExit as exc:
        code = _exit_code(exc)
    except BaseException:  # noqa: BLE001 - the interpreter prints any uncaught exception and exits 1
        traceback.print_exc()
        code = 1
    try:  # the interpreter's own exit: non-daemon threads joined (threading's exit hooks), then atexit
        threading._shutdown()  # type: ignore[attr-defined]
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001
                pass
        os._exit(code)


class Started:
    """A forked ``python -m`` started and not yet waited for (``start``): ``wait`` gives its result."""

    def __init__(self, args: list[str], cwd: Path | str, env: dict[str, str] | None) -> None:
        self.args = [sys.executable, *args]
        self._tmp = tempfile.TemporaryDirectory(prefix="sphri-forked-")
        self._out, self._err = os.path.join(self._tmp.name, "stdout"), os.path.join(self._tmp.name, "stderr")
        env = dict(os.environ if env is None else env)
        self._proc = _context().Process(
            target=_child, args=(args[1], list(args[2:]), str(cwd), env, self._out, self._err)
        )
        self._proc.start()

    def wait(self, timeout: float = 600) -> subprocess.CompletedProcess:
        """Its exit code (negative: the signal that killed it, as subprocess gives it), stdout and stderr;
        past ``timeout`` seconds it is killed and TimeoutExpired raised."""
        try:
            self._proc.join(timeout)
            if self._proc.exitcode is None:
                self._proc.kill()
                self._proc.join()
                raise subprocess.TimeoutExpired(self.args, timeout)
            read = lambda p: Path(p).read_text(encoding="utf-8", errors="backslashreplace")  # noqa: E731
            return subprocess.CompletedProcess(self.args, self._proc.exitcode, read(self._out), read(self._err))
        finally:
            self._tmp.cleanup()


class _FreshStarted:
    """``start`` under ``SPHRI_TEST_SUBPROCESS=1``: a fresh interpreter, with ``Started``'s ``wait``."""

    def __init__(self, args: list[str], cwd: Path | str, env: dict[str, str] | None) -> None:
        self.args = [sys.executable, *args]
        self._proc = subprocess.Popen(
            self.args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )

    def wait(self, timeout: float = 600) -> subprocess.CompletedProcess:
        try:
            out, err = self._proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.communicate()
            raise
        return subprocess.CompletedProcess(self.args, self._proc.returncode, out, err)


def start(args: list[str], cwd: Path | str, env: dict[str, str] | None = None) -> Started | _FreshStarted:
    """``python <args>`` (``-m <module> ...``) forked and left running: several at once run concurrently."""
    if len(args) < 2 or args[0] != "-m":
        raise ValueError(f"forked_cli.start runs `-m <module>` only, not {args[:2]}")
    if os.environ.get("SPHRI_TEST_SUBPROCESS") == "1":
        return _FreshStarted(args, cwd, env)
    return Started(args, cwd, env)


def run(
    args: list[str], cwd: Path | str, env: dict[str, str] | None = None, timeout: float = 600
) -> subprocess.CompletedProcess:
    """``python <args>`` (``args`` starting ``-m <module>``) in ``cwd``, output captured as text, as
    ``subprocess.run([sys.executable, *args], capture_output=True, text=True)`` returns it."""
    if len(args) < 2 or args[0] != "-m":  # `-c` code and scripts: a fresh interpreter
        return subprocess.run(
            [sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
        )
    return start(args, cwd, env).wait(timeout)


def one_line(proc: subprocess.CompletedProcess, code: int, *words: str) -> str:
    """The one stderr line of a refused command: exit ``code``, no traceback, holding every word."""
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == code, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and len(err) == 1, proc.stderr[-2000:]
    assert all(w in err[0] for w in words), err[0]
    return err[0]
