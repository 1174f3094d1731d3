"""An in-memory transport: tests play the host by calling its `host_*` methods."""

from __future__ import annotations

from emulator.device import LineSettings
from emulator.transports.base import PortSink, Transport


class MemoryTransport(Transport):
    kind = "memory"

    def __init__(self) -> None:
        self.sink: PortSink | None = None
        self.written = bytearray()
        self.writes: list[bytes] = []
        self.vanished = False
        self.closed = False

    @property
    def path(self) -> str:
        return "memory://"

    def open(self, sink: PortSink) -> None:
        self.sink = sink

    def write(self, data: bytes) -> None:
        self.written += data
        self.writes.append(bytes(data))

    def close(self) -> None:
        self.closed = True

    def vanish(self) -> None:
        self.vanished = True

    def reappear(self) -> None:
        self.vanished = False

    def attach(self, host: LineSettings | None = None) -> None:
        assert self.sink is not None
        self.sink.host_attached(host)

    def send(self, data: bytes) -> None:
        assert self.sink is not None
        self.sink.host_data(data)

    def take(self) -> bytes:
        data = bytes(self.written)
        self.written.clear()
        return data
