"""Serial transport, both ends: the host's port (pyserial) and a simulated device's endpoint.

Everything protocol-specific lives in the pure decoders; this module only
moves bytes. Host side (:class:`Link`): any pyserial URL works: ``/dev/ttyUSB0``,
``/dev/rfcomm0`` (Bluetooth serial), ``loop://`` (loopback, for dry runs),
``socket://host:port`` (a simulator or a network bridge). A port that vanishes
(unplugged device, closed socket) raises :class:`PortLost` with a message
naming the port; :class:`Link` with ``reconnect=True`` instead retries opening
it until ``reconnect_timeout_s``.

Device side (the simulators, :mod:`sphri.hardware.sim_skin` and
:mod:`sphri.hardware.sim_glove`): a pseudo-terminal (:class:`PtyEndpoint`) or a
listening socket (:class:`SocketEndpoint`) the host opens with the URLs above,
the settings every simulated device shares (:class:`DeviceSettings`), and
:func:`start_in_thread`.
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import select
import socket
import struct
import termios
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import serial

from sphri.config import ConfigError, Schema, require, setting

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

    def read(self, wait: bool = True) -> bytes:
        """Bytes that arrived (blocks up to the read timeout for the first one; ``wait=False``: only
        the bytes already waiting, ``b""`` if none).

        Raises :class:`PortLost` when the port vanished; with ``reconnect``
        it reconnects first and returns ``b""`` (callers reset their decoder
        when :attr:`reconnects` changes).
        """
        try:
            ser = self._require()
            n = ser.in_waiting
            return ser.read(max(n, 1)) if n > 0 or wait else b""
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


# =========================================================================== device side (simulators)
@dataclass
class DeviceSettings(Schema):
    """What every simulated device takes (``sphri simulate skin|glove``)."""

    port: str = "pty"
    """pty (a pseudo-terminal; its path is printed and linked at ``link``) or socket://HOST:PORT to listen on."""
    link: str = ""
    """pty only: a stable symlink to the pseudo-terminal (re-pointed after a simulated replug)."""
    seed: int = setting(0, lo=0)
    """Seeds the injected faults (and the skin's pattern source)."""
    report: str = ""
    """Write what was sent (good frames, faults) or received as JSON to this file."""

    def check(self) -> None:
        require(self.port == "pty" or self.port.startswith("socket://"), "port", self.port, "pty or socket://HOST:PORT")


class HostGone(RuntimeError):
    """The host side closed the connection (socket endpoints)."""


class Stopped(RuntimeError):
    """The simulator was asked to stop."""


# --------------------------------------------------------------------------- endpoints
class PtyEndpoint:
    """A pseudo-terminal: the host opens :attr:`name` (or the ``link`` symlink)."""

    def __init__(self, link: str = "") -> None:
        self.link = link
        self.master: int | None = None
        self.slave: int | None = None
        self.name = ""

    @property
    def url(self) -> str:
        return self.link or self.name

    def _master_fd(self) -> int:
        if self.master is None:
            raise RuntimeError("pty endpoint is not open (open() not called, or unplugged)")
        return self.master

    def open(self, stop: threading.Event) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no line editing, before any host opens it
        os.set_blocking(self.master, False)
        self.name = os.ttyname(self.slave)
        if self.link:
            tmp = f"{self.link}.tmp{os.getpid()}"
            if os.path.lexists(tmp):
                os.unlink(tmp)
            os.symlink(self.name, tmp)
            os.replace(tmp, self.link)

    def write(self, data: bytes, stop: threading.Event) -> None:
        view = memoryview(data)
        while view:
            if stop.is_set():
                raise Stopped()
            fd = self._master_fd()
            _, w, _ = select.select([], [fd], [], 0.1)
            if not w:
                continue
            try:
                n = os.write(fd, view)
            except BlockingIOError:
                continue
            view = view[n:]

    def read(self) -> bytes:
        fd = self._master_fd()
        r, _, _ = select.select([fd], [], [], 0)
        if not r:
            return b""
        try:
            return os.read(fd, 4096)
        except BlockingIOError:
            return b""
        except OSError as exc:  # EIO: no slave open (cannot happen while we hold one)
            if exc.errno == errno.EIO:
                return b""
            raise

    def pending(self) -> int:
        """Bytes written but not yet read by the host."""
        if self.slave is None:
            return 0
        return struct.unpack("i", fcntl.ioctl(self.slave, termios.FIONREAD, b"\0\0\0\0"))[0]

    def drain(self, stop: threading.Event, timeout_s: float = 5.0) -> None:
        """Wait until the host has read everything written (the kernel moves
        bytes to the slave side asynchronously: settle twice, 20 ms apart)."""
        t0 = time.monotonic()
        settled = 0
        while settled < 2 and time.monotonic() - t0 < timeout_s and not stop.is_set():
            time.sleep(0.02)
            settled = settled + 1 if self.pending() == 0 else 0

    def unplug(self) -> None:
        if self.link and os.path.islink(self.link):
            os.unlink(self.link)
        for fd in (self.master, self.slave):
            if fd is not None:
                os.close(fd)
        self.master = self.slave = None

    close = unplug


