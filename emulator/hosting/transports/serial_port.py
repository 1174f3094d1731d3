"""Opening a real serial port at a device's line settings, and reading the line errors its UART
reports (for emulator/hosting/transports/serial.py). The settings mapping and the decoder (`port_settings`,
`refused_settings`, `unmark`, `error_kind`) are pure; the rest touches the port.

- Settings: a device's `LineSettings` become pyserial's (`port_settings`). After configuring, the
  port's termios are read back (`refused_settings`): drivers do not all fail on what their UART
  cannot do, some keep what they can (a pseudo-terminal keeps 8 data bits and no parity whatever
  it is asked), and a device served at other settings than its own would garble every byte.
  POSIX has no 1.5 stop bits: the port sends 2, which reads the same to any receiver (it checks the
  first stop bit only).
- Line errors (POSIX ports): with PARMRK and INPCK set, and IGNPAR, IGNBRK, BRKINT and ISTRIP clear,
  the kernel marks a character received with a framing or parity error as FF 00 X, a break as
  FF 00 00, and doubles a data FF (FF FF). `unmark` undoes that. pyserial clears PARMRK and INPCK
  each time it configures the port, so `mark_errors` sets them again after it.
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
import struct
import sys
import termios
from dataclasses import dataclass, replace
from typing import Any

import serial

from emulator.device import FRAMING_ERROR, PARITY_ERROR, HostLine, LineSettings
from emulator.hosting.transports.pty import PortError, host_settings

PARITIES = {"none": serial.PARITY_NONE, "even": serial.PARITY_EVEN, "odd": serial.PARITY_ODD}
STOP_BITS = {1: serial.STOPBITS_ONE, 1.5: serial.STOPBITS_ONE_POINT_FIVE, 2: serial.STOPBITS_TWO}
#: a port whose real rate is off by more than this fraction would garble: a UART's usual tolerance
BAUD_TOLERANCE = 0.02
#: the byte that opens a PARMRK mark
MARK = 0xFF


@dataclass(frozen=True)
class LineError:
    """A character the UART received with a framing or parity error (a break reads as 00)."""

    byte: int


#: what `unmark` yields: runs of data bytes and line errors, in order
Piece = bytes | LineError


def is_url(device: str) -> bool:
    """pyserial URLs (`rfc2217://`, `socket://`, ...) name no device node."""
    return "://" in device


def port_settings(line: LineSettings) -> dict[str, Any]:
    """pyserial's settings for a device's line; PortError for what pyserial has no name for."""
    parity = PARITIES.get(line.parity or "")
    stop = STOP_BITS.get(line.stop_bits or 0)
    if parity is None or stop is None or not line.baud or line.data_bits not in (5, 6, 7, 8):
        raise PortError(f"a serial port cannot be set to {line.describe()}")
    return {
        "baudrate": line.baud,
        "bytesize": line.data_bits,
        "parity": parity,
        "stopbits": stop,
        "rtscts": bool(line.rtscts),
        "xonxoff": bool(line.xonxoff),
    }


def open_port(device: str, line: LineSettings, timeout: float | None) -> serial.SerialBase:
    """The port opened at `line` (exclusively, on POSIX: a second opener is refused); PortError
    with one sentence that says what is wrong otherwise. `timeout` is pyserial's read timeout."""
    settings = port_settings(line)
    url = is_url(device)
    if not url:
        _check_node(device)
    try:
        port = serial.serial_for_url(
            device,
            do_not_open=True,
            timeout=timeout,
            exclusive=True if os.name == "posix" and not url else None,
        )
        port.apply_settings(settings)
        port.open()
    except (serial.SerialException, OSError, ValueError, termios.error) as exc:
        raise PortError(open_failure(device, line, exc)) from None
    return port


def _check_node(device: str) -> None:
    """Refuse a directory or a regular file before pyserial opens it (it would only say that it
    cannot configure it)."""
    try:
        mode = os.stat(device).st_mode
    except OSError:
        return  # pyserial says what is wrong, in its own error
    kind = "a directory" if stat.S_ISDIR(mode) else "a regular file" if stat.S_ISREG(mode) else None
    if kind is not None:
        raise PortError(f"serial port {device}: not a serial port (it is {kind})")


def open_failure(device: str, line: LineSettings, exc: BaseException) -> str:
    """One sentence for why `device` did not open at `line`."""
    code = getattr(exc, "errno", None)
    where = f"serial port {device}"
    if code in (errno.ENOENT, errno.ENODEV, errno.ENXIO):
        return f"{where}: no such device (is the adapter plugged in? `ls /dev/serial/by-id` lists them)"
    if code in (errno.EAGAIN, errno.EBUSY):
        return f"{where}: in use by another program (it is opened exclusively)"
    if code == errno.EACCES:
        return f"{where}: permission denied (on Linux, join the group that owns it, usually dialout)"
    if code == errno.EISDIR:
        return f"{where}: not a serial port (it is a directory)"
    if not is_url(device) and not is_terminal(device):
        return f"{where}: not a serial port (the system refuses terminal settings on it)"
    if isinstance(exc, termios.error):  # the driver refused the settings
        return f"{where}: does not support {line.describe()} ({reason(exc)})"
    if isinstance(exc, ValueError) or "configure" in str(exc):
        return f"{where}: does not support {line.describe()} ({exc})"
    return f"{where}: cannot open: {exc}"


