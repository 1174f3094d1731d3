"""The serial transport in this process, on a null-modem cable of two pseudo-terminals
(tests/support/nullmodem.py) and on a pyserial URL: bytes both ways unchanged (a data FF included,
which the kernel doubles under PARMRK), the device's settings followed, settings a port does not
take refused, reading stopped at no room and resumed, output bounded, an unplugged port reopened on
a timer, line errors handed over in their place, and what the MP-285 makes of them (MP-6)."""

from __future__ import annotations

import asyncio
import logging
import os
import socket
import termios
from collections.abc import Callable
from pathlib import Path

import pytest
import serial

from emulator.device import FRAMING_ERROR, PARITY_ERROR, DeviceServices, HostLine, LineSettings, ModemLines
from emulator.hosting.clock import ManualClock
from emulator.hosting.line_errors import UNSEEN_HOST
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.trafficlog import TrafficLog
from emulator.hosting.transports.pty import OUTPUT_LIMIT, PortError
from emulator.hosting.transports.serial import REOPEN_S, SerialHost, SerialTransport
from emulator.hosting.transports.serial_io import FdIo
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST
from tests.support.memory_transport import MemoryTransport
from tests.support.nullmodem import NullModem

TIMEOUT = 5.0
LINE = LineSettings(9600, 8, "none", 1, False, False)


class Sink:
    """Plays the runner: records what the transport reports; `space` bytes of room (None: always)."""

    def __init__(self, space: int | None = None, line: LineSettings = LINE) -> None:
        self.space = space
        self.line = line
        self.data = bytearray()
        #: data runs and line errors, in order
        self.pieces: list[bytes | tuple[int, str]] = []
        self.hosts: list[HostLine | None] = []
        self.changed = asyncio.Event()

    def _note(self) -> None:
        self.changed.set()

    def host_attached(self, host: HostLine | None) -> None:
        self.hosts.append(host)
        self._note()

    def host_detached(self) -> None:
        self.hosts.append(None)
        self._note()

    def host_line(self, host: HostLine) -> None:
        raise AssertionError("a serial line shows no host settings")

    def host_data(self, data: bytes) -> None:
        if self.space is not None:
            assert len(data) <= self.space, "read more than the room it was given"
            self.space -= len(data)
        self.data += data
        self.pieces.append(bytes(data))
        self._note()

    def line_error(self, byte: int, kind: str) -> None:
        self.pieces.append((byte, kind))
        self._note()

    def room(self) -> int:
        return 1 << 20 if self.space is None else self.space

    def input_discarded(self, count: int) -> None:
        raise AssertionError("a serial port discards nothing at a hang-up")

    def device_line(self) -> LineSettings:
        return self.line

    def modem_lines(self) -> ModemLines:
        return ModemLines()

    @property
    def attached(self) -> bool:
        return bool(self.hosts) and self.hosts[-1] is not None

    async def until(self, condition: Callable[[], bool], timeout: float = TIMEOUT) -> None:
        async def wait() -> None:
            while not condition():
                self.changed.clear()
                await self.changed.wait()

        await asyncio.wait_for(wait(), timeout)


async def host_reads(port: serial.Serial, count: int) -> bytes:
    """`count` bytes from the host's end, read off the loop's thread."""
    return await asyncio.to_thread(port.read, count)


def test_bytes_cross_unchanged_both_ways(tmp_path: Path) -> None:
    """Every byte value, a data FF among them (PARMRK doubles it in the kernel; the transport
    undoes that). The host is attached from open, its settings described as not visible."""

    async def scenario() -> None:
        sink = Sink()
        with NullModem(tmp_path) as cable:
            transport = SerialTransport(str(cable.device_link))
            transport.open(sink)
            assert sink.hosts == [SerialHost()]
            assert SerialHost().describe() == UNSEEN_HOST
            assert transport.device_path == os.path.realpath(cable.device_link)
            every = bytes(range(256)) * 2
            with serial.Serial(str(cable.host_link), 9600, timeout=TIMEOUT) as host:
                host.write(every)
                await sink.until(lambda: len(sink.data) == len(every))
                assert bytes(sink.data) == every
                assert transport.write(every) == 0
                assert await host_reads(host, len(every)) == every
            transport.close()
            assert sink.hosts[-1] is None

    asyncio.run(scenario())


