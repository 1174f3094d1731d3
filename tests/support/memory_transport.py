"""An in-memory transport: tests play the host by calling its `host_*` methods."""

from __future__ import annotations

from emulator.device import HostLine
from emulator.hosting.transports.base import PortSink, Transport


class MemoryTransport(Transport):
    kind = "memory"

    def __init__(self, output_limit: int | None = None) -> None:
        self.sink: PortSink | None = None
        #: what the host has received and not yet taken; at most `output_limit` bytes (None: no limit)
        self.written = bytearray()
        self.writes: list[bytes] = []
        self.output_limit = output_limit
        self.resumes = 0
        self.vanished = False
        self.closed = False

    @property
    def path(self) -> str:
        return "memory://"

    def open(self, sink: PortSink) -> None:
        self.sink = sink

    def write(self, data: bytes) -> int:
        self.writes.append(bytes(data))
        room = len(data) if self.output_limit is None else max(self.output_limit - len(self.written), 0)
        self.written += data[:room]
        return max(len(data) - room, 0)

    def resume_reading(self) -> None:
        self.resumes += 1

    def close(self) -> None:
        self.closed = True

    def vanish(self) -> None:
        self.vanished = True

    def reappear(self) -> None:
        self.vanished = False

    def attach(self, host: HostLine | None = None) -> None:
        assert self.sink is not None
        self.sink.host_attached(host)

    def send(self, data: bytes) -> None:
        assert self.sink is not None
        self.sink.host_data(data)

    def room(self) -> int:
        assert self.sink is not None
        return self.sink.room()

    def take(self) -> bytes:
        data = bytes(self.written)
        self.written.clear()
        return data
