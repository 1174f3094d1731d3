"""`stage-emu proxy`: a pseudo-terminal in front of a real controller, recording a session.

The host opens the PTY (emulator/hosting/transports/pty.py, as a daemon's port: mode 0600, a link in the
per-user directory) as it would the controller's own port. Bytes go both ways as they come: what the
host writes is written to the real port at once, what the controller sends is read by a thread (a
pyserial read blocks) and handed to the event loop, which writes it to the PTY. The host's line
settings (baud, stop bits, flow control: what a PTY shows) are set on the real port too, so a host
at the wrong baud rate is at the wrong baud rate on the controller. Every read is recorded with its
time (emulator/tools/session.py); SIGINT, SIGTERM or SIGHUP stop it and complete the file.

The real side is any pyserial URL: a device path, `rfc2217://`, or an emulator's own port, which is
how a session recorded from the emulator is made to check the proxy and the replay against.
"""

from __future__ import annotations

import asyncio
import json
import logging
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import serial

import emulator.urlhandler  # noqa: F401  (a stageemu:// URL may stand for the controller)
from emulator.device import HostLine, LineSettings, ModemLines
from emulator.hosting.transports.pty import PtyTransport
from emulator.tools.replay import ReplayError, apply_line, open_port
from emulator.tools.session import RX, TX, Header, SessionWriter

log = logging.getLogger("stage_emu.proxy")

#: host bytes taken per read: the real port's write is synchronous, so no wire pacing is needed here
ROOM = 4096


class ProxyError(Exception):
    """The proxy cannot start or the real port failed; one line."""


@dataclass(frozen=True)
class ProxyOptions:
    real: str
    family: str
    profile: str
    line: LineSettings
    link: Path
    record: Path


class Proxy:
    """Forwards between the PTY (a `PortSink` of its transport) and the real port; records both."""

    def __init__(self, options: ProxyOptions) -> None:
        self.options = options
        self._start = time.monotonic()
        self._real: serial.Serial | None = None
        self._writer: SessionWriter | None = None
        self._transport: PtyTransport | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._done = threading.Event()
        self._closed = False
        self.failure: str | None = None

    def _now(self) -> float:
        return time.monotonic() - self._start

    async def run(self) -> None:
        """Serve until a stop signal (or the real port fails: `failure` says why)."""
        options = self.options
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        try:
            self._real = open_port(options.real, options.line)
        except ReplayError as exc:
            raise ProxyError(str(exc)) from None
        reader: threading.Thread | None = None
        try:
            self._transport = PtyTransport(options.link, 0o600, self._loop)
            self._transport.open(self)
            self._writer = SessionWriter(
                options.record, Header(options.family, options.profile, options.line, options.real)
            )
            self._start = time.monotonic()
            reader = threading.Thread(target=self._read_real, name="stage-emu-proxy-reader", daemon=True)
            reader.start()
            for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
                self._loop.add_signal_handler(signum, self._stop.set)
            self._announce()
            await self._stop.wait()
        finally:
            self._done.set()
            if reader is not None:
                reader.join()
                await asyncio.sleep(0)  # record what the reader handed over before it stopped
            self._close()

    def _announce(self) -> None:
        assert self._transport is not None
        record = {
            "device": self.options.family,
            "profile": self.options.profile,
            "path": self._transport.path,
            "pts": self._transport.device_path,
            "real": self.options.real,
            "record": str(self.options.record),
        }
        sys.stdout.write(json.dumps(record) + "\n")
        sys.stdout.flush()

    def _close(self) -> None:
        if self._transport is not None:
            self._transport.close()
        if self._real is not None:
            self._real.close()
        if self._writer is not None:
            self._writer.close(self._now())
        self._closed = True

    @property
    def exchanges(self) -> int:
        return 0 if self._writer is None else self._writer.exchanges

    # ---- the controller's side ------------------------------------------------------------------

    def _read_real(self) -> None:
        """The reader thread: each read's bytes, stamped on arrival, to the loop."""
        real, loop = self._real, self._loop
        assert real is not None and loop is not None
        try:  # the port's read timeout (replay.READ_POLL_S) bounds how late it sees the stop
            while not self._done.is_set():
                data = real.read(1)
                if data:
                    waiting = real.in_waiting
                    data += real.read(waiting) if waiting else b""
                    loop.call_soon_threadsafe(self._device_data, self._now(), data)
        except (serial.SerialException, OSError) as exc:
            loop.call_soon_threadsafe(self._fail, f"{self.options.real}: the real port failed: {exc}")

    def _device_data(self, t: float, data: bytes) -> None:
        if self._closed or self._writer is None or self._transport is None:
            return
        self._writer.chunk(t, TX, data)
        dropped = self._transport.write(data)
        if dropped:
            log.warning("%d bytes from the controller dropped: the host is not reading", dropped)

    def _fail(self, message: str) -> None:
        self.failure = message
        assert self._stop is not None
        self._stop.set()

    # ---- the host's side (PortSink) -------------------------------------------------------------

    def host_attached(self, host: HostLine | None) -> None:
        log.info("a host opened %s", self.options.link)
        if host is not None:
            self.host_line(host)

    def host_detached(self) -> None:
        log.info("the host closed %s", self.options.link)

    def host_line(self, host: HostLine) -> None:
        assert self._writer is not None and self._real is not None
        self._writer.line(self._now(), host)
        try:
            apply_line(self._real, host)
        except (ValueError, serial.SerialException) as exc:
            log.warning("the real port refused the host's settings %s: %s", host.describe(), exc)

    def host_data(self, data: bytes) -> None:
        assert self._writer is not None and self._real is not None
        self._writer.chunk(self._now(), RX, data)
        try:
            self._real.write(data)
        except (serial.SerialException, OSError) as exc:
            self._fail(f"{self.options.real}: writing to the real port failed: {exc}")

    def room(self) -> int:
        return ROOM

    def input_discarded(self, count: int) -> None:
        log.info("%d bytes the host wrote before closing were never read", count)

    def device_line(self) -> LineSettings:
        return self.options.line

    def modem_lines(self) -> ModemLines:
        """Not relayed: the host's side is a pseudo-terminal, which carries no modem lines."""
        return ModemLines()

    def line_error(self, byte: int, kind: str) -> None:
        """Never called: the host's side is a pseudo-terminal, which reports no line errors."""
