"""The raw TCP transport on loopback: one host at a time, hang-ups of every kind, flow control both
ways as on a PTY (emulator/hosting/transports/base.py), and a clean refusal of an address in use."""

from __future__ import annotations

import asyncio
import errno
import logging
import socket

import pytest

from emulator.device import HostLine
from emulator.hosting.ratelimit import LOG_INTERVAL_S, LogLimiter
from emulator.hosting.transports.pty import OUTPUT_LIMIT, PortError
from emulator.hosting.transports.rfc2217 import Rfc2217Transport
from emulator.hosting.transports.tcp import (
    KEEPALIVE_COUNT,
    KEEPALIVE_IDLE_S,
    KEEPALIVE_INTERVAL_S,
    USER_TIMEOUT_MS,
    NetworkTransport,
    TcpTransport,
    is_loopback,
)
from tests.unit.test_pty_flow import Sink, until


class HostSink(Sink):
    """The PTY tests' sink, also keeping the host each attach reported."""

    def __init__(self, space: int | None) -> None:
        super().__init__(space)
        self.hosts: list[HostLine | None] = []

    def host_attached(self, host: HostLine | None) -> None:  # type: ignore[override]
        self.hosts.append(host)
        super().host_attached(host)  # type: ignore[arg-type]


def serve(sink: Sink) -> tuple[TcpTransport, int]:
    transport = TcpTransport("127.0.0.1", 0)
    transport.open(sink)
    port = int(transport.path.rsplit(":", 1)[1])
    return transport, port


async def connect(port: int) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
    return await asyncio.open_connection("127.0.0.1", port)


def test_carries_bytes_both_ways_and_attaches_with_no_settings() -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        assert transport.path == f"socket://127.0.0.1:{port}" and port > 0
        reader, writer = await connect(port)
        writer.write(b"W X\r\xff")
        await until(sink, lambda: bytes(sink.data) == b"W X\r\xff")
        assert sink.hosts == [HostLine()]  # a raw socket shows no settings: the device's own apply
        assert transport.write(b":A 0\r\n\xff") == 0
        assert await asyncio.wait_for(reader.readexactly(7), 5) == b":A 0\r\n\xff"
        writer.close()
        await until(sink, lambda: sink.detached == 1)
        transport.close()

    asyncio.run(scenario())


def test_a_second_client_is_refused_and_the_first_keeps_the_port(caplog: pytest.LogCaptureFixture) -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        _, first = await connect(port)
        await until(sink, lambda: sink.attached == 1)
        second_reader, second = await connect(port)
        assert await asyncio.wait_for(second_reader.read(), 5) == b""  # closed by the server
        first.write(b"still mine")
        await until(sink, lambda: bytes(sink.data) == b"still mine")
        assert (sink.attached, sink.detached) == (1, 0)
        for writer in (first, second):
            writer.close()
        await until(sink, lambda: sink.detached == 1)
        _, third = await connect(port)  # free again once the host hung up
        await until(sink, lambda: sink.attached == 2)
        third.close()
        transport.close()

    with caplog.at_level(logging.WARNING, "stage_emu.tcp"):
        asyncio.run(scenario())
    assert [r.message for r in caplog.records if "refused a connection" in r.message]


def test_reset_is_a_hangup() -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        client = socket.create_connection(("127.0.0.1", port))
        await until(sink, lambda: sink.attached == 1)
        client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        client.close()  # linger 0: an RST, not a FIN
        await until(sink, lambda: sink.detached == 1)
        transport.close()

    asyncio.run(scenario())


def test_reads_no_more_than_room_and_a_hangup_while_paused_discards_the_rest() -> None:
    async def scenario() -> None:
        sink = HostSink(10)
        transport, port = serve(sink)
        _, writer = await connect(port)
        writer.write(b"x" * 100)
        await until(sink, lambda: len(sink.data) == 10)
        for _ in range(5):
            await asyncio.sleep(0)  # let the loop run: nothing more may be read
        assert len(sink.data) == 10
        sink.space = 50
        transport.resume_reading()
        await until(sink, lambda: len(sink.data) == 60)
        writer.close()  # seen while paused: the epoll watches for the hang-up without reading
        await until(sink, lambda: sink.detached == 1)
        assert (len(sink.data), sink.discarded, sink.overruns) == (60, 40, 0)
        transport.close()

    asyncio.run(scenario())


