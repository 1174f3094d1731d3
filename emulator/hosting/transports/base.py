"""What every transport offers the device runner. Transports move bytes and report line settings;
they never parse the protocol.

Flow control (both directions are bounded, like a real serial line):
- Input: before each read a transport asks `PortSink.room()` how many host bytes the emulated wire
  can take now, reads at most that many, and stops reading while it is 0, leaving the rest in the
  OS buffer, so the host's write blocks as on a real port. The sink calls `resume_reading()` once
  room has reopened. A transport also reads in bounded slices per wakeup, so one flooding port
  cannot starve the others.
- Output: `write` keeps a bounded buffer of what the host has not taken yet and drops what does not
  fit (a real host's UART overruns the same way); it returns how many bytes it dropped, for the
  sink's count.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Protocol

from emulator.device import HostLine, LineSettings, ModemLines


class PortSink(Protocol):
    """Receives what a transport observes (implemented by the device runner)."""

    def host_attached(self, host: HostLine | None) -> None: ...

    def host_detached(self) -> None: ...

    def host_line(self, host: HostLine) -> None: ...

    def host_data(self, data: bytes) -> None: ...

    def room(self) -> int:
        """How many host bytes the transport may pass to `host_data` now (0: stop reading)."""
        ...

    def input_discarded(self, count: int) -> None:
        """`count` host bytes were thrown away unread (the host hung up with them still queued)."""
        ...

    def device_line(self) -> LineSettings:
        """The device's own line settings on this port now (a serial port is opened at them)."""
        ...

    def modem_lines(self) -> ModemLines:
        """The modem-status lines the device drives on this port (for transports that carry them)."""
        ...

    def line_error(self, byte: int, kind: str) -> None:
        """The port's UART received `byte` with a line error (`kind`: emulator/device.py
        FRAMING_ERROR or PARITY_ERROR), after the bytes already passed to `host_data` (a serial
        port reports them; other transports never see one)."""
        ...


class Transport(ABC):
    """One host-facing port. `write` is only called while a host is attached."""

    kind: str = ""
    #: The port is a physical line whose UARTs pace every character at the baud rate (a serial
    #: port): the runner hands the device's bytes over at the instants they start and takes the
    #: host's as the driver delivers them (complete), instead of pacing either direction again.
    wire_paces: bool = False

    @property
    @abstractmethod
    def path(self) -> str:
        """What a host opens: a link or device path, or a URL such as `socket://127.0.0.1:4001`."""

    @property
    def device_path(self) -> str | None:
        """The underlying device node (`/dev/pts/N`) when there is one."""
        return None

    @abstractmethod
    def open(self, sink: PortSink) -> None:
        """Create the port and start reporting to `sink` (inside the running event loop)."""

    @abstractmethod
    def write(self, data: bytes) -> int:
        """Send bytes to the attached host (never blocks); returns how many of them were dropped
        because the host is not taking output and the transport's bounded buffer is full."""

    def device_line_changed(self) -> None:
        """The device's own line settings changed (`PortSink.device_line` has the new ones): a
        transport whose port runs at them (a serial port) follows."""
        return None

    def resume_reading(self) -> None:
        """The sink has room again: read what was left waiting because `room()` was 0. Called from
        inside the sink's own processing, so a transport must read later, not within this call."""
        return None

    @abstractmethod
    def close(self) -> None:
        """Remove the port and everything it created on disk."""

    @abstractmethod
    def vanish(self) -> None:
        """Fault injection: the port disappears (the host sees a hang-up) until `reappear`."""

    @abstractmethod
    def reappear(self) -> None:
        """Undo `vanish`: the port exists again at the same path."""
