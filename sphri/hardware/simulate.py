"""``python -m sphri.hardware.simulate skin|glove``: emulate a device on a pseudo-terminal or socket.

::

    python -m sphri.hardware.simulate skin +debug=fast trials=8 corrupt_rate=0.05
    python -m sphri.hardware.simulate skin source=pattern grid=18x6 port=socket://127.0.0.1:7777
    python -m sphri.hardware.simulate glove ack_drop_rate=0.1

The command line only: the skin simulator is :mod:`sphri.hardware.sim_skin`, the glove simulator
:mod:`sphri.hardware.sim_glove`, their endpoints :mod:`sphri.hardware.transport`. ``port=pty``
makes a pseudo-terminal; its path is printed (and symlinked at ``link=`` if given, re-pointed after a
replug, like a udev name). ``port=socket://HOST:PORT`` listens there (port 0 = any free port).
"""

from __future__ import annotations

import json
import logging
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

from sphri.config import ConfigError
from sphri.errors import clean_errors
from sphri.hardware.sim_glove import GloveLedger, GloveSimSettings, GloveSimulator
from sphri.hardware.sim_skin import (
    SkinLedger,
    SkinSimSettings,
    SkinSimulator,
    pattern_stream,
    pipeline_stream,
    skin_simulator,
)
from sphri.hardware.transport import PtyEndpoint, SocketEndpoint, make_endpoint, start_in_thread
from sphri.keyvalue import parse_cli

#: Names importable from here before the split (kept for earlier scripts).
__all__ = [
    "GloveLedger",
    "GloveSimSettings",
    "GloveSimulator",
    "PtyEndpoint",
    "SkinLedger",
    "SkinSimSettings",
    "SkinSimulator",
    "SocketEndpoint",
    "main",
    "make_endpoint",
    "pattern_stream",
    "pipeline_stream",
    "start_in_thread",
]

USAGE = """usage: python -m sphri.hardware.simulate skin|glove [key=value ...] [pipeline overrides ...]

skin:  streams frames (skin protocol) of encoded synthetic trials (source=pipeline, with the
       pipeline overrides, e.g. +debug=fast) or moving blobs (source=pattern grid=18x6)
       trials=8 participant=... rate_hz=0 realtime=true format=auto|u8|u16|bits gap_s=0.5
       faults: garbage_rate corrupt_rate drop_rate truncate_rate wrong_count_rate (per frame)
       unplug_after_s=0 unplug_s=1 wait_start=true hold_s=1
glove: acknowledges ACTUATE messages; ack_drop_rate=0 ack_delay_s=0 duration_s=0
both:  port=pty|socket://HOST:PORT link=/tmp/skin.tty seed=0 report=ledger.json
(defaults and meanings: SkinSimSettings in sphri/hardware/sim_skin.py, GloveSimSettings in sim_glove.py)
"""


@clean_errors("sphri.hardware.simulate")
def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE)
        return 0 if argv else 2
    device, args = argv[0], argv[1:]
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if device not in ("skin", "glove"):
        print(f"sphri.hardware.simulate: unknown device {device!r} (skin or glove)\n\n{USAGE}", file=sys.stderr)
        return 2
    try:
        if device == "skin":
            settings, overrides = parse_cli(args, SkinSimSettings, pipeline=True)
            sim: SkinSimulator | GloveSimulator = skin_simulator(settings, overrides)
        else:
            settings, _ = parse_cli(args, GloveSimSettings, pipeline=False)
            sim = GloveSimulator(settings, make_endpoint(settings), verbose=True)
    except ConfigError as exc:
        print(f"sphri.hardware.simulate: invalid setting: {exc}", file=sys.stderr)
        return 2

    def announce() -> None:
        sim.ready.wait()
        endpoint = sim.endpoint
        extra = f" (pseudo-terminal {endpoint.name})" if isinstance(endpoint, PtyEndpoint) and endpoint.link else ""
        print(f"{device} simulator ready on {endpoint.url}{extra}", flush=True)

    threading.Thread(target=announce, daemon=True).start()
    try:
        ledger = sim.run()
    except KeyboardInterrupt:
        sim.stop.set()
        ledger = sim.ledger
    if settings.report:
        Path(settings.report).parent.mkdir(parents=True, exist_ok=True)
        Path(settings.report).write_text(json.dumps(ledger.to_json(), indent=1))
    summary = {k: v for k, v in ledger.to_json().items() if isinstance(v, (int, float)) and v}
    print(
        f"{device} simulator finished: "
        + ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in summary.items()),
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
