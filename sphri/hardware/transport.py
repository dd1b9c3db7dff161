"""Serial transport (pyserial): open a port or URL, read, write, reconnect.

Everything protocol-specific lives in the pure decoders; this module only
moves bytes. Any pyserial URL works: ``/dev/ttyUSB0``, ``/dev/rfcomm0``
(Bluetooth serial), ``loop://`` (loopback, for dry runs),
``socket://host:port`` (a simulator or a network bridge).

A port that vanishes (unplugged device, closed socket) raises
:class:`PortLost` with a message naming the port; :class:`Link` with
``reconnect=True`` instead retries opening it until ``reconnect_timeout_s``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import serial

log = logging.getLogger(__name__)


class PortError(RuntimeError):
    """A serial port could not be opened; the message names it and suggests a fix."""


class PortLost(PortError):
    """An open serial port vanished (device unplugged, socket closed)."""


def is_loopback(port: str) -> bool:
    """True for pyserial's ``loop://`` (a dry run: what is written is read back)."""
    return port.startswith("loop://")


def open_port(port: str, baud: int = 115200, timeout_s: float = 0.05) -> serial.SerialBase:
    """Open ``port`` (a device path or pyserial URL) at ``baud`` bits/s.

    ``timeout_s`` is the read timeout: reads return what arrived within it.
    Raises :class:`PortError` naming the port when it cannot be opened.
    """
    try:
        return serial.serial_for_url(port, baudrate=baud, timeout=timeout_s, write_timeout=2.0)
    except (serial.SerialException, OSError, ValueError) as exc:
        hint = ""
        if port.startswith("/dev/"):
            hint = (
                " (is the device plugged in and are you allowed to use it? list ports with "
                "`python -m serial.tools.list_ports`; on Linux add yourself to the dialout group)"
            )
        elif port.startswith("socket://"):
            hint = " (is the simulator or bridge listening there?)"
        raise PortError(f"cannot open serial port {port!r}: {exc}{hint}") from None


class Link:
    """An open port with byte-level read/write and optional reconnection.

    ``on_connect(link)`` is called after every (re)connection, e.g. to send
    a START command. ``reconnect_timeout_s=0`` retries forever.
    """

    def __init__(
        self,
        port: str,
        baud: int = 115200,
        read_timeout_s: float = 0.05,
        reconnect: bool = False,
        reconnect_interval_s: float = 0.5,
        reconnect_timeout_s: float = 30.0,
        on_connect: Callable[[Link], None] | None = None,
    ) -> None:
        self.port = port
        self.baud = baud
        self.read_timeout_s = read_timeout_s
        self.reconnect = reconnect
        self.reconnect_interval_s = reconnect_interval_s
        self.reconnect_timeout_s = reconnect_timeout_s
        self.on_connect = on_connect
        self.reconnects = 0
        self._ser: serial.SerialBase | None = None

    def open(self) -> Link:
        self._ser = open_port(self.port, self.baud, self.read_timeout_s)
        log.info("opened %s at %d baud", self.port, self.baud)
        if self.on_connect is not None:
            self.on_connect(self)
        return self

    def close(self) -> None:
        if self._ser is not None:
            try:
                self._ser.close()
            except (serial.SerialException, OSError):  # already gone
                pass
            self._ser = None

    def __enter__(self) -> Link:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def is_open(self) -> bool:
        return self._ser is not None and self._ser.is_open

    def read(self) -> bytes:
        """Bytes that arrived (blocks up to the read timeout for the first one).

        Raises :class:`PortLost` when the port vanished; with ``reconnect``
        it reconnects first and returns ``b""`` (callers reset their decoder
        when :attr:`reconnects` changes).
        """
        try:
            ser = self._require()
            n = ser.in_waiting
            return ser.read(n if n > 0 else 1)
        except (serial.SerialException, OSError) as exc:
            self._lost(exc)
            return b""

    def poll(self) -> bytes:
        """Bytes already waiting, without blocking (``b""`` if none)."""
        try:
            ser = self._require()
            n = ser.in_waiting
            return ser.read(n) if n > 0 else b""
        except (serial.SerialException, OSError) as exc:
            self._lost(exc)
            return b""

    def write(self, data: bytes) -> None:
        """Write all of ``data`` (raises :class:`PortLost`, or reconnects, if the port vanished)."""
        try:
            self._require().write(data)
        except (serial.SerialException, OSError) as exc:
            self._lost(exc)

    def _require(self) -> serial.SerialBase:
        if self._ser is None:
            raise serial.SerialException("port is not open")
        return self._ser

    def _lost(self, exc: BaseException) -> None:
        self.close()
        msg = f"serial port {self.port!r} vanished ({exc})"
        if not self.reconnect:
            raise PortLost(msg + "; the device was unplugged or the link closed (reconnect=true retries)") from None
        log.warning("%s; reconnecting every %.1f s", msg, self.reconnect_interval_s)
        t0 = time.monotonic()
        while True:
            try:
                self.open()
            except PortError as err:
                waited = time.monotonic() - t0
                if self.reconnect_timeout_s > 0 and waited >= self.reconnect_timeout_s:
                    raise PortLost(f"{msg}; gave up reconnecting after {waited:.1f} s: {err}") from None
                time.sleep(self.reconnect_interval_s)
                continue
            self.reconnects += 1
            log.warning("reconnected to %s after %.1f s", self.port, time.monotonic() - t0)
            return
