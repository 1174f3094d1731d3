"""A device model run inside the host program's process, behind in-process ports.

No thread and no event loop: every call from the host first brings the runner up to the current
device time (`DeviceRunner.pump`). That is exact, not an approximation: a model stamps each output
with the instant it was due and the line paces it from there, so catching up late yields the same
bytes at the same device instants as a timer would have. Only waiting needs the clock
(emulator/urlhandler/timebase.py): in real time a read that has not got its bytes, or a write the
wire has no room for, sleeps until the next instant something is due or its timeout, whichever is
first, then catches up again; in virtual time the same wait moves device time to that instant at
once. A write waits only while host bytes or device output are still crossing the wire (so something
is due): on an unpaced line the device takes host bytes as they are handed over, and the write hands
over its next chunk at once. (A host waiting for a CTS the device never asserts is the exception: its
write waits until its timeout, for ever without one, as on a real port.)

A device is made by opening a `stageemu://PROFILE` URL (the port owns it: closing the port switches
it off) or by `serve` (a test harness owns it, like a daemon: ports open and close on it while it
runs). Every device is listed under a key while it runs, so `stageemu://?attach=KEY&channel=NAME`
opens a port on any of its channels (`url`): the MS2000 TTL REPORT's `aux` beside the main port, or
the main port of a device a pytest fixture serves. Each port carries modem lines (lines.py): RTS,
DTR and the device's CTS, DSR, CD and RI, with the bytes each side's flow control holds. Hosts may
read in one thread and write in another (pyserial's `ReaderThread`, miniterm): every call holds one
condition's lock, and a waiting reader is woken whenever another thread writes, changes the line
settings or the modem lines, cancels or closes, so it re-computes when its reply is due. The
in-process control channel (emulator/urlhandler/control.py) goes through the same lock (`call`) and
takes the device's pushed events from `subscribe`.
"""

from __future__ import annotations

import contextlib
import itertools
import threading
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, TypeVar

from serial.serialutil import SerialException, SerialTimeoutException

from emulator.device import MAIN, DeviceServices, HostLine, ModemLines, Store, StoreReport
from emulator.hosting.runner import DeviceRunner
from emulator.profiles import registry
from emulator.profiles.profile import ProfileError, load_profile
from emulator.storage.nvstore import ReportingStore, StateInUse
from emulator.urlhandler.lines import ModemTransport
from emulator.urlhandler.timebase import Deadline, RealTime, VirtualTime
from emulator.urlhandler.url import VIRTUAL, UrlOptions

T = TypeVar("T")

NEVER = Deadline(None)

#: the devices served in this process, by key (`stageemu://?attach=KEY`), while they run
_SERVED: dict[str, HostedDevice] = {}
_SERVED_GUARD = threading.Lock()
_KEYS = itertools.count(1)


def serve(options: UrlOptions) -> HostedDevice:
    """A device of `options`' profile with no port open yet, running until `close()`: a harness's
    device, whose ports the host opens by `url()` (the pytest plugin's virtual time, the
    conformance suite)."""
    return HostedDevice(f"stageemu://{options.profile}", options, None)


def served(key: str) -> HostedDevice:
    """The running device listed as `key`; ValueError (pyserial's for URLs) when there is none."""
    with _SERVED_GUARD:
        device = _SERVED.get(key)
    if device is None:
        raise ValueError(f"no device {key!r} is served in this process (closed, or never made)")
    return device


@dataclass
class _Port:
    """One channel's in-process port and what its host asked of it."""

    transport: ModemTransport
    opened: bool = False
    read_cancelled: bool = False
    write_cancelled: bool = False


