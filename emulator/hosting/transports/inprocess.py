"""A port inside the host's own process: the host program calls `attach`, `send` and `take` directly
(the `stageemu://` pyserial URL handler, emulator/urlhandler/). No file descriptor, thread or event
loop: whoever holds it pumps the runner.
"""

from __future__ import annotations

from emulator.device import HostLine
from emulator.hosting.transports.base import PortSink, Transport

#: Device output the host has not read yet, in bytes: its receive buffer. What does not fit is
#: dropped (the newest bytes), as a real UART overruns; about what a daemon's PTY holds for a host
#: that does not read (the kernel's buffer and the PTY transport's own).
RECEIVE_BUFFER = 16384


class InProcessTransport(Transport):
    kind = "inprocess"

    def __init__(self, url: str, receive_buffer: int = RECEIVE_BUFFER) -> None:
        self._url = url
        self._limit = receive_buffer
        self._sink: PortSink | None = None
        #: device output waiting for the host to read it
        self.received = bytearray()
        #: a `disconnect` fault took the port away (until `reappear`)
        self.vanished = False

    @property
    def path(self) -> str:
        return self._url

    def open(self, sink: PortSink) -> None:
        self._sink = sink

    def _port(self) -> PortSink:
        if self._sink is None:
            raise RuntimeError("the transport is not attached to a runner yet")
        return self._sink

    # ---- the host's side ------------------------------------------------------------------------

    def attach(self, host: HostLine) -> None:
        """The host opened the port with these settings."""
        self._port().host_attached(host)

    def detach(self) -> None:
        """The host closed the port (the runner keeps it, for the next host to open)."""
        self._port().host_detached()
        self.received.clear()

    def change_line(self, host: HostLine) -> None:
        self._port().host_line(host)

    def room(self) -> int:
        """Host bytes the emulated wire takes now (0 while the device's side is backed up)."""
        return self._port().room()

    def send(self, data: bytes) -> None:
        self._port().host_data(data)

    def take(self, count: int) -> bytes:
        """Up to `count` received bytes, oldest first."""
        data = bytes(self.received[:count])
        del self.received[:count]
        return data

    # ---- the runner's side ----------------------------------------------------------------------

    def write(self, data: bytes) -> int:
        room = max(self._limit - len(self.received), 0)
        self.received += data[:room]
        return max(len(data) - room, 0)

    def close(self) -> None:
        if self._sink is not None:
            sink, self._sink = self._sink, None
            sink.host_detached()
        self.received.clear()

    def vanish(self) -> None:
        self.vanished = True
        self.received.clear()

    def reappear(self) -> None:
        self.vanished = False