def test_the_port_follows_the_device_settings(tmp_path: Path) -> None:
    """The MS2000's `SB X=2` (MS-3): the port changes to 2 stop bits at once, line errors still
    marked (pyserial clears PARMRK whenever it configures the port)."""

    async def scenario() -> None:
        sink = Sink()
        with NullModem(tmp_path) as cable:
            transport = SerialTransport(str(cable.device_link))
            transport.open(sink)
            assert cable.device_settings().stop_bits == 1
            sink.line = LineSettings(19200, 8, "none", 2, False, False)
            transport.device_line_changed()
            seen = cable.device_settings()
            assert (seen.baud, seen.stop_bits) == (19200, 2)
            fd = os.open(cable.device_link, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            try:
                assert termios.tcgetattr(fd)[0] & termios.PARMRK
            finally:
                os.close(fd)
            transport.close()

    asyncio.run(scenario())


def test_settings_the_port_does_not_take_are_refused(tmp_path: Path) -> None:
    """A pseudo-terminal keeps 8 data bits and no parity: a 7E1 device cannot be served on it."""

    async def scenario() -> None:
        with NullModem(tmp_path) as cable:
            transport = SerialTransport(str(cable.device_link))
            with pytest.raises(PortError) as info:
                transport.open(Sink(line=LineSettings(9600, 7, "even", 1, False, False)))
            assert str(info.value) == (
                f"serial port {cable.device_link}: does not support 7 data bits (it keeps 8), "
                "even parity (it keeps none)"
            )
            transport.open(Sink())  # the port was closed: it opens again
            transport.close()

    asyncio.run(scenario())


def test_reading_stops_at_no_room_and_resumes(tmp_path: Path) -> None:
    async def scenario() -> None:
        sink = Sink(space=10)
        with NullModem(tmp_path) as cable:
            transport = SerialTransport(str(cable.device_link))
            transport.open(sink)
            with serial.Serial(str(cable.host_link), 9600, timeout=TIMEOUT) as host:
                host.write(b"x" * 1000)
                await sink.until(lambda: len(sink.data) == 10)
                for _ in range(20):
                    await asyncio.sleep(0)
                assert len(sink.data) == 10
                sink.space = None
                transport.resume_reading()
                await sink.until(lambda: len(sink.data) == 1000)
            transport.close()

    asyncio.run(scenario())


def test_output_the_host_does_not_take_is_bounded() -> None:
    """Nobody reads the far end: what the driver and OUTPUT_LIMIT do not hold is dropped, counted."""

    async def scenario() -> None:
        master, slave = os.openpty()
        try:
            transport = SerialTransport(os.ttyname(slave))
            transport.open(Sink())
            sent = dropped = 0
            while dropped == 0 and sent < 1 << 22:
                dropped = transport.write(b"y" * 4096)
                sent += 4096
            assert 0 < dropped <= 4096
            assert transport.write(b"z") == 1  # full: the newest byte is the one lost
            transport.close()
        finally:
            os.close(slave)
            os.close(master)

    assert OUTPUT_LIMIT == 4096
    asyncio.run(scenario())


def test_an_unplugged_port_is_a_hangup_and_is_reopened(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """One line when it goes, one when it is back; tried again on a timer meanwhile."""

    async def scenario() -> None:
        sink = Sink()
        with NullModem(tmp_path) as cable:
            transport = SerialTransport(str(cable.device_link))
            transport.open(sink)
            cable.unplug()
            await sink.until(lambda: not sink.attached)
            await asyncio.sleep(3 * REOPEN_S)  # a few failed tries: no line each
            cable.replug()
            await sink.until(lambda: sink.attached)
            with serial.Serial(str(cable.host_link), 9600, timeout=TIMEOUT) as host:
                host.write(b"again")
                await sink.until(lambda: sink.data.endswith(b"again"))
            transport.close()
        assert sink.hosts == [SerialHost(), None, SerialHost(), None]

    with caplog.at_level(logging.WARNING, logger="stage_emu.serial"):
        asyncio.run(scenario())
    assert [r.getMessage().split(": ", 1)[1] for r in caplog.records] == [
        f"serial port gone (hang-up); trying to reopen it every {REOPEN_S:g} s",
        "serial port is back",
    ]


def test_vanish_and_reappear_close_and_reopen_the_port(tmp_path: Path) -> None:
    async def scenario() -> None:
        sink = Sink()
        with NullModem(tmp_path) as cable:
            transport = SerialTransport(str(cable.device_link))
            transport.open(sink)
            transport.vanish()
            assert sink.hosts == [SerialHost(), None]
            other = serial.Serial(str(cable.device_link), exclusive=True)  # closed: free for others
            other.close()
            transport.reappear()
            assert sink.hosts == [SerialHost(), None, SerialHost()]
            transport.close()

    asyncio.run(scenario())


def test_line_errors_are_handed_over_in_their_place() -> None:
    """The kernel's marks, as a pipe stands in for the port: FF 00 X is X with an error, in order
    with the data around it."""

    async def scenario() -> None:
        sink = Sink()
        read_end, write_end = os.pipe()
        gone: list[str] = []

        def hung_up(reason: str) -> None:
            gone.append(reason)
            sink.changed.set()

        FdIo(read_end, asyncio.get_running_loop(), sink, hung_up)
        os.write(write_end, b"\x63\xff\x00\x63\x0d\xff\xff\xff")
        await sink.until(lambda: len(sink.pieces) == 3)
        os.write(write_end, b"\x00\x00")  # a break, its mark split across two reads
        await sink.until(lambda: len(sink.pieces) == 4)
        assert sink.pieces == [b"\x63", (0x63, FRAMING_ERROR), b"\x0d\xff", (0x00, FRAMING_ERROR)]
        os.close(write_end)
        await sink.until(lambda: bool(gone))
        assert gone == ["hang-up"]
        os.close(read_end)

    asyncio.run(scenario())


def test_a_url_port_is_served_through_threads() -> None:
    """A port without a descriptor the loop can watch (here `socket://`): a reader and a writer
    thread; the far end closing is a hang-up."""

    async def scenario() -> None:
        with socket.create_server(("127.0.0.1", 0)) as server:
            url = f"socket://127.0.0.1:{server.getsockname()[1]}"
            sink = Sink()
            transport = SerialTransport(url)
            transport.open(sink)
            assert transport.device_path is None and sink.attached
            peer, _ = await asyncio.to_thread(server.accept)
            peer.sendall(b"W X\r")
            await sink.until(lambda: bytes(sink.data) == b"W X\r")
            assert transport.write(b":A 0\r\n") == 0
            assert await asyncio.to_thread(peer.recv, 100) == b":A 0\r\n"
            peer.close()
            await sink.until(lambda: not sink.attached)
            again, _ = await asyncio.to_thread(server.accept)  # reopened on the timer
            await sink.until(lambda: sink.attached)
            transport.close()
            again.close()

    asyncio.run(scenario())


# ---- what the model makes of a line error --------------------------------------------------------


def mp285_runner(traffic: TrafficLog | None = None) -> tuple[DeviceRunner, MemoryTransport]:
    profile = load_profile("mp285")
    clock = ManualClock()
    runner = DeviceRunner(
        lambda now: family("mp285").factory("mp285", profile, now, DeviceServices()),
        clock,
        traffic=traffic,
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, FAST)
    port.attach(SerialHost())
    clock.advance(2.0)  # past the power-on silence (MP-76)
    return runner, port


def test_a_framing_error_raises_error_1_on_the_mp285(tmp_path: Path) -> None:
    """MP-6 item 4: `63` received with a framing error is not a data byte, and the clean `0D` that
    follows ends the frame with error '1' (`31 0D`); a parity error is ignored (item 3): `63 0D` is
    then a position request."""
    log = tmp_path / "traffic.jsonl"
    traffic = TrafficLog(log)
    _, port = mp285_runner(traffic)
    sink = port.sink
    assert sink is not None
    sink.line_error(0x63, FRAMING_ERROR)
    port.send(b"\r")
    assert port.take() == b"1\r"
    sink.line_error(0x63, PARITY_ERROR)
    port.send(b"\r")
    assert len(port.take()) == 13  # X, Y, Z and CR (MP-13)
    traffic.close()
    notes = [line for line in log.read_text().splitlines() if '"garbled"' in line]
    assert len(notes) == 2 and "the UART received 63 with a framing error" in notes[0]
    assert UNSEEN_HOST in notes[0]


class FollowingTransport(MemoryTransport):
    """Records the device's settings each time the runner says they changed."""

    def __init__(self) -> None:
        super().__init__()
        self.followed: list[LineSettings] = []

    def device_line_changed(self) -> None:
        assert self.sink is not None
        self.followed.append(self.sink.device_line())


def test_the_port_is_told_when_the_device_settings_change_also_after_a_reset() -> None:
    """MS-3 `SB X=2`, a factory reset (a new model, back at 1 stop bit: `SB` was not saved), `SB X=2`
    again: the transport is told each time, with the current model's settings."""
    profile = load_profile("ms2000")
    runner = DeviceRunner(
        lambda now: family("ms2000").factory("ms2000", profile, now, DeviceServices()), ManualClock()
    )
    port = FollowingTransport()
    runner.attach_transport("main", port, FAST)
    port.attach(SerialHost())
    port.send(b"SB X=2\r")
    assert port.take() == b":A\r\n"
    runner.reset()
    port.send(b"SB X=2\r")
    assert [line.stop_bits for line in port.followed] == [2, 1, 2]