class HostedDevice:
    """One device (profile `options.profile`) with its ports in this process."""

    def __init__(self, url: str, options: UrlOptions, host: HostLine | None) -> None:
        try:
            profile = load_profile(options.profile)
        except ProfileError as exc:
            raise ValueError(f"{url!r}: {exc}") from None
        family = registry.family(profile.family)
        assert family is not None  # load_profile checked it
        #: the stores the models opened: closing the port gives up their claims on the state files
        self._stores: list[ReportingStore] = []

        def open_store(device_id: str, report: StoreReport) -> Store:
            store = ReportingStore(options.state_dir, device_id, report)
            self._stores.append(store)
            return store

        services = DeviceServices(stores=open_store)
        self.time = VirtualTime() if options.time == VIRTUAL else RealTime(options.scale)
        self.clock = self.time.clock
        #: the device's name on the in-process control channel
        self.name = profile.name
        try:
            self.runner = DeviceRunner(
                lambda now: family.factory(profile.name, profile, now, services),
                self.clock,
                on_event=self._on_event,
            )
        except StateInUse as exc:
            raise ValueError(f"{url!r}: {exc}; give state= another directory, or none") from None
        self._ports: dict[str, _Port] = {}
        for channel in self.runner.channels:
            transport = ModemTransport(url if channel == MAIN else f"{url}#{channel}")
            self.runner.attach_transport(channel, transport, options.timing)
            self._ports[channel] = _Port(transport)
        self._changed = threading.Condition()
        #: threads waiting to take `_changed`'s lock: a virtual wait lets them in before time passes
        self._queued = 0
        self._queue_guard = threading.Lock()
        self._closed = False
        #: queues of pushed events, one per in-process subscriber, with the device name it knows
        self._subscribers: list[tuple[deque[dict[str, Any]], str]] = []
        with _SERVED_GUARD:
            #: the device's key among those served in this process (`url`)
            self.key = f"{profile.name}-{next(_KEYS)}"
            _SERVED[self.key] = self
        if host is not None:
            self.open_channel(MAIN, host)

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(self._ports)

    def url(self, channel: str = MAIN) -> str:
        """What `serial.serial_for_url` opens to get a port on `channel` of this device."""
        self._port(channel)
        suffix = "" if channel == MAIN else f"&channel={channel}"
        return f"stageemu://?attach={self.key}{suffix}"

    def now(self) -> float:
        """The device's time (in virtual time, the host's clock too)."""
        return self.call(self.clock.now)

    def deadline(self, seconds: float | None) -> Deadline:
        """`seconds` from now on the host's clock (a pyserial timeout; None never)."""
        return self.time.after(seconds)

    # ---- the host's calls -----------------------------------------------------------------------

    def open_channel(self, channel: str, host: HostLine) -> None:
        with self._lock():
            port = self._port(channel)
            if port.opened:
                raise SerialException(f"{port.transport.path}: already open")
            self._catch_up()
            port.opened = True
            port.transport.attach(host)

    def close_channel(self, channel: str) -> None:
        """The host closed a channel's port: it hangs up, the device runs on."""
        with self._lock():
            port = self._port(channel)
            if port.opened and not self._closed:
                port.opened = False
                self._catch_up()
                port.transport.detach()
                self._changed.notify_all()

    def read(self, channel: str, size: int, deadline: Deadline, inter_byte: float | None = None) -> bytes:
        """Up to `size` bytes: all of them, or what arrived before `deadline` (or before a gap of
        `inter_byte` seconds after a byte), the read was cancelled or the port closed."""
        port = self._port(channel)
        data = bytearray()
        gap = NEVER
        with self._lock():
            port.read_cancelled = False
            while not self._closed:
                self._catch_up()
                got = port.transport.take(size - len(data))
                data += got
                if got and inter_byte is not None:
                    gap = self.deadline(inter_byte)
                if len(data) >= size or deadline.passed() or gap.passed() or port.read_cancelled:
                    break
                self._wait(_sooner(deadline, gap))
        return bytes(data)

    def write(self, channel: str, data: bytes, deadline: Deadline, non_blocking: bool = False) -> int:
        """Hand `data` to the line as fast as the emulated wire takes it (its backlog is a real
        driver's transmit buffer): blocks while it is full, until `deadline` (then
        SerialTimeoutException); `non_blocking` returns at once how many bytes were taken."""
        port = self._port(channel)
        wire = self.runner.channels[channel]
        sent = 0
        with self._lock():
            port.write_cancelled = False
            while not self._closed:
                self._catch_up()
                chunk = data[sent : sent + port.transport.room()]
                if chunk:
                    port.transport.send(chunk)
                    sent += len(chunk)
                    self._changed.notify_all()  # a reader may now expect a reply sooner
                if sent == len(data) or port.write_cancelled:
                    break
                if chunk and not wire.from_host:
                    # The device took the chunk at once (an unpaced line): the wire has room again
                    # now, and nothing is due that would end a wait for it.
                    continue
                if non_blocking:
                    break
                if deadline.passed():
                    raise SerialTimeoutException("Write timeout")
                self._wait(deadline.left())
        return sent

    def drain(self, channel: str) -> None:
        """Wait until every byte written has crossed the wire (tcdrain): also those held for CTS, so
        a host that waits for a CTS the device never asserts waits for ever, as on a real port."""
        port = self._port(channel)
        wire = self.runner.channels[channel].from_host
        self.wait_for(lambda: not (wire or port.transport.held_in) or port.write_cancelled, NEVER)

    def in_waiting(self, channel: str) -> int:
        return self.call(lambda: len(self._port(channel).transport.received))

    def out_waiting(self, channel: str) -> int:
        """Bytes written that have not crossed the wire yet (those held for CTS included)."""
        port = self._port(channel)
        return self.call(lambda: len(self.runner.channels[channel].from_host) + len(port.transport.held_in))

    def discard_input(self, channel: str) -> None:
        """Drop what has arrived and is unread (bytes still on the wire arrive later)."""
        self.call(self._port(channel).transport.received.clear)

    def discard_output(self, channel: str) -> None:
        """Drop what was written and has not crossed the wire yet (tcflush TCOFLUSH)."""
        port = self._port(channel)

        def discard() -> None:
            self.runner.channels[channel].from_host.clear()
            port.transport.discard_held_input()

        self.call(discard)

    def set_line(self, channel: str, host: HostLine) -> None:
        """The host changed its line settings: later bytes in both directions are framed by them."""
        self.call(lambda: self._port(channel).transport.change_line(host))

    def set_control(self, channel: str, rts: bool | None = None, dtr: bool | None = None) -> None:
        """The host set its RTS or DTR line."""
        transport = self._port(channel).transport

        def apply() -> None:
            if rts is not None:
                transport.set_rts(rts)
            if dtr is not None:
                transport.set_dtr(dtr)

        self.call(apply)

    def modem_lines(self, channel: str) -> ModemLines:
        """The device's CTS, DSR, CD and RI as the host reads them now."""
        return self.call(self._port(channel).transport.lines)

    def cancel_read(self, channel: str) -> None:
        with self._lock():
            self._port(channel).read_cancelled = True
            self._changed.notify_all()

    def cancel_write(self, channel: str) -> None:
        with self._lock():
            self._port(channel).write_cancelled = True
            self._changed.notify_all()

    def close(self) -> None:
        """Switch the device off (saving what it keeps, with `state=`); its ports close."""
        with self._lock():
            if self._closed:
                return
            self._closed = True
            with _SERVED_GUARD:
                _SERVED.pop(self.key, None)
            self.runner.close()
            for store in self._stores:
                store.close()
            self._changed.notify_all()

    # ---- the in-process control channel ---------------------------------------------------------

    def call(self, action: Callable[[], T]) -> T:
        """`action()` on the device brought up to now, under the port's lock; other threads are
        told afterwards (it may have changed what they wait for)."""
        with self._lock():
            self._catch_up()
            return action()

    def subscribe(self, name: str) -> deque[dict[str, Any]]:
        """A queue that gets each event the device pushes from now on, as from device `name`
        (`unsubscribe` to stop)."""
        queue: deque[dict[str, Any]] = deque()
        with self._lock():
            self._subscribers.append((queue, name))
        return queue

    def unsubscribe(self, queue: deque[dict[str, Any]]) -> None:
        with self._lock():
            self._subscribers = [(q, name) for q, name in self._subscribers if q is not queue]

    def wait_for(self, condition: Callable[[], bool], deadline: Deadline) -> bool:
        """Let time pass as a host wait does until `condition()` holds (True) or `deadline` passes,
        the port closes (False)."""
        with self._lock():
            while not self._closed:
                self._catch_up()
                if condition():
                    return True
                if deadline.passed():
                    return False
                self._wait(deadline.left())
        return False

    def _on_event(self, _device: str, event: dict[str, Any]) -> None:
        for queue, name in self._subscribers:
            queue.append({**event, "device": name})

    # ---- time -----------------------------------------------------------------------------------

    @contextlib.contextmanager
    def _lock(self) -> Iterator[None]:
        """The port's lock, counted while a thread waits for it (`_others_queued`); others are told
        when a call ends (what it did may end their wait)."""
        with self._queue_guard:
            self._queued += 1
        with self._changed:
            with self._queue_guard:
                self._queued -= 1
            try:
                yield
            finally:
                self._changed.notify_all()

    def _others_queued(self) -> bool:
        return self._queued > 0

    def _port(self, channel: str) -> _Port:
        port = self._ports.get(channel)
        if port is None:
            raise SerialException(
                f"{self.name} has no channel {channel!r} (it has: {', '.join(self._ports)})"
            )
        return port

    def _catch_up(self) -> None:
        """Bring the device and the lines up to the current device time. In virtual time they are
        always there: that clock moves only by a wait or a step, and the runner follows each move
        (as it follows each host byte and control request) at once."""
        if self._ports[MAIN].transport.vanished:
            raise SerialException(
                f"{self._ports[MAIN].transport.path}: the port disappeared (disconnect fault)"
            )
        if not self.time.virtual:
            self.runner.pump()
        for port in self._ports.values():
            if port.transport.held_in:  # the host's bytes that waited for CTS, once they may cross
                port.transport.pass_held()

    def _wait(self, limit: float | None) -> None:
        """Until the next thing is due, `limit` host seconds pass, or another thread wakes us: a
        sleep in real time, a jump of device time in virtual time."""
        self.time.wait(self._changed, self.runner, limit, self._others_queued)


def _sooner(first: Deadline, second: Deadline) -> float | None:
    """Host seconds until the earlier of two deadlines (None: neither comes)."""
    return min((d for d in (first.left(), second.left()) if d is not None), default=None)
