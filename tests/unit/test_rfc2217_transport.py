"""The RFC 2217 transport on loopback: pyserial's own client negotiates line settings that reach the
sink as one `HostLine` (parity and data bits included), data bytes 0xFF survive telnet escaping
both ways, and malformed or oversized options end only that connection."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct

import pytest
import serial
from serial import rfc2217

from emulator.device import HostLine
from emulator.transports.rfc2217 import MAX_SUBOPTION, Rfc2217Transport
from tests.unit.test_pty_flow import until
from tests.unit.test_tcp_transport import HostSink

SB_COM = rfc2217.IAC + rfc2217.SB + rfc2217.COM_PORT_OPTION


def serve(sink: HostSink) -> tuple[Rfc2217Transport, int]:
    transport = Rfc2217Transport("127.0.0.1", 0)
    transport.open(sink)
    return transport, int(transport.path.rsplit(":", 1)[1])


def test_pyserial_settings_reach_the_device_as_one_host_line_and_data_is_escaped() -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        assert transport.path == f"rfc2217://127.0.0.1:{port}"
        settings = {"baudrate": 19200, "bytesize": 7, "parity": serial.PARITY_EVEN, "stopbits": 2}
        client = await asyncio.to_thread(
            serial.serial_for_url, transport.path, rtscts=True, timeout=5, **settings
        )
        try:
            await until(sink, lambda: len(sink.lines) == 1)
            assert sink.hosts == [HostLine()]  # nothing negotiated yet at the connection
            assert sink.lines == [HostLine(19200, 7, "even", 2, True, False)]
            await asyncio.to_thread(client.write, b"\xffV\r")
            await until(sink, lambda: bytes(sink.data) == b"\xffV\r")
            assert transport.write(b"\xff:A\r\n") == 0
            assert await asyncio.to_thread(client.read, 5) == b"\xff:A\r\n"
        finally:
            await asyncio.to_thread(client.close)
        await until(sink, lambda: sink.detached == 1)
        assert len(sink.lines) == 1
        transport.close()

    asyncio.run(scenario())


def test_a_lone_setting_is_applied_once_the_client_stops_negotiating() -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        _, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(SB_COM + rfc2217.SET_BAUDRATE + struct.pack("!I", 4800) + rfc2217.IAC + rfc2217.SE)
        await until(sink, lambda: len(sink.lines) == 1)
        assert sink.lines == [HostLine(baud=4800)]  # the rest unseen: the device's own apply
        writer.close()
        await until(sink, lambda: sink.detached == 1)
        transport.close()

    asyncio.run(scenario())


@pytest.mark.parametrize(
    "bad",
    [
        SB_COM + rfc2217.SET_BAUDRATE + b"\x01" + rfc2217.IAC + rfc2217.SE,  # a baud rate of one byte
        SB_COM + rfc2217.SET_PARITY + b"\x09" + rfc2217.IAC + rfc2217.SE,  # no such parity
        rfc2217.IAC + rfc2217.SE,  # the end of a subnegotiation never begun
        SB_COM + b"x" * (MAX_SUBOPTION + 300),  # a subnegotiation that never ends
    ],
    ids=["short", "unknown-parity", "stray-SE", "oversized"],
)
def test_bad_options_end_that_connection_only(bad: bytes, caplog: pytest.LogCaptureFixture) -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(b"ok" + bad + b"never seen")
        await until(sink, lambda: sink.detached == 1)
        assert bytes(sink.data) in (b"", b"ok")  # data read with the bad option goes with it
        with contextlib.suppress(ConnectionResetError):  # reset when it closed with input unread
            await asyncio.wait_for(reader.read(), 5)  # returns at the end: the server closed it
        writer.close()
        with socket.create_connection(("127.0.0.1", port)) as again:  # the port itself lives on
            await until(sink, lambda: sink.attached == 2)
            again.sendall(b"fine")
            await until(sink, lambda: sink.data.endswith(b"fine"))
        transport.close()

    with caplog.at_level(logging.WARNING, "stage_emu.rfc2217"):
        asyncio.run(scenario())
    assert [r for r in caplog.records if "disconnecting" in r.message]
