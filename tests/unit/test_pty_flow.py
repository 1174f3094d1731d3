"""Flow control of the PTY transport against a real pseudo-terminal: it reads no more than its sink
has room for, resumes on its own, serves ports in slices, still sees hang-ups and settings changes
while paused, and bounds the output a host does not read."""

from __future__ import annotations

import asyncio
import errno
import os
import termios
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from emulator.device import LineSettings, ModemLines
from emulator.hosting.transports.pty import EXTPROC, OUTPUT_LIMIT, READ_CHUNK, PtyTransport

TIMEOUT = 5.0


class Sink:
    """Plays the runner: `space` bytes of room, used up by what the transport hands over (None:
    always room, as on a fast port)."""

    def __init__(self, space: int | None, ticks: Callable[[], int] = lambda: 0) -> None:
        self.space = space
        self.data = bytearray()
        self.overruns = 0
        self.attached = self.detached = self.discarded = 0
        self.lines: list[LineSettings] = []
        self.deliveries: dict[int, int] = {}  # loop tick -> bytes handed over in it
        self._ticks = ticks
        self.changed = asyncio.Event()

    def host_attached(self, host: LineSettings | None) -> None:
        self.attached += 1
        self.changed.set()

    def host_detached(self) -> None:
        self.detached += 1
        self.changed.set()

    def host_line(self, host: LineSettings) -> None:
        self.lines.append(host)
        self.changed.set()

    def host_data(self, data: bytes) -> None:
        if len(data) > self.room():
            self.overruns += 1
        if self.space is not None:
            self.space -= len(data)
        self.data += data
        tick = self._ticks()
        self.deliveries[tick] = self.deliveries.get(tick, 0) + len(data)
        self.changed.set()

    def room(self) -> int:
        return 1 << 20 if self.space is None else self.space

    def input_discarded(self, count: int) -> None:
        self.discarded += count
        self.changed.set()

    def device_line(self) -> LineSettings:
        return LineSettings(9600, 8, "none", 1, False, False)

    def modem_lines(self) -> ModemLines:
        """A device ready to receive, for transports that carry modem lines."""
        return ModemLines(cts=True, dsr=True)


async def until(sink: Sink, condition: Callable[[], bool]) -> None:
    while not condition():
        sink.changed.clear()
        await asyncio.wait_for(sink.changed.wait(), TIMEOUT)


@contextmanager
def host(path: Path) -> Iterator[int]:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        yield fd
    finally:
        os.close(fd)


def write_all_it_takes(fd: int, data: bytes) -> int:
    """Write until the kernel refuses (EAGAIN); returns how much it took."""
    taken = 0
    try:
        while taken < len(data):
            taken += os.write(fd, data[taken:])
    except BlockingIOError:
        pass
    return taken


def open_port(tmp_path: Path, name: str, sink: Sink) -> PtyTransport:
    transport = PtyTransport(tmp_path / name)
    transport.open(sink)
    return transport


def test_reads_no_more_than_room_and_resumes_on_its_own(tmp_path: Path) -> None:
    async def scenario() -> None:
        sink = Sink(10)
        transport = open_port(tmp_path, "port", sink)
        flood = bytes(range(256)) * 400
        with host(tmp_path / "port") as fd:
            taken = write_all_it_takes(fd, flood)
            assert taken < 32 * 1024, "the host's write must block while the port does not read"
            await until(sink, lambda: len(sink.data) == 10)
            for _ in range(5):
                await asyncio.sleep(0)  # let any further edge be handled: nothing may be read
            assert len(sink.data) == 10
            sink.space = 100_000
            transport.resume_reading()  # no new edge comes: the transport must read by itself
            await until(sink, lambda: len(sink.data) == taken)
        assert bytes(sink.data) == flood[:taken] and sink.overruns == 0
        transport.close()

    asyncio.run(scenario())


def test_hangup_while_paused_detaches_and_counts_what_was_discarded(tmp_path: Path) -> None:
    async def scenario() -> None:
        sink = Sink(10)
        transport = open_port(tmp_path, "port", sink)
        with host(tmp_path / "port") as fd:
            assert os.write(fd, b"x" * 100) == 100
            await until(sink, lambda: len(sink.data) == 10)
        await until(sink, lambda: sink.detached == 1)
        assert (sink.attached, sink.discarded, len(sink.data)) == (1, 90, 10)
        transport.close()

    asyncio.run(scenario())


