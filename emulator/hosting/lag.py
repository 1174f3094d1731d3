"""A device that cannot keep up with the clock falls behind it instead of holding the loop.

At a high time scale a model can have more work per second of device time than the CPU can do (a
SEQUENCER stepping every millisecond at scale 100, a CRISP lock at scale 1000). Catching up in one
step would then never end: the loop would stop serving signals, the control channel and every other
device while the backlog, and the memory it takes, grew. So a runner works through its device's
events for at most one `WorkBudget` per step; where the budget runs out, the device's own time
(`DeviceClock`) stays behind the shared clock by what was left, and the loop turns before the next
slice. The model sees the same events at the same device instants, so it reaches the same outcome,
only later in wall time, and it catches up once it has less to do. How far behind a device is shows
in `ctl list` (`behind_s`), and each episode of falling behind is logged once (`LagEpisodes`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

from emulator.device import Device
from emulator.hosting.clock import Clock

log = logging.getLogger("stage_emu.runner")

#: Wall seconds of model work one device may do in one step before the loop gets its turn back. A
#: neighbour's round trip takes a few turns (read, paced input, paced reply), so with three devices
#: behind at once it still comes in about 20 ms, inside the 50 ms a neighbour, a signal or the
#: control channel may wait; a device that keeps up does far less in a step (a reply is tens of µs).
WORK_SLICE_S = 0.002
#: An episode of falling behind ends once the device has kept up for this long (wall seconds), so a
#: device at the edge of what the CPU can do logs once, not at every other step.
EPISODE_END_S = 1.0


@dataclass(frozen=True)
class WorkBudget:
    """How much wall time a step may spend in the model, measured on `timer`."""

    seconds: float = WORK_SLICE_S
    timer: Callable[[], float] = time.perf_counter


class DeviceClock(Clock):
    """One device's time: the shared clock less `behind`, the device seconds of work it has not
    done yet. A step always works towards the shared clock, so a device behind it catches up as
    soon as it has less to do; meanwhile what its host sends is stamped with the device's own time
    and heard in order with the device's events.

    While the device keeps up (`behind` is 0) its `now` and `wall_delay` are the shared clock's own
    methods, so the hot path pays no extra call for this view."""

    def __init__(self, shared: Clock) -> None:
        super().__init__()
        self.shared = shared
        self.behind = 0.0
        self.set_behind(0.0)

    def now(self) -> float:
        return self.shared.now() - self.behind

    def wall_delay(self, device_time: float) -> float | None:
        return self.shared.wall_delay(device_time + self.behind)

    def device_span(self, wall_seconds: float) -> float:
        return self.shared.device_span(wall_seconds)

    def on_change(self, listener: Callable[[], None]) -> None:
        self.shared.on_change(listener)

    def set_behind(self, seconds: float) -> None:
        self.behind = max(seconds, 0.0)
        if self.behind:
            self.now = self._behind_now  # type: ignore[method-assign]
            self.wall_delay = self._behind_wall_delay  # type: ignore[method-assign]
        else:
            self.now = self.shared.now  # type: ignore[method-assign]
            self.wall_delay = self.shared.wall_delay  # type: ignore[method-assign]

    def _behind_now(self) -> float:
        return DeviceClock.now(self)

    def _behind_wall_delay(self, device_time: float) -> float | None:
        return DeviceClock.wall_delay(self, device_time)


class LagEpisodes:
    """Logs each episode of a device falling behind once: when it starts, and when the device has
    kept up for `EPISODE_END_S` again."""

    def __init__(self, name: str, clock: DeviceClock, timer: Callable[[], float]) -> None:
        self._name = name
        self._clock = clock
        self._timer = timer
        #: the device fell behind within the last `EPISODE_END_S`
        self.lagging = False
        self.episodes = 0
        self._last_slip = 0.0

    def slipped(self) -> None:
        self._last_slip = self._timer()
        if self.lagging:
            return
        self.lagging = True
        self.episodes += 1
        log.warning(
            "%s: cannot keep up with the clock (the model has more work per second of device time "
            "than the CPU can do): its device time now runs behind, %.3f s so far; every event still "
            "happens, later",
            self._name,
            self._clock.behind,
        )

    def kept_up(self) -> None:
        if self._timer() - self._last_slip < EPISODE_END_S:
            return
        self.lagging = False
        log.info("%s: keeping up with the clock again", self._name)


class DeviceTime:
    """A runner's view of time for its device: the device's own clock, the work budget of a step
    and the episodes of falling behind."""

    def __init__(self, name: str, shared: Clock, budget: WorkBudget | None) -> None:
        #: the device's own time: `shared`, or behind it once the device could not keep up
        self.clock = DeviceClock(shared)
        #: the model work one step may do (None: unbounded, for hosts that own the thread)
        self.budget = budget
        self.lag = LagEpisodes(name, self.clock, (budget or WorkBudget()).timer)
        #: called after each step that ended behind the clock or caught up with it (the control
        #: channel answers a clock `step` once every device has run the stepped time)
        self.on_slice: Callable[[], None] | None = None

    def run(self, device: Device, now: float, deliver: Callable[[float], None] | None) -> float:
        """Run the device's events due by `now`, with `deliver(t)` handing it the host bytes due by
        each instant first (so both come in time order), within the budget. Returns the device time
        reached: earlier than `now` when the budget ran out and the device fell behind."""
        budget = self.budget
        if budget is not None:
            due = device.next_deadline()
            if due is not None and due < now:
                stop = budget.timer() + budget.seconds
                while due is not None and due < now:
                    if deliver is not None:
                        deliver(due)
                    device.advance(due)
                    if budget.timer() >= stop:
                        self.clock.set_behind(self.clock.shared.now() - due)
                        self.lag.slipped()
                        if self.on_slice is not None:
                            self.on_slice()
                        return due
                    due = device.next_deadline()
            if self.clock.behind:
                self.clock.set_behind(0.0)
                if self.on_slice is not None:
                    self.on_slice()
            if self.lag.lagging:
                self.lag.kept_up()
        if deliver is None:
            device.advance(now)
        else:
            deliver(now)
        return now
