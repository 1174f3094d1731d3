"""pyserial handler of `stageemu://` URLs: an emulated controller inside the calling process.

    import emulator.urlhandler  # once: registers the scheme with pyserial
    port = serial.serial_for_url("stageemu://ms2000?timing=fast", baudrate=9600, timeout=1)

Each open builds a factory-fresh device from the profile (emulator/urlhandler/url.py has the URL
form) and closes it with the port. The host's line settings reach the model as they would through a
daemon's port, and more fully: a PTY hides parity and data bits, here they are known, so a host at
the wrong baud rate, data bits or parity gets the garbled bytes the real device would give it.
Nothing on this path needs a pseudo-terminal, termios or fcntl: it runs on Windows and macOS too.
"""

from __future__ import annotations

from typing import Any

from serial.serialutil import (
    PARITY_EVEN,
    PARITY_NONE,
    PARITY_ODD,
    PortNotOpenError,
    SerialBase,
    SerialException,
)

from emulator.device import HostLine
from emulator.urlhandler.hosted import Deadline, HostedDevice
from emulator.urlhandler.url import parse_url

_PARITY_NAMES = {PARITY_NONE: "none", PARITY_EVEN: "even", PARITY_ODD: "odd"}


class Serial(SerialBase):
    """A pyserial port whose other end is a device model run in this process."""

    # the models know no mark or space parity: pyserial refuses them when set (ValueError)
    PARITIES = tuple(_PARITY_NAMES)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # set before SerialBase's __init__, which opens the port when given one
        self._device: HostedDevice | None = None
        #: the settings the model was last told (pyserial reconfigures on every timeout change too)
        self._line: HostLine | None = None
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        url = str(self.port)
        self._line = self._host_line()
        self._device = HostedDevice(url, parse_url(url), self._line)
        self.is_open = True

    def close(self) -> None:
        if self._device is not None:
            self._device.close()
            self._device = None
        self.is_open = False

    def _open_device(self) -> HostedDevice:
        if not self.is_open or self._device is None:
            raise PortNotOpenError()
        return self._device

    # ---- settings -------------------------------------------------------------------------------

    def _host_line(self) -> HostLine:
        baud = self.baudrate
        if not isinstance(baud, int) or not 0 < baud < 2**32:
            raise ValueError(f"invalid baudrate: {baud!r}")
        return HostLine(
            baud=baud,
            data_bits=self.bytesize,
            parity=_PARITY_NAMES[self.parity],
            stop_bits=self.stopbits,
            rtscts=bool(self.rtscts),
            xonxoff=bool(self.xonxoff),
        )

    def _reconfigure_port(self) -> None:
        """Called by pyserial when a setting changes on the open port (timeouts included)."""
        host = self._host_line()
        device = self._open_device()
        if host != self._line:
            self._line = host
            device.set_line(host)

    # ---- data -----------------------------------------------------------------------------------

    @property
    def in_waiting(self) -> int:
        return self._open_device().in_waiting()

    @property
    def out_waiting(self) -> int:
        return self._open_device().out_waiting()

    def read(self, size: int = 1) -> bytes:
        device = self._open_device()
        return device.read(size, Deadline.after(self.timeout), self.inter_byte_timeout)

    def write(self, data: bytes | bytearray | memoryview) -> int:  # type: ignore[override]
        device = self._open_device()
        timeout = self.write_timeout
        return device.write(bytes(data), Deadline.after(timeout), non_blocking=timeout == 0)

    def flush(self) -> None:
        """Wait until all data written has been sent."""
        self._open_device().drain()

    def reset_input_buffer(self) -> None:
        self._open_device().discard_input()

    def reset_output_buffer(self) -> None:
        self._open_device().discard_output()

    def cancel_read(self) -> None:
        self._open_device().cancel_read()

    def cancel_write(self) -> None:
        self._open_device().cancel_write()

    # ---- modem lines ----------------------------------------------------------------------------
    # The models have no modem-line inputs (RTS/CTS flow control reaches them as a line setting),
    # so what the host drives goes nowhere, and the device side reads as a powered controller
    # ready to receive: CTS and DSR asserted, no carrier, no ring.

    def _update_rts_state(self) -> None:
        """RTS goes nowhere (see above)."""

    def _update_dtr_state(self) -> None:
        """DTR goes nowhere (see above)."""

    def _update_break_state(self) -> None:
        """A break goes nowhere: the models have no break detection."""

    @property
    def cts(self) -> bool:
        self._open_device()
        return True

    @property
    def dsr(self) -> bool:
        self._open_device()
        return True

    @property
    def cd(self) -> bool:
        self._open_device()
        return False

    @property
    def ri(self) -> bool:
        self._open_device()
        return False