def test_output_a_host_does_not_read_is_bounded_and_the_newest_is_dropped() -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        client = socket.create_connection(("127.0.0.1", port))
        await until(sink, lambda: sink.attached == 1)
        chunk = bytes(range(256)) * 16
        dropped = 0
        sent = 0
        while dropped == 0:  # the kernel's buffers fill first, then ours
            dropped = transport.write(chunk)
            sent += len(chunk) - dropped
            assert sent < 64 << 20
        assert transport.write(b"lost") == 4
        client.setblocking(False)
        received = bytearray()
        loop = asyncio.get_running_loop()
        while len(received) < sent:  # the loop must run meanwhile: it flushes what the port holds
            received += await asyncio.wait_for(loop.sock_recv(client, 65536), 5)
        assert bytes(received) == (chunk * (sent // len(chunk) + 1))[:sent]
        assert 0 < dropped <= len(chunk) and len(chunk) - dropped <= OUTPUT_LIMIT
        client.close()
        await until(sink, lambda: sink.detached == 1)
        transport.close()

    asyncio.run(scenario())


def test_vanish_refuses_connections_and_reappear_listens_on_the_same_port() -> None:
    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        _, writer = await connect(port)
        await until(sink, lambda: sink.attached == 1)
        transport.vanish()
        assert sink.detached == 1
        with pytest.raises(ConnectionRefusedError):
            await connect(port)
        transport.reappear()
        assert transport.path.endswith(f":{port}")
        _, again = await connect(port)
        await until(sink, lambda: sink.attached == 2)
        for w in (writer, again):
            w.close()
        transport.close()

    asyncio.run(scenario())


def test_an_address_in_use_is_one_clear_error() -> None:
    async def scenario() -> None:
        with socket.socket() as taken:
            taken.bind(("127.0.0.1", 0))
            taken.listen()
            port = taken.getsockname()[1]
            transport = TcpTransport("127.0.0.1", port)
            with pytest.raises(PortError, match=rf"tcp port 127\.0\.0\.1:{port}: cannot listen: .*in use"):
                transport.open(HostSink(None))
            transport.close()  # nothing was left half-created

    asyncio.run(scenario())


def test_every_connection_is_set_up_to_find_a_silently_dead_peer() -> None:
    """A half-open connection (the peer's machine vanished: no FIN, no RST) would hold the port for
    ever; keepalive probes (idle) and a user timeout (unacknowledged output) make the kernel end it,
    which the transport then sees as a hang-up. Loopback cannot lose a peer, so the settings are
    what is checked."""

    async def scenario() -> None:
        sink = HostSink(None)
        transport, port = serve(sink)
        _, writer = await connect(port)
        await until(sink, lambda: sink.hosts == [HostLine()])
        conn = transport._conn
        assert conn is not None
        assert conn.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE) == 1
        assert conn.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE) == KEEPALIVE_IDLE_S
        assert conn.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL) == KEEPALIVE_INTERVAL_S
        assert conn.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT) == KEEPALIVE_COUNT
        assert conn.getsockopt(socket.IPPROTO_TCP, socket.TCP_USER_TIMEOUT) == USER_TIMEOUT_MS
        writer.close()
        transport.close()

    asyncio.run(scenario())


# ---- what is logged ------------------------------------------------------------------------------


def exposure_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "without authentication" in r.getMessage()]


@pytest.mark.parametrize("kind", [TcpTransport, Rfc2217Transport])
@pytest.mark.parametrize("bind", ["0.0.0.0", "::"])
def test_a_port_reachable_from_the_network_is_warned_about_once(
    kind: type[NetworkTransport], bind: str, caplog: pytest.LogCaptureFixture
) -> None:
    """`--tcp 0.0.0.0:N`, `--rfc2217 ...` or a rig `bind:` started without a word."""

    paths: list[str] = []

    async def scenario() -> None:
        transport = kind(bind, 0)
        transport.open(HostSink(None))
        paths.append(transport.path)
        transport.vanish()
        transport.reappear()  # the same port again: no second warning
        transport.close()

    with caplog.at_level(logging.WARNING):
        asyncio.run(scenario())
    warnings = exposure_warnings(caplog)
    assert len(warnings) == 1 and warnings[0].startswith(f"{paths[0]}: reachable from the network"), warnings


