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
from emulator.hosting.transports.rfc2217 import MAX_SUBOPTION, Rfc2217Transport, describe_bad_option
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


def sub(command: bytes, value: bytes) -> bytes:
    return SB_COM + command + value + rfc2217.IAC + rfc2217.SE


@pytest.mark.parametrize(
    ("bad", "told"),
    [
        (sub(rfc2217.SET_BAUDRATE, b"\x25\x80"), "SET-BAUDRATE with 2 value bytes (expected 4)"),
        (sub(rfc2217.SET_BAUDRATE, b""), "SET-BAUDRATE with 0 value bytes (expected 4)"),
        (sub(rfc2217.SET_DATASIZE, b""), "SET-DATASIZE with 0 value bytes (expected 1)"),
        (sub(rfc2217.SET_PARITY, b"\x09"), "SET-PARITY with value 9 (expected one of 0, 1, 2, 3, 4, 5)"),
        (sub(rfc2217.SET_STOPSIZE, b"\x07"), "SET-STOPSIZE with value 7 (expected one of 0, 1, 2, 3)"),
        (sub(rfc2217.SET_MODEMSTATE_MASK, b""), "SET-MODEMSTATE-MASK with 0 value bytes (expected 1)"),
        (rfc2217.IAC + rfc2217.SE, "IAC SE with no subnegotiation begun (no IAC SB before it)"),
    ],
    ids=["baud-2", "baud-0", "datasize-0", "parity-9", "stopsize-7", "modemstate-mask-0", "stray-SE"],
)
def test_a_malformed_option_is_told_in_rfc2217_terms(
    bad: bytes, told: str, caplog: pytest.LogCaptureFixture
) -> None:
    """The line said pyserial's own words ("unpack requires a buffer of 4 bytes", "9")."""

    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        _, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(bad)
        await until(sink, lambda: sink.detached == 1)
        writer.close()
        transport.close()

    with caplog.at_level(logging.WARNING, "stage_emu.rfc2217"):
        asyncio.run(scenario())
    lines = [r.getMessage() for r in caplog.records if "disconnecting" in r.getMessage()]
    assert len(lines) == 1 and lines[0].endswith(f"sent a malformed telnet option: {told}; disconnecting"), (
        lines
    )


@pytest.mark.parametrize(
    ("suboption", "told"),
    [
        (b"\x2c\x01\x00\x00\x25", "SET-BAUDRATE with 3 value bytes (expected 4)"),
        (b"\x2c\x03", "SET-PARITY with 0 value bytes (expected 1)"),
        (b"\x2c\x04\x01", "SET-STOPSIZE with value bytes 01"),  # nothing wrong with it
        (b"\x2c\x63\x01", "subnegotiation 2c 63 01"),  # no RFC 2217 command
        (b"\x18\x01", "subnegotiation 18 01"),  # another telnet option
    ],
)
def test_describe_bad_option(suboption: bytes, told: str) -> None:
    assert describe_bad_option(suboption) == told
