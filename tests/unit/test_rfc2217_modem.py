"""Modem lines on the RFC 2217 transport, seen by pyserial's own client
(emulator/hosting/transports/modem.py): the device's declared lines arrive in NOTIFY-MODEMSTATE; with the
device's RTS/CTS flow control the client's RTS holds the device's output and CTS follows the device's room for
input; a client that set RTS/CTS while CTS is off has its bytes held, not passed on, while its options are
still answered.

Every wait is for a condition (the sink's or the client's), never for a time; a client call that
sets a line returns once the server has acknowledged it, so what the server read before that
acknowledgement has been acted on by then."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Any

import pytest
import serial

from emulator.device import LineSettings, ModemLines
from emulator.hosting.transports.modem import HELD_INPUT_LIMIT
from emulator.hosting.transports.pty import OUTPUT_LIMIT
from emulator.hosting.transports.rfc2217 import Rfc2217Transport
from tests.unit.test_pty_flow import TIMEOUT, until
from tests.unit.test_tcp_transport import HostSink


class ModemSink(HostSink):
    """A device that declares `declared` lines and, with `flow`, does RTS/CTS flow control."""

    def __init__(self, space: int | None, declared: ModemLines, flow: bool) -> None:
        super().__init__(space)
        self.declared = declared
        self.flow = flow

    def device_line(self) -> LineSettings:
        return LineSettings(9600, 8, "none", 1, self.flow, False)

    def modem_lines(self) -> ModemLines:
        return self.declared


MS2000_LIKE = ModemLines()
MP285A_LIKE = ModemLines(cts=True)

Scenario = Callable[[ModemSink, Rfc2217Transport, serial.SerialBase], Awaitable[None]]


def run(sink: ModemSink, scenario: Scenario, **settings: Any) -> None:
    """`scenario(sink, transport, client)` with pyserial's client connected to a fresh port."""

    async def main() -> None:
        transport = Rfc2217Transport("127.0.0.1", 0)
        transport.open(sink)
        client = await asyncio.to_thread(serial.serial_for_url, transport.path, timeout=TIMEOUT, **settings)
        try:
            await scenario(sink, transport, client)
        finally:
            await asyncio.to_thread(client.close)
            await until(sink, lambda: sink.detached == 1)
            transport.close()

    asyncio.run(main())


async def client_lines(client: serial.SerialBase) -> tuple[bool, bool, bool, bool]:
    return await asyncio.to_thread(lambda: (client.cts, client.dsr, client.cd, client.ri))


async def eventually(condition: Callable[[], bool]) -> None:
    """Until `condition()` holds: the client learns of a change when the server's notice arrives
    (polled: the client has no event to wait on)."""

    async def poll() -> None:
        while not await asyncio.to_thread(condition):
            await asyncio.sleep(0.01)

    await asyncio.wait_for(poll(), TIMEOUT)


@pytest.mark.parametrize(
    "declared",
    [ModemLines(), ModemLines(cts=True, dsr=True), ModemLines(cd=True, ri=True)],
    ids=["none", "cts-dsr", "cd-ri"],
)
def test_the_client_reads_the_declared_lines(declared: ModemLines) -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        assert await client_lines(client) == (declared.cts, declared.dsr, declared.cd, declared.ri)

    run(ModemSink(None, declared, flow=False), scenario)


def test_rts_off_holds_the_output_of_a_device_with_flow_control(caplog: pytest.LogCaptureFixture) -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        await asyncio.to_thread(setattr, client, "rts", False)
        assert transport.write(b"\xff:A\r\n") == 0  # held, not dropped
        await asyncio.to_thread(setattr, client, "dtr", False)  # a round trip: nothing came first
        assert client.in_waiting == 0
        await asyncio.to_thread(setattr, client, "rts", True)
        assert await asyncio.to_thread(client.read, 5) == b"\xff:A\r\n"

    with caplog.at_level(logging.INFO, logger="stage_emu.rfc2217"):
        run(ModemSink(None, MP285A_LIKE, flow=True), scenario, rtscts=True)
    assert "host set RTS off: the device holds its output until RTS is on" in caplog.text
    assert "host set RTS on: the device sends again (5 bytes held meanwhile)" in caplog.text
    assert "host set DTR off (ignored: the device has no DTR input)" in caplog.text


