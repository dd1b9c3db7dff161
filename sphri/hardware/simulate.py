"""``sphri simulate skin|glove``: emulate a device on a pseudo-terminal or socket.

::

    sphri simulate skin +debug=fast trials=8 corrupt_rate=0.05
    sphri simulate skin source=pattern grid=18x6 port=socket://127.0.0.1:7777
    sphri simulate glove ack_drop_rate=0.1

The command line only: the skin simulator is :mod:`sphri.hardware.sim_skin`, the glove simulator
:mod:`sphri.hardware.sim_glove`, their endpoints :mod:`sphri.hardware.transport`. ``port=pty``
makes a pseudo-terminal; its path is printed (and symlinked at ``link=`` if given, re-pointed after a
replug, like a udev name). ``port=socket://HOST:PORT`` listens there (port 0 = any free port).
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

from sphri.args import settings_main
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


#: The simulated devices and their settings (``simulate skin`` also takes config overrides).
COMMANDS = {"skin": (SkinSimSettings, True), "glove": (GloveSimSettings, False)}


@settings_main("sphri simulate", COMMANDS)
def main(device: str, settings: SkinSimSettings | GloveSimSettings, overrides: list[str]) -> int:
    """``sphri simulate skin|glove key=value ...``."""
    sim: SkinSimulator | GloveSimulator
    if isinstance(settings, SkinSimSettings):  # read_settings builds COMMANDS[device]'s class: skin's only here
        sim = skin_simulator(settings, overrides)
    else:
        sim = GloveSimulator(settings, make_endpoint(settings), verbose=True)

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