def test_settings_change_while_paused_is_seen_when_reading_resumes(tmp_path: Path) -> None:
    async def scenario() -> None:
        sink = Sink(10)
        transport = open_port(tmp_path, "port", sink)
        with host(tmp_path / "port") as fd:
            assert os.write(fd, b"y" * 100) == 100
            await until(sink, lambda: len(sink.data) == 10)
            attrs = termios.tcgetattr(fd)
            attrs[4] = attrs[5] = termios.B19200
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
            sink.space = 1000
            transport.resume_reading()
            await until(sink, lambda: len(sink.data) == 100 and bool(sink.lines))
        assert sink.lines[-1].baud == 19200 and bytes(sink.data) == b"y" * 100
        transport.close()

    asyncio.run(scenario())


def test_a_flooding_port_is_read_in_slices_and_others_are_served(tmp_path: Path) -> None:
    async def scenario() -> None:
        loop = asyncio.get_running_loop()
        ticks = 0

        def tick() -> None:
            nonlocal ticks
            ticks += 1
            loop.call_soon(tick)

        tick()
        flooded, quiet = Sink(None, lambda: ticks), Sink(None, lambda: ticks)
        ports = [open_port(tmp_path, name, sink) for name, sink in (("a", flooded), ("b", quiet))]
        with host(tmp_path / "a") as fd_a, host(tmp_path / "b") as fd_b:
            taken = write_all_it_takes(fd_a, b"z" * 100_000)
            assert os.write(fd_b, b"ping") == 4
            await until(quiet, lambda: quiet.data == b"ping")
            await until(flooded, lambda: len(flooded.data) == taken)
        # One slice per wakeup: at most the scheduled continuation plus a fresh edge in one loop pass.
        assert len(flooded.deliveries) >= 2, flooded.deliveries
        assert max(flooded.deliveries.values()) <= 2 * READ_CHUNK, flooded.deliveries
        for port in ports:
            port.close()

    asyncio.run(scenario())


def test_output_the_host_does_not_read_is_bounded_and_flows_again(tmp_path: Path) -> None:
    async def scenario() -> None:
        sink = Sink(1000)
        transport = open_port(tmp_path, "port", sink)
        with host(tmp_path / "port") as fd:
            os.write(fd, b"!")
            await until(sink, lambda: sink.attached == 1)
            offered = dropped = 0
            while dropped == 0:
                dropped = transport.write(b"o" * 1000)
                offered += 1000
            for _ in range(100):  # well past the limit: everything more is dropped, nothing piles up
                assert transport.write(b"o" * 1000) == 1000
            received = bytearray()
            while len(received) < offered - dropped:
                await loop_readable(fd)
                received += read_available(fd)
            assert bytes(received) == b"o" * (offered - dropped)
            assert offered - dropped < 64 * 1024 + OUTPUT_LIMIT
            assert transport.write(b"fresh") == 0
            await loop_readable(fd)
            assert read_available(fd) == b"fresh"
        transport.close()

    asyncio.run(scenario())


async def loop_readable(fd: int) -> None:
    loop = asyncio.get_running_loop()
    ready = loop.create_future()
    loop.add_reader(fd, lambda: ready.done() or ready.set_result(None))
    try:
        await asyncio.wait_for(ready, TIMEOUT)
    finally:
        loop.remove_reader(fd)


def read_available(fd: int) -> bytes:
    chunks = []
    while True:
        try:
            chunks.append(os.read(fd, 65536))
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK):
                return b"".join(chunks)
            raise


def test_a_host_that_clears_extproc_still_has_its_settings_seen_with_its_data(tmp_path: Path) -> None:
    """With EXTPROC set, settings changes are announced and data packets cost no settings read; a
    host that clears it announces that once, and from then on its settings are read with its data."""

    def set_attrs(fd: int, speed: int, clear_extproc: bool = False) -> None:
        attrs = termios.tcgetattr(fd)
        attrs[4] = attrs[5] = speed
        if clear_extproc:
            attrs[3] &= ~EXTPROC
        termios.tcsetattr(fd, termios.TCSANOW, attrs)

    async def scenario() -> None:
        sink = Sink(None)
        transport = open_port(tmp_path, "port", sink)
        with host(tmp_path / "port") as fd:
            set_attrs(fd, termios.B19200)  # the first announcement attaches the host
            await until(sink, lambda: sink.attached == 1)
            set_attrs(fd, termios.B4800, clear_extproc=True)  # announced: the old settings had it
            await until(sink, lambda: bool(sink.lines) and sink.lines[-1].baud == 4800)
            set_attrs(fd, termios.B2400)  # not announced any more
            assert os.write(fd, b"z") == 1
            await until(sink, lambda: bytes(sink.data) == b"z")
        assert sink.lines[-1].baud == 2400
        transport.close()

    asyncio.run(scenario())
