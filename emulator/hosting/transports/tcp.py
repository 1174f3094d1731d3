"""A TCP port a host connects to instead of opening a serial port (`socket://HOST:PORT`).

One host at a time, as on a serial line: a second client is refused. A client that goes away (EOF,
reset, or a half-open connection that TCP keepalive finds dead) is a hang-up, as when a PTY host
closes. The bytes are the device's bytes unchanged; a raw TCP host has no line settings, so it
attaches with every `HostLine` field None: the device's own settings are assumed.

Logging: refusals (a client retrying in a loop) and failed accepts (out of descriptors) are written
at most once per LOG_INTERVAL_S each (emulator/hosting/ratelimit.py), with the count held back since; the
refusals still untold when the host leaves are told then. A port bound to any address but loopback
gets one warning: whoever reaches it drives the device, and nothing authenticates them.

Flow control follows emulator/hosting/transports/base.py: the socket is read only while `room()` > 0 (the
rest stays in the kernel, so the client's send blocks), in slices of READ_CHUNK per wakeup, and
output waits in a bounded buffer that drops the newest bytes. The connection is watched through its
own level-triggered epoll so that a hang-up (EPOLLRDHUP) is seen even while reading is paused.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import ipaddress
import logging
import select
import socket

from emulator.device import HostLine
from emulator.hosting.ratelimit import LogLimiter, held_note
from emulator.hosting.transports.base import PortSink, Transport
from emulator.hosting.transports.pty import OUTPUT_LIMIT, READ_CHUNK, PortError

log = logging.getLogger("stage_emu.tcp")

#: a dead peer of an idle connection is found within KEEPIDLE + KEEPCNT * KEEPINTVL seconds
KEEPALIVE_IDLE_S = 10
KEEPALIVE_INTERVAL_S = 5
KEEPALIVE_COUNT = 3
#: a peer that acknowledges none of our output for this long is gone (keepalive only probes idle links)
USER_TIMEOUT_MS = 30_000
#: after the system refused an `accept` (out of descriptors), accepting resumes this much later
ACCEPT_RETRY_S = 1.0
#: what is left unread at a hang-up is read in pieces of this size
DRAIN_CHUNK = 65536

#: the limiter's key for refused second clients
_REFUSED = "refused"

_HANGUP = select.EPOLLRDHUP | select.EPOLLHUP | select.EPOLLERR


def format_address(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def is_loopback(host: str) -> bool:
    """Whether `host` (a bound address, or a name) is this machine only: 127.0.0.0/8, ::1 (also as
    an IPv4-mapped ::ffff:127.x.y.z) or `localhost`."""
    if host.lower() == "localhost":
        return True
    try:
        address = ipaddress.ip_address(host.split("%", 1)[0])  # without an IPv6 scope
    except ValueError:
        return False
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        address = address.ipv4_mapped
    return address.is_loopback


class NetworkTransport(Transport):
    """The listening socket and the one connection; subclasses translate the byte streams."""

    scheme = ""

    def __init__(
        self,
        bind: str,
        port: int,
        loop: asyncio.AbstractEventLoop | None = None,
        limiter: LogLimiter | None = None,
    ) -> None:
        self._bind = bind
        self._port = port  # 0 until bound when any free port was asked for
        self._loop = loop
        self._sink: PortSink | None = None
        self._listener: socket.socket | None = None
        self._conn: socket.socket | None = None
        self._peer = ""
        self._epoll: select.epoll | None = None
        self._mask = 0
        self._pending = bytearray()
        self._accept_retry: asyncio.TimerHandle | None = None
        #: repeated refusals and accept failures (a test passes one on its own clock)
        self._limiter = limiter or LogLimiter()
        self._exposure_told = False

    @property
    def path(self) -> str:
        return f"{self.scheme}://{format_address(self._bind, self._port)}"

    def open(self, sink: PortSink) -> None:
        self._sink = sink
        if self._loop is None:
            self._loop = asyncio.get_running_loop()
        self._listen()

    def _listen(self) -> None:
        try:
            family, kind, proto, _name, address = socket.getaddrinfo(
                self._bind, self._port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
            )[0]
            listener = socket.socket(family, kind, proto)
        except OSError as exc:
            raise PortError(f"{self.kind} port {self._where()}: {exc.strerror or exc}") from None
        try:
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # restart despite TIME_WAIT
            listener.bind(address)
            listener.listen(4)
            listener.setblocking(False)
        except OSError as exc:
            listener.close()
            raise PortError(
                f"{self.kind} port {self._where()}: cannot listen: {exc.strerror or exc}"
                + ("; is another program (or emulator) using it?" if exc.errno == errno.EADDRINUSE else "")
            ) from None
        bound, self._port = listener.getsockname()[:2]
        self._listener = listener
        assert self._loop is not None
        self._loop.add_reader(listener.fileno(), self._accept)
        if not self._exposure_told and not is_loopback(bound):
            self._exposure_told = True  # once per port, not again at each `reappear`
            log.warning(
                "%s: reachable from the network without authentication (bound to %s, not loopback): "
                "anyone who can connect drives the device; bind 127.0.0.1 to keep it on this machine",
                self.path,
                bound,
            )

    def _where(self) -> str:
        return format_address(self._bind, self._port)

    def _stop_listening(self) -> None:
        if self._accept_retry is not None:
            self._accept_retry.cancel()
            self._accept_retry = None
        if self._listener is not None:
            assert self._loop is not None
            self._loop.remove_reader(self._listener.fileno())
            self._listener.close()
            self._listener = None

    def close(self) -> None:
        self.vanish()

    def vanish(self) -> None:
        self._stop_listening()
        self._drop_connection(discarded=0)

    def reappear(self) -> None:
        if self._listener is not None:
            return
        try:
            self._listen()
        except PortError as exc:  # the address was taken meanwhile: the port stays away
            log.error("%s", exc)

    # ---- connections --------------------------------------------------------------------------

    def _accept(self) -> None:
        assert self._listener is not None and self._loop is not None
        while self._listener is not None:
            try:
                conn, address = self._listener.accept()
            except (BlockingIOError, InterruptedError, ConnectionAbortedError):
                return
            except OSError as exc:  # out of descriptors: retry later instead of spinning
                held = self._limiter.admit(f"accept {exc.errno}")
                if held is not None:
                    log.error(
                        "%s: cannot accept a connection: %s%s",
                        self.path,
                        exc.strerror or exc,
                        held_note(held, "more failed accepts since the last such line"),
                    )
                self._loop.remove_reader(self._listener.fileno())
                self._accept_retry = self._loop.call_later(ACCEPT_RETRY_S, self._resume_accepting)
                return
            peer = format_address(*address[:2])
            if self._conn is not None:
                conn.close()
                held = self._limiter.admit(_REFUSED)
                if held is not None:
                    log.warning(
                        "%s: refused a connection from %s: %s is connected (a serial port has one host)%s",
                        self.path,
                        peer,
                        self._peer,
                        held_note(held, "more refused since the last such line"),
                    )
                continue
            self._start(conn, peer)

    def _resume_accepting(self) -> None:
        self._accept_retry = None
        if self._listener is not None and self._loop is not None:
            self._loop.add_reader(self._listener.fileno(), self._accept)

    def _start(self, conn: socket.socket, peer: str) -> None:
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # replies go out byte-exact in time
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE, KEEPALIVE_IDLE_S)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL, KEEPALIVE_INTERVAL_S)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT, KEEPALIVE_COUNT)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_USER_TIMEOUT, USER_TIMEOUT_MS)
        self._conn, self._peer = conn, peer
        self._epoll = select.epoll()
        self._mask = select.EPOLLIN | select.EPOLLRDHUP
        self._epoll.register(conn.fileno(), self._mask)
        assert self._loop is not None and self._sink is not None
        self._loop.add_reader(self._epoll.fileno(), self._on_ready)
        log.info("%s: %s connected", self.path, peer)
        self._connected()
        self._sink.host_attached(self._initial_host())

    def _drop_connection(self, discarded: int) -> None:
        """Close the connection and report the hang-up (with the input it left unread)."""
        if self._conn is None:
            return
        assert self._loop is not None and self._epoll is not None and self._sink is not None
        self._loop.remove_reader(self._epoll.fileno())
        self._epoll.close()
        self._epoll = None
        with contextlib.suppress(OSError):
            self._conn.close()
        self._conn = None
        self._pending.clear()
        self._disconnected()
        log.info("%s: %s disconnected", self.path, self._peer)
        held = self._limiter.settle(_REFUSED)
        if held:
            log.warning("%s: refused %d more connections while %s was connected", self.path, held, self._peer)
        if discarded:
            log.info(
                "%s: %d bytes the host sent before hanging up were discarded unread", self.path, discarded
            )
            self._sink.input_discarded(discarded)
        self._sink.host_detached()

    def _set_mask(self, mask: int) -> None:
        if mask != self._mask and self._epoll is not None and self._conn is not None:
            self._mask = mask
            self._epoll.modify(self._conn.fileno(), mask)

    # ---- events -------------------------------------------------------------------------------

    def _on_ready(self) -> None:
        assert self._epoll is not None
        events = 0
        for _fd, mask in self._epoll.poll(0):
            events |= mask
        if events & select.EPOLLOUT:
            self._flush()
        if events & _HANGUP:
            self._hang_up()
        elif events & select.EPOLLIN:
            self._read()

    def resume_reading(self) -> None:
        # Only the mask changes: the level-triggered epoll wakes the loop, which reads later.
        self._set_mask(self._mask | select.EPOLLIN)

    def _read(self) -> None:
        """At most `room()` bytes, one slice per wakeup: with bytes left, the level-triggered epoll
        reports the socket again on the loop's next pass, after the other ports had their turn."""
        assert self._sink is not None
        budget = READ_CHUNK
        while self._conn is not None and budget > 0:
            room = max(self._sink.room(), 0)
            if room == 0:
                self._set_mask(self._mask & ~select.EPOLLIN)  # the host's bytes wait in the kernel
                return
            asked = min(room, budget)
            try:
                raw = self._conn.recv(asked)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                self._hang_up()
                return
            if not raw:
                self._hang_up()
                return
            budget -= len(raw)
            self._received(raw)
            if len(raw) < asked:
                return

    def _hang_up(self) -> None:
        """The host went away: what it sent and we have not read yet reaches the device as far as
        there is room (as a PTY's last bytes do); the rest is counted as discarded."""
        assert self._sink is not None
        discarded = 0
        while self._conn is not None:
            try:
                raw = self._conn.recv(DRAIN_CHUNK)
            except OSError:  # reset, timed out, or nothing more
                break
            if not raw:
                break
            data = self._decode(raw)
            if data is None:
                break
            room = max(self._sink.room(), 0)
            if room:
                self._sink.host_data(data[:room])
            discarded += max(len(data) - room, 0)
        self._drop_connection(discarded)

    # ---- output -------------------------------------------------------------------------------

    def write(self, data: bytes) -> int:
        if self._conn is None:
            return 0
        kept = self._fit(data, OUTPUT_LIMIT - len(self._pending))
        if kept:
            waiting = bool(self._pending)  # then EPOLLOUT is armed and flushes once the host reads
            self._pending += self._encode(data[:kept])
            if not waiting:
                self._flush()
        return len(data) - kept  # the newest bytes are the ones lost, as in an overrun

    def _send_raw(self, data: bytes) -> None:
        """Protocol bytes of the transport itself (never dropped; their amount is bounded by the
        subclass)."""
        if self._conn is None:
            return
        waiting = bool(self._pending)
        self._pending += data
        if not waiting:
            self._flush()

    def _flush(self) -> None:
        while self._pending and self._conn is not None:
            try:
                sent = self._conn.send(self._pending)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # the peer is gone: its hang-up arrives as an epoll event
                self._pending.clear()
                break
            del self._pending[:sent]
        if self._pending:
            self._set_mask(self._mask | select.EPOLLOUT)
        else:
            self._set_mask(self._mask & ~select.EPOLLOUT)

    # ---- what a subclass changes --------------------------------------------------------------

    def _initial_host(self) -> HostLine:
        return HostLine()

    def _connected(self) -> None:
        """A host connected (before it is reported attached)."""

    def _disconnected(self) -> None:
        """The connection is gone."""

    def _received(self, raw: bytes) -> None:
        data = self._decode(raw)
        if data is None:
            self._drop_connection(discarded=0)
        elif data:
            assert self._sink is not None
            self._sink.host_data(data)

    def _decode(self, raw: bytes) -> bytes | None:
        """The device's bytes in what the host sent (None: the host broke the protocol; the
        connection is to be dropped)."""
        return raw

    def _encode(self, data: bytes) -> bytes:
        return data

    def _fit(self, data: bytes, room: int) -> int:
        """How many of `data`'s first bytes fit in `room` bytes of output buffer once encoded."""
        return max(min(len(data), room), 0)


class TcpTransport(NetworkTransport):
    kind = "tcp"
    scheme = "socket"