@pytest.mark.parametrize("bind", ["127.0.0.1", "127.0.0.2", "localhost", "::1"])
def test_a_loopback_port_is_not_warned_about(bind: str, caplog: pytest.LogCaptureFixture) -> None:
    async def scenario() -> None:
        transport = TcpTransport(bind, 0)
        transport.open(HostSink(None))
        transport.close()

    with caplog.at_level(logging.WARNING):
        asyncio.run(scenario())
    assert exposure_warnings(caplog) == []


@pytest.mark.parametrize(
    ("host", "loopback"),
    [
        ("127.0.0.1", True),
        ("127.255.0.9", True),
        ("::1", True),
        ("::ffff:127.0.0.1", True),
        ("LocalHost", True),
        ("0.0.0.0", False),
        ("::", False),
        ("192.168.1.5", False),
        ("fe80::1%eth0", False),
        ("stage-rig.lab", False),
    ],
)
def test_loopback_is_127_0_0_0_8_and_ipv6_one_and_localhost(host: str, loopback: bool) -> None:
    assert is_loopback(host) is loopback


def test_refused_clients_are_logged_once_per_interval_with_a_count(caplog: pytest.LogCaptureFixture) -> None:
    """A client retrying in a loop against a held port logged one line per attempt (550 in 10 s)."""
    now = [0.0]

    async def scenario() -> None:
        sink = HostSink(None)
        transport = TcpTransport("127.0.0.1", 0, limiter=LogLimiter(clock=lambda: now[0]))
        transport.open(sink)
        port = int(transport.path.rsplit(":", 1)[1])
        _, first = await connect(port)
        await until(sink, lambda: sink.attached == 1)

        async def refused(count: int) -> None:
            for _ in range(count):
                reader, writer = await connect(port)
                assert await asyncio.wait_for(reader.read(), 5) == b""  # closed by the server
                writer.close()

        await refused(30)
        now[0] += LOG_INTERVAL_S
        await refused(5)  # the interval is over: one line, counting the 29 held back
        first.close()
        await until(sink, lambda: sink.detached == 1)  # ... and the last 4 when the host leaves
        transport.close()

    with caplog.at_level(logging.WARNING, "stage_emu.tcp"):
        asyncio.run(scenario())
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3, lines
    assert "refused a connection from 127.0.0.1:" in lines[0] and "more" not in lines[0]
    assert lines[1].endswith("(and 29 more refused since the last such line)")
    assert "refused 4 more connections while 127.0.0.1:" in lines[2]


class _Exhausted:
    """A listener whose `accept` fails as when the process is out of descriptors."""

    def __init__(self, listener: socket.socket) -> None:
        self._listener = listener

    def fileno(self) -> int:
        return self._listener.fileno()

    def accept(self) -> tuple[socket.socket, object]:
        raise OSError(errno.EMFILE, "Too many open files")


def test_accept_failures_are_logged_once_per_interval(caplog: pytest.LogCaptureFixture) -> None:
    """Out of descriptors, each port logged a line every ACCEPT_RETRY_S."""
    now = [0.0]

    async def scenario() -> None:
        transport = TcpTransport("127.0.0.1", 0, limiter=LogLimiter(clock=lambda: now[0]))
        transport.open(HostSink(None))
        listener = transport._listener
        assert listener is not None
        transport._listener = _Exhausted(listener)  # type: ignore[assignment]
        for _ in range(20):  # what the retry timer does every ACCEPT_RETRY_S
            transport._accept()
            transport._resume_accepting()
        now[0] += LOG_INTERVAL_S
        transport._accept()
        transport._listener = listener
        transport.close()

    with caplog.at_level(logging.ERROR, "stage_emu.tcp"):
        asyncio.run(scenario())
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2, lines
    assert "cannot accept a connection: Too many open files" in lines[0]
    assert lines[1].endswith("(and 19 more failed accepts since the last such line)")
