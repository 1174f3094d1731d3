"""A device model run inside the host program's process, behind an in-process port.

No thread and no event loop: device time is a `ScaledClock` (real time by default), and every call
from the host first brings the runner up to the current device time (`DeviceRunner.pump`). That is
exact, not an approximation: a model stamps each output with the instant it was due and the line
paces it from there, so catching up late yields the same bytes at the same device instants as a
timer would have. Only waiting needs the clock: a read that has not got its bytes, or a write the
wire has no room for, sleeps until the next instant something is due (the model's next event, the
next paced byte in either direction) or its timeout, whichever is first, then catches up again.
That sleep is the only wait. A write sleeps only while host bytes or device output are still
crossing the wire (so something is due): on an unpaced line the device takes host bytes as they
are handed over, and the write hands over its next chunk at once.

Hosts may read in one thread and write in another (pyserial's `ReaderThread`, miniterm): every call
holds one condition's lock, and a sleeping reader is woken whenever another thread writes, changes
the line settings, cancels or closes, so it re-computes when its reply is due.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from serial.serialutil import SerialException, SerialTimeoutException

from emulator import registry
from emulator.clock import ScaledClock
from emulator.device import MAIN, HostLine, HostServices, Store, StoreReport
from emulator.nvstore import ReportingStore, StateInUse
from emulator.profile import ProfileError, load_profile
from emulator.runner import DeviceRunner
from emulator.transports.inprocess import InProcessTransport
from emulator.urlhandler.url import UrlOptions

#: Shortest sleep of a wait, wall seconds: a model that kept reporting a deadline already passed
#: would otherwise turn a read into a busy loop. Far below a character time at any supported baud.
MIN_WAIT_S = 0.0002


@dataclass(frozen=True)
class Deadline:
    """When a wait gives up, on `time.monotonic`: None never (a pyserial timeout of None); a
    deadline already passed when made (timeout 0) means do not wait at all."""

    at: float | None

    @classmethod
    def after(cls, seconds: float | None) -> Deadline:
        return cls(None if seconds is None else time.monotonic() + seconds)

    def left(self) -> float | None:
        return None if self.at is None else max(self.at - time.monotonic(), 0.0)

    def passed(self) -> bool:
        return self.at is not None and time.monotonic() >= self.at


NEVER = Deadline(None)


class HostedDevice:
    """One device (profile `options.profile`) on the main port of an in-process serial line."""

    def __init__(self, url: str, options: UrlOptions, host: HostLine) -> None:
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

        services = HostServices(stores=open_store)
        self.clock = ScaledClock(options.scale)
        self.transport = InProcessTransport(url)
        try:
            self.runner = DeviceRunner(
                lambda now: family.factory(profile.name, profile, now, services), self.clock
            )
        except StateInUse as exc:
            raise ValueError(f"{url!r}: {exc}; give state= another directory, or none") from None
        self.runner.attach_transport(MAIN, self.transport, options.timing)
        self._main = self.runner.channels[MAIN]
        self._changed = threading.Condition()
        self._closed = False
        self._read_cancelled = False
        self._write_cancelled = False
        self.transport.attach(host)

    # ---- the host's calls -----------------------------------------------------------------------

    def read(self, size: int, deadline: Deadline, inter_byte: float | None = None) -> bytes:
        """Up to `size` bytes: all of them, or what arrived before `deadline` (or before a gap of
        `inter_byte` seconds after a byte), the read was cancelled or the port closed."""
        data = bytearray()
        gap = NEVER
        with self._changed:
            self._read_cancelled = False
            while not self._closed:
                self._catch_up()
                got = self.transport.take(size - len(data))
                data += got
                if got and inter_byte is not None:
                    gap = Deadline.after(inter_byte)
                if len(data) >= size or deadline.passed() or gap.passed() or self._read_cancelled:
                    break
                self._wait(_sooner(deadline, gap))
        return bytes(data)

    def write(self, data: bytes, deadline: Deadline, non_blocking: bool = False) -> int:
        """Hand `data` to the line as fast as the emulated wire takes it (its backlog is a real
        driver's transmit buffer): blocks while it is full, until `deadline` (then
        SerialTimeoutException); `non_blocking` returns at once how many bytes were taken."""
        sent = 0
        with self._changed:
            self._write_cancelled = False
            while not self._closed:
                self._catch_up()
                chunk = data[sent : sent + self.transport.room()]
                if chunk:
                    self.transport.send(chunk)
                    sent += len(chunk)
                    self._changed.notify_all()  # a reader may now expect a reply sooner
                if sent == len(data) or self._write_cancelled:
                    break
                if chunk and not self._main.from_host:
                    # The device took the chunk at once (an unpaced line): the wire has room again
                    # now, and nothing is due that would end a wait for it.
                    continue
                if non_blocking:
                    break
                if deadline.passed():
                    raise SerialTimeoutException("Write timeout")
                self._wait(deadline.left())
        return sent

    def drain(self) -> None:
        """Wait until every byte written has crossed the wire (tcdrain)."""
        with self._changed:
            while not self._closed and not self._write_cancelled:
                self._catch_up()
                if not self._main.from_host:
                    return
                self._wait(None)

    def in_waiting(self) -> int:
        with self._changed:
            self._catch_up()
            return len(self.transport.received)

    def out_waiting(self) -> int:
        """Bytes written that have not crossed the wire yet."""
        with self._changed:
            self._catch_up()
            return len(self._main.from_host)

    def discard_input(self) -> None:
        """Drop what has arrived and is unread (bytes still on the wire arrive later)."""
        with self._changed:
            self._catch_up()
            self.transport.received.clear()

    def discard_output(self) -> None:
        """Drop what was written and has not crossed the wire yet (tcflush TCOFLUSH)."""
        with self._changed:
            self._catch_up()
            self._main.from_host.clear()

    def set_line(self, host: HostLine) -> None:
        """The host changed its line settings: later bytes in both directions are framed by them."""
        with self._changed:
            self._catch_up()
            self.transport.change_line(host)
            self._changed.notify_all()

    def cancel_read(self) -> None:
        with self._changed:
            self._read_cancelled = True
            self._changed.notify_all()

    def cancel_write(self) -> None:
        with self._changed:
            self._write_cancelled = True
            self._changed.notify_all()

    def close(self) -> None:
        """The host closes the port: the device shuts down (saving what it keeps, with `state=`)."""
        with self._changed:
            if self._closed:
                return
            self._closed = True
            self.runner.close()
            for store in self._stores:
                store.close()
            self._changed.notify_all()

    # ---- time -----------------------------------------------------------------------------------

    def _catch_up(self) -> None:
        """Bring the device and the line up to the current device time."""
        if self.transport.vanished:
            raise SerialException(f"{self.transport.path}: the port disappeared (disconnect fault)")
        self.runner.pump()

    def _wait(self, limit: float | None) -> None:
        """Sleep (lock released) until the next thing is due, `limit` wall seconds pass, or another
        thread wakes us."""
        delay = self._until_next_due()
        if limit is not None:
            delay = limit if delay is None else min(delay, limit)
        self._changed.wait(None if delay is None else max(delay, MIN_WAIT_S))

    def _until_next_due(self) -> float | None:
        """Wall seconds until the model's next event or the next paced byte (output released as
        early as the runner releases it), None when nothing is scheduled."""
        return self.runner.wall_until_due()


def _sooner(first: Deadline, second: Deadline) -> float | None:
    """Wall seconds until the earlier of two deadlines (None: neither comes)."""
    return min((d for d in (first.left(), second.left()) if d is not None), default=None)
