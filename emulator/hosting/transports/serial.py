"""A real serial port (`transport: serial`, `serve --serial DEVICE`): the device answers on a UART,
so a small Linux box with a USB-RS-232 adapter and a null-modem cable stands in for the controller
to an unmodified PC. `device` is a device path (`/dev/ttyUSB0`, `/dev/serial/by-id/...`) or any
pyserial URL (`rfc2217://...`: a serial port on another machine); a name such as `COM7` is handed
to pyserial as it is.

- The port runs at the device's own settings (`PortSink.device_line`: baud, data bits, parity, stop
  bits, RTS/CTS when the device uses it), and follows them when they change (the MS2000's `SB`,
  MS-3; the MP-285's front-panel menu): the port is reconfigured in place, so input already queued
  and the modem lines stay as they are. A port that does not take the settings is refused at start
  (one line); a later change it does not take is logged, and the port keeps what it could set.
- The host's settings are not visible on a serial line: a host at other settings gets garbage from
  the UARTs themselves. The host is reported with no settings (the model assumes they match), and
  described so (`SerialHost`). Nor does a serial line say when the far end opens it: the host
  counts as attached from the moment the port is open.
- Line errors: characters received with a framing or parity error, and breaks, reach the model as
  such (`PortSink.line_error`, emulator/hosting/transports/serial_port.py). A port without a descriptor (a
  URL) reports none: its characters arrive as its driver gives them.
- A port that disappears (an adapter unplugged: EOF, EIO, a hang-up) is the host hanging up: one log
  line, then a try to reopen it every REOPEN_S (a timer), and one log line when it is back. The
  other ports carry on meanwhile. `vanish`/`reappear` (fault injection) close and reopen it.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import termios
from dataclasses import dataclass

import serial

from emulator.device import HostLine, LineSettings
from emulator.hosting.line_errors import UNSEEN_HOST
from emulator.hosting.transports.base import PortSink, Transport
from emulator.hosting.transports.pty import PortError
from emulator.hosting.transports.serial_io import FdIo, ThreadIo
from emulator.hosting.transports.serial_port import (
    is_url,
    mark_errors,
    open_port,
    port_line,
    port_settings,
    reason,
    refused_settings,
)

log = logging.getLogger("stage_emu.serial")

#: a port that disappeared is tried again this often
REOPEN_S = 0.5
#: a port read by a thread (no descriptor) returns from a read this often with nothing, so that the
#: reader of a port closed meanwhile sees it and ends
READ_WAIT_S = 0.5


@dataclass(frozen=True)
class SerialHost(HostLine):
    """The far end of a serial line: none of its settings are visible."""

    def describe(self) -> str:
        return UNSEEN_HOST


class SerialTransport(Transport):
    kind = "serial"
    wire_paces = True

    def __init__(self, device: str, loop: asyncio.AbstractEventLoop | None = None) -> None:
        self._device = device
        self._loop = loop
        self._sink: PortSink | None = None
        self._port: serial.SerialBase | None = None
        self._io: FdIo | ThreadIo | None = None
        #: the settings the port was last set to
        self._line: LineSettings | None = None
        self._retry: asyncio.TimerHandle | None = None
        self._attached = False

    @property
    def path(self) -> str:
        return self._device

    @property
    def device_path(self) -> str | None:
        """The device node behind the path (`/dev/ttyUSB0` for a `/dev/serial/by-id/` link)."""
        return None if is_url(self._device) else os.path.realpath(self._device)

    def open(self, sink: PortSink) -> None:
        self._sink = sink
        if self._loop is None:
            self._loop = asyncio.get_running_loop()
        self._connect()

    def _connect(self, back: bool = False) -> None:
        """Open the port at the device's settings and attach the host; PortError if it cannot be.
        `back`: it is reopened after it had gone (said once, before the host attaches)."""
        assert self._sink is not None and self._loop is not None
        line = self._sink.device_line()
        port = open_port(self._device, line, READ_WAIT_S)
        try:
            fd = _descriptor(port)
            io: FdIo | ThreadIo
            if fd is None:
                io = ThreadIo(port, self._loop, self._sink, self._gone)
            else:
                refused = _mark_and_check(fd, line)
                if refused:
                    raise PortError(f"serial port {self._device}: {refused}")
                io = FdIo(fd, self._loop, self._sink, self._gone)
                io.parity_on = line.parity != "none"
        except BaseException:
            port.close()
            raise
        self._port, self._io, self._line = port, io, line
        self._drive_modem_lines()
        if back:
            log.warning("%s: serial port is back", self._device)
        self._attached = True
        self._sink.host_attached(SerialHost())

    def _drive_modem_lines(self) -> None:
        """Through a null-modem cable the host reads this port's RTS as its CTS and its DTR as its
        DSR and CD: set them to the device's lines (`PortSink.modem_lines`). With RTS/CTS the driver
        runs RTS itself (off while its input buffer is full: the device holding the host off), so
        only DTR is set. A computer's port cannot drive RI. A port without modem lines (a
        pseudo-terminal, a raw socket URL) keeps none; said at debug level."""
        assert self._sink is not None and self._port is not None and self._line is not None
        lines = self._sink.modem_lines()
        try:
            if not self._line.rtscts:
                self._port.rts = lines.cts
            self._port.dtr = lines.dsr or lines.cd
        except (OSError, ValueError, serial.SerialException) as exc:
            log.debug("%s: no modem lines to drive: %s", self._device, reason(exc))

    def _disconnect(self) -> None:
        """Close the port; the host, if attached, hangs up."""
        io, self._io = self._io, None
        if io is not None:
            io.stop()
        port, self._port = self._port, None
        if port is not None:
            with contextlib.suppress(Exception):  # a port that is gone may fail to close cleanly
                port.close()
        if self._attached:
            self._attached = False
            assert self._sink is not None
            self._sink.host_detached()

    def _gone(self, reason: str) -> None:
        log.warning(
            "%s: serial port gone (%s); trying to reopen it every %g s", self._device, reason, REOPEN_S
        )
        self._disconnect()
        self._retry_later()

    def _retry_later(self) -> None:
        assert self._loop is not None
        self._retry = self._loop.call_later(REOPEN_S, self._reopen)

    def _reopen(self) -> None:
        self._retry = None
        try:
            self._connect(back=True)
        except PortError:
            self._retry_later()

    def _cancel_retry(self) -> None:
        if self._retry is not None:
            self._retry.cancel()
            self._retry = None

    def close(self) -> None:
        self._cancel_retry()
        self._disconnect()

    def vanish(self) -> None:
        self._cancel_retry()
        self._disconnect()

    def reappear(self) -> None:
        if self._io is not None or self._retry is not None:
            return
        try:
            self._connect()
        except PortError as exc:  # taken or unplugged meanwhile: keep trying, as after a hang-up
            log.error("%s; trying again every %g s", exc, REOPEN_S)
            self._retry_later()

    # ---- data ---------------------------------------------------------------------------------

    def write(self, data: bytes) -> int:
        return 0 if self._io is None else self._io.write(data)

    def resume_reading(self) -> None:
        if self._io is not None:
            self._io.resume()

    def device_line_changed(self) -> None:
        """Reconfigure the open port at the device's new settings (a closed one opens at them)."""
        if self._port is None or self._sink is None:
            return
        line = self._sink.device_line()
        if line == self._line:
            return
        self._line = line
        failure = None
        try:
            self._port.apply_settings(port_settings(line))
        except (PortError, ValueError, serial.SerialException, OSError, termios.error) as exc:
            failure = reason(exc)
        fd = _descriptor(self._port)
        if fd is not None:  # pyserial cleared the marks, whatever it managed to set
            failure = _mark_and_check(fd, line) or failure
        if failure:
            log.error("%s: cannot follow the device to %s: %s", self._device, line.describe(), failure)
        else:
            log.info("%s: now at %s, as the device", self._device, line.describe())
        if isinstance(self._io, FdIo):
            self._io.parity_on = line.parity != "none"


def _mark_and_check(fd: int, line: LineSettings) -> str | None:
    """Have line errors marked, then read the settings back: what the port did not take of `line`
    (None: it took all of it)."""
    try:
        mark_errors(fd)
        refused = refused_settings(line, port_line(fd))
    except (OSError, termios.error) as exc:
        return f"cannot set it up: {reason(exc)}"
    return None if refused is None else f"does not support {refused}"


def _descriptor(port: serial.SerialBase) -> int | None:
    """The terminal device descriptor the loop can watch (None: a URL, or no POSIX port)."""
    fd = getattr(port, "fd", None)
    return fd if isinstance(fd, int) and os.isatty(fd) else None