def reason(exc: BaseException) -> str:
    """The system's words for a failure (termios.error carries them as its second argument)."""
    if isinstance(exc, termios.error) and len(exc.args) == 2:
        return str(exc.args[1])
    return getattr(exc, "strerror", None) or str(exc)


def is_terminal(device: str) -> bool:
    try:
        fd = os.open(device, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    except OSError:
        return False
    try:
        return os.isatty(fd)
    finally:
        os.close(fd)


def refused_settings(wanted: LineSettings, actual: HostLine) -> str | None:
    """What the port did not take of `wanted`, read back as `actual` (None: all of it)."""
    refused = []
    if (
        actual.baud is not None
        and wanted.baud
        and abs(actual.baud - wanted.baud) > wanted.baud * BAUD_TOLERANCE
    ):
        refused.append(f"{wanted.baud} baud (it runs at {actual.baud})")
    if actual.data_bits is not None and actual.data_bits != wanted.data_bits:
        refused.append(f"{wanted.data_bits} data bits (it keeps {actual.data_bits})")
    if actual.parity is not None and actual.parity != wanted.parity:
        refused.append(f"{wanted.parity} parity (it keeps {actual.parity})")
    stop = 2 if wanted.stop_bits == 1.5 else wanted.stop_bits  # POSIX: 1.5 is sent as 2
    if actual.stop_bits is not None and actual.stop_bits != stop:
        refused.append(f"{wanted.stop_bits:g} stop bits (it keeps {actual.stop_bits:g})")
    return ", ".join(refused) or None


def unmark(data: bytes, held: bytes = b"") -> tuple[list[Piece], bytes]:
    """Split what a PARMRK port gave into data runs and line errors. `held` is the unfinished mark
    the previous read ended with (b"", FF, or FF 00); the one this read ends with is returned, for
    the next. An FF followed by anything but FF or 00 is data: the kernel did not double it (the
    port was being reconfigured, PARMRK briefly off)."""
    buf = held + data if held else data
    if MARK not in buf:
        return ([bytes(buf)] if buf else []), b""
    pieces: list[Piece] = []
    run = bytearray()
    i, end = 0, len(buf)
    while True:
        j = buf.find(MARK, i)
        if j < 0:
            run += buf[i:]
            rest = b""
            break
        run += buf[i:j]
        if j + 1 == end or (j + 2 == end and buf[j + 1] == 0):
            rest = bytes(buf[j:])  # the mark goes on in the next read
            break
        follower = buf[j + 1]
        if follower == MARK:
            run.append(MARK)
            i = j + 2
        elif follower == 0:
            if run:
                pieces.append(bytes(run))
                run = bytearray()
            pieces.append(LineError(buf[j + 2]))
            i = j + 3
        else:
            run.append(MARK)
            i = j + 1
    if run:
        pieces.append(bytes(run))
    return pieces, rest


# ---- POSIX ports: termios -----------------------------------------------------------------------

#: Linux: the UART's error counters (struct serial_icounter_struct: 20 ints)
TIOCGICOUNT = 0x545D
_ICOUNT = struct.Struct("20i")


def port_line(fd: int) -> HostLine:
    """The settings the port has now, read back from its termios."""
    seen = host_settings(fd)  # baud (a non-standard rate too), stop bits, flow control
    cflag = termios.tcgetattr(fd)[2]
    sizes = {termios.CS5: 5, termios.CS6: 6, termios.CS7: 7, termios.CS8: 8}
    parity = "none" if not cflag & termios.PARENB else "odd" if cflag & termios.PARODD else "even"
    return replace(seen, data_bits=sizes[cflag & termios.CSIZE], parity=parity)


def mark_errors(fd: int) -> None:
    """Have the kernel mark line errors in the data (`unmark`) rather than drop or zero them."""
    attrs = termios.tcgetattr(fd)
    attrs[0] |= termios.PARMRK | termios.INPCK
    attrs[0] &= ~(termios.IGNPAR | termios.IGNBRK | termios.BRKINT | termios.ISTRIP)
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def error_counts(fd: int) -> tuple[int, int, int] | None:
    """The UART's framing, parity and break counters (None where the driver keeps none: a
    pseudo-terminal, some USB adapters, systems other than Linux)."""
    if not sys.platform.startswith("linux"):
        return None  # the request number is Linux's
    try:
        raw = fcntl.ioctl(fd, TIOCGICOUNT, bytes(_ICOUNT.size))
    except OSError:
        return None
    counts = _ICOUNT.unpack(raw)
    return counts[6], counts[8], counts[9]


def error_kind(
    parity_on: bool, before: tuple[int, int, int] | None, after: tuple[int, int, int] | None
) -> str:
    """Whether the marked characters read between two counter readings were parity errors (the
    kernel marks both kinds alike): only when the port checks parity and its counters say parity
    alone rose; a framing error otherwise, a break included."""
    if not parity_on or before is None or after is None:
        return FRAMING_ERROR
    frame, parity, brk = (a - b for a, b in zip(after, before, strict=True))
    return PARITY_ERROR if parity > 0 and frame == 0 and brk == 0 else FRAMING_ERROR
