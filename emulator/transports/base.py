"""What every transport offers the device host. Transports move bytes and report line settings;
they never parse the protocol."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Protocol

from emulator.device import LineSettings


class PortSink(Protocol):
    """Receives what a transport observes (implemented by the device runner)."""

    def host_attached(self, host: LineSettings | None) -> None: ...

    def host_detached(self) -> None: ...

    def host_line(self, host: LineSettings) -> None: ...

    def host_data(self, data: bytes) -> None: ...


class Transport(ABC):
    """One host-facing port. `write` is only called while a host is attached."""

    kind: str = ""

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
    def write(self, data: bytes) -> None:
        """Send bytes to the attached host (never blocks; buffers if the host is slow)."""

    @abstractmethod
    def close(self) -> None:
        """Remove the port and everything it created on disk."""

    @abstractmethod
    def vanish(self) -> None:
        """Fault injection: the port disappears (the host sees a hang-up) until `reappear`."""

    @abstractmethod
    def reappear(self) -> None:
        """Undo `vanish`: the port exists again at the same path."""
