"""Say when sphri's numba kernels compile, and for how long.

sphri's kernels (contact, rasterization, noise, hand kinematics, density)
are compiled by numba on their first call on a machine and then stored in
numba's on-disk cache (``cache=True``), so only the first run pays
(``bench/bench_startup.py`` measures it; docs/BENCHMARKS.md). A run that compiles says so when the first kernel starts,
instead of looking stuck, and reports the total compile time at the end.

Uses numba's own event API (``numba:compile`` fires only on a real compile,
never on a load from the disk cache), so no list of kernels is kept here.
"""

from __future__ import annotations

import logging
import threading
import time

from numba.core import event

log = logging.getLogger("sphri")


class CompileAnnouncer(event.Listener):
    """A numba event listener: announces the first compile of a sphri kernel, times all of them."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.kernels = 0
        self._depth = 0
        self._t0 = 0.0
        self._lock = threading.Lock()

    @staticmethod
    def _ours(event) -> bool:
        dispatcher = (event.data or {}).get("dispatcher")
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        return module == "sphri" or module.startswith("sphri.")

    def on_start(self, event) -> None:
        if not self._ours(event):
            return
        with self._lock:
            if self._depth == 0:
                if self.kernels == 0:
                    log.info(
                        "compiling sphri's numba kernels (first run with this code on this machine; "
                        "later runs load them from numba's cache; `sphri warmup` compiles them all at once)"
                    )
                self._t0 = time.perf_counter()
            self._depth += 1

    def on_end(self, event) -> None:
        if not self._ours(event):
            return
        with self._lock:
            self._depth -= 1
            if self._depth == 0:
                self.seconds += time.perf_counter() - self._t0
                self.kernels += 1


_ANNOUNCER: CompileAnnouncer | None = None


def announce_compiles() -> CompileAnnouncer:
    """Install the process's :class:`CompileAnnouncer` once (later calls return it).

    Import this module only where kernels will run: it imports numba."""
    global _ANNOUNCER
    if _ANNOUNCER is None:
        _ANNOUNCER = CompileAnnouncer()
        event.register("numba:compile", _ANNOUNCER)
    return _ANNOUNCER
