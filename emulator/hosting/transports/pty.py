"""A pseudo-terminal that a host program opens like a serial port.

Linux facts this relies on (checked on 6.x):
- Termios set by the host on the slave is readable from the master: baud (incl. BOTHER rates via
  TCGETS2), CSTOPB, CRTSCTS, IXON/IXOFF. Parity and data bits are not (the pty forces CS8).
- In packet mode (TIOCPKT) with EXTPROC set, each host `tcsetattr` yields a status byte with
  TIOCPKT_IOCTL: the signal to re-read the host's settings. Data reads come prefixed with 0x00.
- With no slave open, reads fail with EIO and poll reports POLLHUP level-triggered, so the master is
  watched through an edge-triggered epoll: one event when the last host closes, one when a host next
  configures the port or writes. No spinning while nobody is attached.
- Bytes left unread in the slave's input queue reach the next opener; they are flushed at detach.
- A host's write blocks (or fails with EAGAIN) once the kernel holds about 12 KiB it wrote that
  the master has not read: leaving bytes unread is how the port applies back pressure. The epoll is
  edge-triggered, so after stopping short of EAGAIN the transport must read again on its own.
- Packet-mode status bytes jump ahead of queued data: the next read returns them first.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import fcntl
import logging
import os
import select
import struct
import termios
import tty
from pathlib import Path

from emulator.device import HostLine
from emulator.hosting.transports.base import PortSink, Transport
from emulator.storage.runtime import PTS_DIR

log = logging.getLogger("stage_emu.pty")

TIOCPKT = 0x5420
TIOCGPTPEER = 0x5441
TCGETS2 = 0x802C542A
EXTPROC = 0x10000
BOTHER = 0o010000
CBAUD = 0o010017
TIOCPKT_IOCTL = 0x40

_SPEEDS = {
    getattr(termios, name): int(name[1:])
    for name in dir(termios)
    if name.startswith("B") and name[1:].isdigit() and name != "B0"
}
_ET_IN = select.EPOLLIN | select.EPOLLET | select.EPOLLHUP
_ET_IN_OUT = _ET_IN | select.EPOLLOUT

#: Most host bytes read per read and per wakeup of one port. With fast timing a flooding host is
#: served in such slices, and the loop serves every other ready port between two slices. The model's
#: work per byte, not the read, is what costs: 256 bytes are ~64 MS2000 commands, a few ms. With a
#: fast port flooded by `W X`, a neighbour's `W X` round trip (11.8 ms p99 idle) measured ~15 ms p99;
#: with 4096-byte slices it was 77 ms. The flood's own throughput hardly changes.
READ_CHUNK = 256
#: Device output the host's buffer would not take, kept here until the host reads. The kernel
#: already buffers about 18 KiB for a host that does not read; this only absorbs bursts. What does
#: not fit is dropped and reported to the runner, which counts it: a real host's UART overruns so.
OUTPUT_LIMIT = 4096


def drop_overrun(pending: bytearray) -> int:
    """Cut `pending` to OUTPUT_LIMIT; how many bytes were dropped (the newest are the ones lost, as
    in a UART overrun)."""
    excess = len(pending) - OUTPUT_LIMIT
    if excess <= 0:
        return 0
    del pending[OUTPUT_LIMIT:]
    return excess


_yielded = False


def _turn_over() -> None:
    global _yielded
    _yielded = False


def yield_once_per_turn(loop: asyncio.AbstractEventLoop) -> None:
    """Give up the CPU after the first write of a loop turn. The kernel hands bytes written to a
    master to the slave's reader from a work item queued on this CPU, which would otherwise wait for
    the rest of the turn: yielding lets it run now (measured: a reply reaches the host ~10 µs
    sooner). Only once per turn: on a busy machine each yield can cost a whole time slice, and a
    yield per write made a burst of one-byte replies (a crashed MP-285 answering 400 bytes with 400
    NULs) take 4 ms per byte beside CPU-bound processes."""
    global _yielded
    if _yielded:
        return
    _yielded = True
    os.sched_yield()
    loop.call_soon(_turn_over)


class PortError(Exception):
    """The port cannot be created where asked; the message says why and what to do."""


def host_settings(master: int) -> HostLine:
    """What the host configured on the slave, read through the master (parity and data bits unseen)."""
    return _read_settings(master)[0]


def _read_settings(master: int) -> tuple[HostLine, bool]:
    """The host's settings, and whether EXTPROC is still set (its next change will be announced by
    a TIOCPKT_IOCTL packet, so its data packets need no settings read)."""
    iflag, _oflag, cflag, lflag, ispeed, ospeed, _cc = termios.tcgetattr(master)
    baud = _SPEEDS.get(ospeed) or _SPEEDS.get(ispeed)
    if cflag & CBAUD == BOTHER:
        raw = fcntl.ioctl(master, TCGETS2, bytes(44))
        baud = struct.unpack_from("I", raw, 40)[0] or None  # 0 is no rate at all: treat as unknown
    host = HostLine(
        baud=baud,
        data_bits=None,
        parity=None,
        stop_bits=2 if cflag & termios.CSTOPB else 1,
        rtscts=bool(cflag & termios.CRTSCTS),
        xonxoff=bool(iflag & (termios.IXON | termios.IXOFF)),
    )
    return host, bool(lflag & EXTPROC)


def prepare_link(link: Path) -> None:
    """Make room for our symlink: only a missing path or a stale link to a vanished pts may go."""
    if not link.is_symlink():
        if link.exists():
            kind = "directory" if link.is_dir() else "file"
            raise PortError(
                f"{link} already exists and is a {kind}, not a stale pty link; "
                "remove it or choose another link path"
            )
        return
    target = os.readlink(link)
    if not target.startswith(PTS_DIR):
        raise PortError(f"{link} is a symlink to {target}, not to a pty; refusing to replace it")
    if os.path.exists(target):
        raise PortError(
            f"{link} points to {target}, which is still open (another emulator?); stop it or remove the link"
        )
    link.unlink()


class PtyTransport(Transport):
    kind = "pty"

    def __init__(self, link: Path, mode: int = 0o600, loop: asyncio.AbstractEventLoop | None = None) -> None:
        self._link = link
        self._mode = mode
        self._loop = loop
        self._sink: PortSink | None = None
        self._master = -1
        self._epoll: select.epoll | None = None
        self._pts = ""
        self._attached = False
        self._host: HostLine | None = None
        #: the host's settings changes arrive as TIOCPKT_IOCTL packets (EXTPROC still set)
        self._announced = False
        self._pending = bytearray()
        #: EPOLLOUT is in the epoll's mask (output is waiting for the host to read)
        self._out_armed = False
        #: reading stopped because the sink had no room; `resume_reading` restarts it
        self._paused = False
        self._resume: asyncio.Handle | None = None
        #: the host closed (EPOLLHUP): read to the end, discarding what does not fit
        self._hung_up = False
        self._discarded = 0

    @property
    def path(self) -> str:
        return str(self._link)

    @property
    def device_path(self) -> str | None:
        return self._pts or None

    def open(self, sink: PortSink) -> None:
        self._sink = sink
        if self._loop is None:
            self._loop = asyncio.get_running_loop()
        prepare_link(self._link)
        self._link.parent.mkdir(parents=True, exist_ok=True)
        self._create()

    def _create(self) -> None:
        master, slave = os.openpty()
        try:
            tty.setraw(slave)
            attrs = termios.tcgetattr(slave)
            attrs[3] |= EXTPROC
            termios.tcsetattr(slave, termios.TCSANOW, attrs)
            self._pts = os.ttyname(slave)
            os.chmod(self._pts, self._mode)
        finally:
            os.close(slave)
        fcntl.ioctl(master, TIOCPKT, struct.pack("i", 1))
        os.set_blocking(master, False)
        self._master = master
        self._epoll = select.epoll()
        self._epoll.register(master, _ET_IN)
        self._out_armed = False
        assert self._loop is not None
        self._loop.add_reader(self._epoll.fileno(), self._on_ready)
        os.symlink(self._pts, self._link)

    def _destroy(self) -> None:
        if self._resume is not None:
            self._resume.cancel()
            self._resume = None
        self._paused = self._hung_up = False
        self._discarded = 0
        if self._epoll is not None:
            assert self._loop is not None
            self._loop.remove_reader(self._epoll.fileno())
            self._epoll.close()
            self._epoll = None
        if self._master >= 0:
            os.close(self._master)
            self._master = -1
        with contextlib.suppress(OSError):
            if self._link.is_symlink() and os.readlink(self._link) == self._pts:
                self._link.unlink()
        self._pending.clear()
        if self._attached:
            self._attached = False
            assert self._sink is not None
            self._sink.host_detached()

    def close(self) -> None:
        self._destroy()

    def vanish(self) -> None:
        self._destroy()

    def reappear(self) -> None:
        if self._master < 0:
            prepare_link(self._link)
            self._create()

    # ---- events -------------------------------------------------------------------------------

    def _on_ready(self) -> None:
        assert self._epoll is not None
        events = 0
        for _fd, mask in self._epoll.poll(0):
            events |= mask
        if events & select.EPOLLOUT:
            self._flush()
        if events & select.EPOLLHUP:
            self._hung_up = True
        if self._resume is None:  # else the read already scheduled takes this port's next slice
            self._read()

    def resume_reading(self) -> None:
        if self._paused:
            self._paused = False
            self._read_soon()

    def _read_soon(self) -> None:
        """Read again from the loop: the edge-triggered epoll will not report bytes already there."""
        if self._resume is None and self._loop is not None:
            self._resume = self._loop.call_soon(self._read_later)

    def _read_later(self) -> None:
        self._resume = None
        self._read()

    def _read(self) -> None:
        """Take what the emulated wire carries now: at most `room()` bytes, one slice per wakeup.
        Once the host has hung up, everything left is read until EIO (the detach), even while there
        is no room: what does not fit is discarded and counted."""
        assert self._sink is not None
        budget = READ_CHUNK
        while self._master >= 0:
            room = max(self._sink.room(), 0)
            if room == 0 and not self._hung_up:
                # A settings change made meanwhile (its status byte waits in the kernel) is seen when
                # reading resumes and then applies to the bytes still queued, as a real port's
                # tcsetattr(TCSANOW) applies at once to bytes still in the host's transmit buffer.
                self._paused = True
                return
            if budget <= 0:
                self._read_soon()
                return
            asked = (budget if self._hung_up else min(room, budget)) + 1  # + the packet-mode header
            try:
                packet = os.read(self._master, asked)
            except BlockingIOError:
                if self._hung_up:
                    self._end_hangup()  # another host opened the port before we saw EIO
                return
            except OSError as exc:
                if exc.errno != errno.EIO:
                    raise
                self._end_hangup()
                self._on_hangup()
                return
            if not packet:
                return
            budget -= max(len(packet) - 1, 1)
            if packet[0] == 0 and len(packet) - 1 > room:  # only after a hang-up
                self._discarded += len(packet) - 1 - room
                if room == 0:
                    continue
                packet = packet[: room + 1]
            self._on_packet(packet)
            if packet[0] == 0 and len(packet) < asked and not self._hung_up:
                # Drained: bytes the host writes later raise a new edge, so no read to EAGAIN. (A
                # status packet is read past: data may be queued behind it.)
                return

    def _end_hangup(self) -> None:
        count, self._discarded = self._discarded, 0
        self._hung_up = False
        if count:
            assert self._sink is not None
            log.info("%s: %d bytes a host wrote before hanging up were discarded unread", self._link, count)
            self._sink.input_discarded(count)

    def _on_packet(self, packet: bytes) -> None:
        assert self._sink is not None
        if packet[0] != 0 and not packet[0] & TIOCPKT_IOCTL:
            return  # flush/flow status only (our own stale flush causes one): no host activity
        if not self._attached:
            self._attached = True
            self._host, self._announced = _read_settings(self._master)
            self._sink.host_attached(self._host)
        if packet[0] == 0:
            # A host that cleared EXTPROC sends no ioctl packets: check its settings with its data.
            # (Clearing it is itself announced, since the old settings had it.)
            if not self._announced:
                self._recheck_settings()
            if len(packet) > 1:
                self._sink.host_data(packet[1:])
        elif packet[0] & TIOCPKT_IOCTL:
            self._recheck_settings()

    def _recheck_settings(self) -> None:
        assert self._sink is not None
        current, self._announced = _read_settings(self._master)
        if current != self._host:
            self._host = current
            self._sink.host_line(current)

    def _on_hangup(self) -> None:
        if not self._attached:
            return
        self._attached = False
        self._pending.clear()
        self._flush_stale()
        assert self._sink is not None
        self._sink.host_detached()

    def _flush_stale(self) -> None:
        """Drop output the departed host never read, so the next opener starts clean."""
        try:
            peer = fcntl.ioctl(self._master, TIOCGPTPEER, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError:
            return
        try:
            termios.tcflush(peer, termios.TCIFLUSH)
        finally:
            os.close(peer)

    # ---- output -------------------------------------------------------------------------------

    def write(self, data: bytes) -> int:
        if self._master < 0 or not self._attached:
            return 0
        waiting = bool(self._pending)  # then EPOLLOUT is armed and flushes once the host reads
        self._pending += data
        if not waiting:
            self._flush()
        return drop_overrun(self._pending)

    def _flush(self) -> None:
        sent = 0
        while self._pending and self._master >= 0:
            try:
                sent = os.write(self._master, self._pending)
            except BlockingIOError:
                break
            except OSError as exc:
                if exc.errno == errno.EIO:
                    self._pending.clear()
                    return
                raise
            del self._pending[:sent]
        if sent:
            assert self._loop is not None
            yield_once_per_turn(self._loop)
        wants_out = bool(self._pending)
        if wants_out != self._out_armed and self._epoll is not None and self._master >= 0:
            # only on a change: re-arming costs a system call per reply
            self._out_armed = wants_out
            self._epoll.modify(self._master, _ET_IN_OUT if wants_out else _ET_IN)
