"""A harness time limit for tests (SIGALRM), not a speed assertion: a call that blocks fails its test
instead of hanging the suite. Main thread only (signals)."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator


@contextlib.contextmanager
def time_limit(seconds: int, what: str, error: type[BaseException] = TimeoutError) -> Iterator[None]:
    """Raise ``error`` naming ``what`` if the block runs longer than ``seconds``."""

    def fire(signum, frame):
        raise error(f"{what}: did not return within {seconds} s")

    previous = signal.signal(signal.SIGALRM, fire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