def test_held_output_is_bounded_like_the_output_buffer() -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        await asyncio.to_thread(setattr, client, "rts", False)
        assert transport.write(bytes(OUTPUT_LIMIT - 10)) == 0
        assert transport.write(bytes(30)) == 20  # the newest bytes are dropped, and told
        await asyncio.to_thread(setattr, client, "rts", True)
        assert len(await asyncio.to_thread(client.read, OUTPUT_LIMIT)) == OUTPUT_LIMIT

    run(ModemSink(None, MP285A_LIKE, flow=True), scenario, rtscts=True)


def test_rts_goes_nowhere_without_flow_control() -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        await asyncio.to_thread(setattr, client, "rts", False)
        assert transport.write(b":A\r\n") == 0
        assert await asyncio.to_thread(client.read, 4) == b":A\r\n"

    run(ModemSink(None, MS2000_LIKE, flow=False), scenario)


def test_cts_follows_the_room_of_a_device_with_flow_control() -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        assert (await client_lines(client))[0] is True
        await asyncio.to_thread(client.write, b"0123456789")
        await until(sink, lambda: bytes(sink.data) == b"0123")  # the device's input is full
        await eventually(lambda: not client.cts)
        sink.space = 100
        transport.resume_reading()  # the runner's call once room has reopened
        await until(sink, lambda: bytes(sink.data) == b"0123456789")
        await eventually(lambda: client.cts)

    run(ModemSink(4, MP285A_LIKE, flow=True), scenario, rtscts=True)


def test_a_client_with_rtscts_cannot_send_while_cts_is_off(caplog: pytest.LogCaptureFixture) -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        await asyncio.to_thread(client.write, b"V\r")
        await asyncio.to_thread(setattr, client, "dtr", False)  # answered: the bytes were read
        assert sink.data == b""
        await asyncio.to_thread(setattr, client, "rtscts", False)
        await until(sink, lambda: bytes(sink.data) == b"V\r")

    with caplog.at_level(logging.INFO, logger="stage_emu.rfc2217"):
        run(ModemSink(None, MS2000_LIKE, flow=False), scenario, rtscts=True)
    assert "the device does not assert CTS: its bytes wait in its transmit buffer (2 so far)" in caplog.text
    assert "2 bytes the host held back for CTS go to the device" in caplog.text


def test_a_purge_of_the_transmit_buffer_drops_the_held_bytes() -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        await asyncio.to_thread(client.write, b"V\r")
        await asyncio.to_thread(client.reset_output_buffer)  # PURGE-DATA 2, acknowledged
        await asyncio.to_thread(setattr, client, "rtscts", False)
        await asyncio.to_thread(client.write, b"W\r")
        await until(sink, lambda: bytes(sink.data) == b"W\r")

    run(ModemSink(None, MS2000_LIKE, flow=False), scenario, rtscts=True)


def test_held_bytes_are_discarded_when_the_client_hangs_up() -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        await asyncio.to_thread(client.write, b"V\r")
        await asyncio.to_thread(setattr, client, "dtr", False)
        await asyncio.to_thread(client.close)
        await until(sink, lambda: sink.discarded == 2)
        assert sink.data == b""

    run(ModemSink(None, MS2000_LIKE, flow=False), scenario, rtscts=True)


def test_a_full_transmit_buffer_stops_reading_until_it_may_send() -> None:
    async def scenario(sink: ModemSink, transport: Rfc2217Transport, client: serial.SerialBase) -> None:
        flood = bytes(range(1, 256)) * (2 * HELD_INPUT_LIMIT // 255)
        writer = asyncio.create_task(asyncio.to_thread(client.write, flood))
        await eventually(lambda: len(transport._held_in) >= HELD_INPUT_LIMIT)
        assert len(transport._held_in) < HELD_INPUT_LIMIT + 256  # one read slice beyond at most
        sink.declared = ModemLines(cts=True)  # the device asserts CTS: the bytes cross
        transport.resume_reading()
        await writer
        await until(sink, lambda: bytes(sink.data) == flood)

    run(ModemSink(None, MS2000_LIKE, flow=False), scenario, rtscts=True)