class SocketEndpoint:
    """A listening TCP socket; the host connects with ``socket://HOST:PORT``."""

    def __init__(self, url: str) -> None:
        hostport = url[len("socket://") :].split("?", 1)[0]
        host, _, port = hostport.rpartition(":")
        try:
            port_n = int(port)
        except ValueError:
            raise ConfigError(f"port={url!r} is invalid: expected socket://HOST:PORT") from None
        self.server = socket.create_server((host or "127.0.0.1", port_n))
        self.server.settimeout(0.1)
        self.host, self.port = self.server.getsockname()[:2]
        self.conn: socket.socket | None = None
        self._rx = b""

    @property
    def url(self) -> str:
        return f"socket://{self.host}:{self.port}"

    def open(self, stop: threading.Event) -> None:
        while not stop.is_set():
            try:
                self.conn, _ = self.server.accept()
            except TimeoutError:
                continue
            self.conn.settimeout(1.0)
            self.conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            return
        raise Stopped()

    def write(self, data: bytes, stop: threading.Event) -> None:
        assert self.conn is not None
        view = memoryview(data)
        while view:
            if stop.is_set():
                raise Stopped()
            try:
                n = self.conn.send(view)
            except TimeoutError:
                continue
            except OSError as exc:
                raise HostGone(str(exc)) from None
            view = view[n:]

    def read(self) -> bytes:
        assert self.conn is not None
        r, _, _ = select.select([self.conn], [], [], 0)
        if not r:
            return b""
        try:
            data = self.conn.recv(4096)
        except OSError as exc:
            raise HostGone(str(exc)) from None
        if not data:
            raise HostGone("the host closed the connection")
        return data

    def drain(self, stop: threading.Event, timeout_s: float = 5.0) -> None:
        pass  # TCP delivers what was sent before the close

    def unplug(self) -> None:
        if self.conn is not None:
            try:
                self.conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self.conn.close()
            self.conn = None

    def close(self) -> None:
        self.unplug()
        self.server.close()


def open_endpoint(endpoint: PtyEndpoint | SocketEndpoint, stop: threading.Event, ready: threading.Event) -> None:
    """Open ``endpoint`` and set ``ready`` as soon as a host can connect to its url."""
    if isinstance(endpoint, SocketEndpoint):
        ready.set()  # already listening; accept() waits for the host
    endpoint.open(stop)
    ready.set()


def make_endpoint(settings: DeviceSettings) -> PtyEndpoint | SocketEndpoint:
    """The endpoint ``settings.port`` names (``pty``, with ``settings.link``, or ``socket://HOST:PORT``)."""
    if settings.port == "pty":
        return PtyEndpoint(settings.link)
    return SocketEndpoint(settings.port)


def start_in_thread(sim: Any, timeout_s: float = 10.0) -> threading.Thread:
    """Run a simulator (``run()``, a ``ready`` event) in a daemon thread; returns once its endpoint is open
    (``sim.endpoint.url``)."""
    th = threading.Thread(target=sim.run, name=f"sphri-{type(sim).__name__}", daemon=True)
    th.start()
    if not sim.ready.wait(timeout_s):
        raise TimeoutError(f"{type(sim).__name__} did not open its endpoint within {timeout_s} s")
    return th
