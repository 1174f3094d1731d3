"""The runner's wake-up: one re-armable timer per device on the daemon's asyncio loop.

asyncio sleeps in whole milliseconds (epoll_wait's timeout is rounded up), so a loop timer wakes
0-1 ms late. Worse, a chain of timers one character apart (1.04 ms at 9600 baud) keeps its phase
from one character to the next: measured with loop timers, the first bytes of an MS2000 reply left
0.3-0.6 ms after their instants in most exchanges, and the reply-byte error's p99 sat at 1.1-1.2 ms
with half a millisecond of early release. On Linux a timerfd on CLOCK_MONOTONIC (the clock
`time.monotonic` reads) wakes the loop when due, so paced bytes leave within tens of µs of their
instants; they still reach a reading host about 0.1 ms later (the wake-up, the runner, the kernel's
hand-over to the reader), so they are released that much early. Where no timerfd can be made, the
loop's own timers are used and output is released half a millisecond early. Either way each byte's
arrival at the host is centred on its instant.
"""

from __future__ import annotations

import asyncio
import ctypes
import functools
import os
from collections.abc import Callable
from typing import Protocol

#: Wall seconds output may leave before its instant with millisecond timers: they wake 0-1 ms late,
#: so releasing half a millisecond early centres each byte on its instant (±0.5 ms).
LOOP_TIMER_EARLY_S = 0.0005
#: Wall seconds output may leave before its instant with a timerfd. Measured from a pyserial-speed
#: host reading the PTY (`make bench`, reply-byte timing): released at its instant, every byte
#: arrived 0.12 ms late or more (median 0.22 ms); released 0.1 ms early, none arrived early (min
#: +0.03 ms, median 0.12 ms).
TIMERFD_EARLY_S = 0.0001

_CLOCK_MONOTONIC = 1
_TFD_NONBLOCK = os.O_NONBLOCK
_TFD_CLOEXEC = os.O_CLOEXEC


class WallTimer(Protocol):
    #: wall seconds before its instant that output may be released, given how late this timer wakes
    early: float

    def arm(self, delay: float) -> None:
        """Call back once, `delay` wall seconds from now (replacing any earlier arming)."""

    def cancel(self) -> None: ...

    def close(self) -> None: ...


class LoopTimer:
    """The loop's own millisecond timer."""

    early = LOOP_TIMER_EARLY_S

    def __init__(self, loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> None:
        self._loop = loop
        self._callback = callback
        self._handle: asyncio.TimerHandle | None = None

    def arm(self, delay: float) -> None:
        self.cancel()
        self._handle = self._loop.call_later(delay, self._fire)

    def _fire(self) -> None:
        self._handle = None
        self._callback()

    def cancel(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None

    def close(self) -> None:
        self.cancel()


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [("it_interval", _Timespec), ("it_value", _Timespec)]


class _Libc:
    """timerfd_create and timerfd_settime (the os module has them only from Python 3.13)."""

    def __init__(self) -> None:
        libc = ctypes.CDLL(None, use_errno=True)
        self._create = libc.timerfd_create
        self._settime = libc.timerfd_settime
        self._create.argtypes = [ctypes.c_int, ctypes.c_int]
        self._settime.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.POINTER(_Itimerspec), ctypes.c_void_p]

    def create(self) -> int:
        fd = int(self._create(_CLOCK_MONOTONIC, _TFD_NONBLOCK | _TFD_CLOEXEC))
        if fd < 0:
            raise OSError(ctypes.get_errno(), "timerfd_create failed")
        return fd

    def settime(self, fd: int, nanoseconds: int) -> None:
        """One expiry `nanoseconds` from now; 0 disarms."""
        spec = _Itimerspec()
        spec.it_value.tv_sec, spec.it_value.tv_nsec = divmod(nanoseconds, 1_000_000_000)
        if self._settime(fd, 0, ctypes.byref(spec), None) != 0:
            raise OSError(ctypes.get_errno(), "timerfd_settime failed")


class TimerFd:
    """A Linux timerfd watched by the loop: wakes when due."""

    early = TIMERFD_EARLY_S

    def __init__(self, loop: asyncio.AbstractEventLoop, callback: Callable[[], None], libc: _Libc) -> None:
        self._loop = loop
        self._callback = callback
        self._libc = libc
        self._fd = libc.create()
        self._armed = False
        loop.add_reader(self._fd, self._fire)

    def arm(self, delay: float) -> None:
        # at least 1 ns: a zero expiry disarms the timer instead of firing it now
        self._libc.settime(self._fd, max(int(delay * 1e9), 1))
        self._armed = True

    def _fire(self) -> None:
        try:
            os.read(self._fd, 8)  # the expiry count; reading it clears readiness
        except BlockingIOError:
            return  # re-armed or cancelled after it expired: nothing is due
        if self._armed:
            self._armed = False
            self._callback()

    def cancel(self) -> None:
        if self._armed:
            self._libc.settime(self._fd, 0)
            self._armed = False

    def close(self) -> None:
        if self._fd >= 0:
            self._loop.remove_reader(self._fd)
            os.close(self._fd)
            self._fd = -1
            self._armed = False


@functools.cache
def _load_libc() -> _Libc:
    return _Libc()


def make_timer(loop: asyncio.AbstractEventLoop, callback: Callable[[], None]) -> WallTimer:
    """A timerfd where the system has one, else the loop's millisecond timer."""
    try:
        return TimerFd(loop, callback, _load_libc())
    except (OSError, AttributeError, NotImplementedError):
        return LoopTimer(loop, callback)
