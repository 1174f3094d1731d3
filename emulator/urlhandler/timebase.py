"""How an in-process port's waits pass time: with the wall clock (real time, optionally scaled), or
virtually (device time jumps to the next thing due whenever the host waits).

Both give the host's own clock for its timeouts (`now`) and the one way a host call waits for the
device (`wait`). In real time the host's clock is `time.monotonic` and a wait sleeps until the next
instant something is due; in virtual time the host's clock is the device's and a wait sleeps not at
all: it moves the device's clock to that instant (or to the host's deadline, if sooner) and returns.
Only when nothing at all is scheduled does a virtual wait block, for another thread of the host (a
reader waiting for a writer) to do something.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from emulator.hosting.clock import ScaledClock, VirtualClock
from emulator.hosting.runner import DeviceRunner

#: Shortest sleep of a real-time wait, wall seconds: a model that kept reporting a deadline already
#: passed would otherwise turn a read into a busy loop. Far below a character time at any baud.
MIN_WAIT_S = 0.0002
#: Shortest step of a virtual wait, device seconds, for the same reason.
MIN_STEP_S = 1e-6


@dataclass(frozen=True)
class Deadline:
    """When a wait gives up, on the host's clock `now`: `at` None never (a pyserial timeout of
    None); a deadline already passed when made (timeout 0) means do not wait at all."""

    at: float | None
    now: Callable[[], float] = time.monotonic

    def left(self) -> float | None:
        return None if self.at is None else max(self.at - self.now(), 0.0)

    def passed(self) -> bool:
        return self.at is not None and self.now() >= self.at


class Timebase:
    """The host's clock (`now`) and the deadlines of its timeouts on it."""

    def __init__(self, now: Callable[[], float]) -> None:
        self.now = now

    def after(self, seconds: float | None) -> Deadline:
        return Deadline(None if seconds is None else self.now() + seconds, self.now)


class RealTime(Timebase):
    """Device time runs with the wall clock, `scale` times faster."""

    virtual = False

    def __init__(self, scale: float) -> None:
        super().__init__(time.monotonic)
        self.clock = ScaledClock(scale)

    def wait(
        self,
        changed: threading.Condition,
        runner: DeviceRunner,
        limit: float | None,
        others_queued: Callable[[], bool],
    ) -> None:
        """Sleep (the lock released) until the runner's next due instant, `limit` host seconds, or
        another thread's notice, whichever is first."""
        delay = runner.wall_until_due()
        if limit is not None:
            delay = limit if delay is None else min(delay, limit)
        changed.wait(None if delay is None else max(delay, MIN_WAIT_S))


class VirtualTime(Timebase):
    """Device time passes only as the host waits: the host's clock is the device's."""

    virtual = True

    def __init__(self) -> None:
        self.clock = VirtualClock()
        super().__init__(self.clock.now)

    def wait(
        self,
        changed: threading.Condition,
        runner: DeviceRunner,
        limit: float | None,
        others_queued: Callable[[], bool],
    ) -> None:
        """Move device time to the runner's next due instant or `limit` host seconds on, whichever
        is first (the runner follows the clock); with neither, wait for another thread. A host
        thread waiting to make a call of its own (a writer beside a reading thread) goes first:
        time passes only once it has made it."""
        if others_queued():
            changed.wait()  # it takes the lock, makes its call and tells us
            return
        now = self.clock.now()
        due = runner.next_due()
        target = None if limit is None else now + limit
        if due is not None and (target is None or due < target):
            target = due
        if target is None:
            changed.wait()
            return
        self.clock.set(max(target, now + MIN_STEP_S))
        changed.notify_all()  # another thread's wait is over too
