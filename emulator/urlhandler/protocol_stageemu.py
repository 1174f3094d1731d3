"""pyserial handler of `stageemu://` URLs: an emulated controller inside the calling process.

    import emulator.urlhandler  # once: registers the scheme with pyserial
    port = serial.serial_for_url("stageemu://ms2000?timing=fast", baudrate=9600, timeout=1)

Each open builds a factory-fresh device from the profile (emulator/urlhandler/url.py has the URL
form) and closes it with the port. The host's line settings reach the model as they would through a
daemon's port, and more fully: a PTY hides parity and data bits, here they are known, so a host at
the wrong baud rate, data bits or parity gets the garbled bytes the real device would give it.
The port carries modem lines as an RFC 2217 port does (emulator/hosting/transports/modem.py): `rts` and
`dtr` reach the device, `cts`, `dsr`, `cd` and `ri` are the device's. Nothing on this path needs a
pseudo-terminal, termios or fcntl: it runs on Windows and macOS too.
"""

from __future__ import annotations

from typing import Any

import serial
from serial.serialutil import (
    PARITY_EVEN,
    PARITY_NONE,
    PARITY_ODD,
    PortNotOpenError,
    SerialBase,
    SerialException,
)

from emulator.device import MAIN, HostLine
from emulator.urlhandler.control import HostedControl
from emulator.urlhandler.hosted import HostedDevice, served
from emulator.urlhandler.url import AttachOptions, parse_url

_PARITY_NAMES = {PARITY_NONE: "none", PARITY_EVEN: "even", PARITY_ODD: "odd"}


class Serial(SerialBase):
    """A pyserial port whose other end is a device model run in this process."""

    # the models know no mark or space parity: pyserial refuses them when set (ValueError)
    PARITIES = tuple(_PARITY_NAMES)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # set before SerialBase's __init__, which opens the port when given one
        self._device: HostedDevice | None = None
        #: which of the device's ports this is (the main one, unless `open_channel` made it)
        self._channel = MAIN
        #: the settings the model was last told (pyserial reconfigures on every timeout change too)
        self._line: HostLine | None = None
        self._control: HostedControl | None = None
        #: whether the device is this port's own (made by opening it), switched off with it
        self._owner = False
        #: the device's other ports opened from this one (`open_channel`), closed with it
        self._others: list[serial.SerialBase] = []
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self.port is None:
            raise SerialException("Port must be configured before it can be used.")
        url = str(self.port)
        options = parse_url(url)
        self._line = self._host_line()
        if isinstance(options, AttachOptions):
            device, self._owner = served(options.key), False
            device.open_channel(options.channel, self._line)
            self._device, self._channel = device, options.channel
        else:
            self._device, self._owner = HostedDevice(url, options, self._line), True
        self.is_open = True
        # a driver raises RTS and DTR at open; pyserial keeps what was set before opening
        self._device.set_control(self._channel, rts=bool(self.rts), dtr=bool(self.dtr))

    def close(self) -> None:
        for other in self._others:
            other.close()
        device, self._device = self._device, None
        if device is not None:
            device.close_channel(self._channel)
            if self._owner:  # the port's own device: switched off with it
                device.close()
        self.is_open = False

    def _open_device(self) -> HostedDevice:
        if not self.is_open or self._device is None:
            raise PortNotOpenError()
        return self._device

    # ---- beyond pyserial: the device's other ports, its control channel, virtual time -----------

    def open_channel(self, channel: str, **settings: Any) -> serial.SerialBase:
        """The device's port `channel` (the MS2000 TTL REPORT's `aux`) as a pyserial port of its
        own, opened with pyserial's keyword `settings`; it closes with this one."""
        other = serial.serial_for_url(self._open_device().url(channel), **settings)
        self._others.append(other)
        return other

    @property
    def control(self) -> HostedControl:
        """The device's control channel, in this process: the daemon's requests (`input`, `get`,
        `fault`, `reset`, `step`, `subscribe` ...) with `stage-emu ctl`'s client methods."""
        if self._control is None:
            self._control = HostedControl(self._open_device())
        return self._control

    @property
    def device_time(self) -> float:
        """The device's time now, in seconds (in virtual time, the host's clock too)."""
        return self._open_device().now()

    def advance(self, seconds: float) -> None:
        """Let `seconds` of device time pass at once (virtual time only: `?time=virtual`)."""
        device = self._open_device()
        if not device.time.virtual:
            raise SerialException(f"{self.port}: advance needs virtual time (?time=virtual)")
        self.control.step(seconds)

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
            device.set_line(self._channel, host)

    # ---- data -----------------------------------------------------------------------------------

    @property
    def in_waiting(self) -> int:
        return self._open_device().in_waiting(self._channel)

    @property
    def out_waiting(self) -> int:
        return self._open_device().out_waiting(self._channel)

    def read(self, size: int = 1) -> bytes:
        device = self._open_device()
        return device.read(self._channel, size, device.deadline(self.timeout), self.inter_byte_timeout)

    def write(self, data: bytes | bytearray | memoryview) -> int:  # type: ignore[override]
        device = self._open_device()
        timeout = self.write_timeout
        return device.write(self._channel, bytes(data), device.deadline(timeout), non_blocking=timeout == 0)

    def flush(self) -> None:
        """Wait until all data written has been sent."""
        self._open_device().drain(self._channel)

    def reset_input_buffer(self) -> None:
        self._open_device().discard_input(self._channel)

    def reset_output_buffer(self) -> None:
        self._open_device().discard_output(self._channel)

    def cancel_read(self) -> None:
        self._open_device().cancel_read(self._channel)

    def cancel_write(self) -> None:
        self._open_device().cancel_write(self._channel)

    # ---- modem lines --------------------------------------------------------------------------
    # What the host drives reaches the device's port; with RTS/CTS flow control on the device's side
    # (the MP-285A's USB port) RTS off holds the device's output. The models have no break detection.

    def _update_rts_state(self) -> None:
        self._open_device().set_control(self._channel, rts=bool(self.rts))

    def _update_dtr_state(self) -> None:
        self._open_device().set_control(self._channel, dtr=bool(self.dtr))

    def _update_break_state(self) -> None:
        """A break goes nowhere: the models have no break detection."""

    @property
    def cts(self) -> bool:
        return self._open_device().modem_lines(self._channel).cts

    @property
    def dsr(self) -> bool:
        return self._open_device().modem_lines(self._channel).dsr

    @property
    def cd(self) -> bool:
        return self._open_device().modem_lines(self._channel).cd

    @property
    def ri(self) -> bool:
        return self._open_device().modem_lines(self._channel).ri
