"""The one source of device time.

Every delay in every device model and in line pacing is expressed in *device seconds*. A clock maps
device time to wall time: the real clock one to one, the scaled clock `scale` device seconds per
wall second (pausable and steppable from the control channel), the manual clock not at all (tests
move it explicitly, so runs are exact and deterministic), and the virtual clock not at all either:
it is moved by whoever hosts the device, whenever the host program waits (emulator/urlhandler).
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Protocol

from emulator.profiles.schema import finite_number, show_number

#: Device seconds per wall second. Beyond these the model cannot keep up (above) or a device second
#: lasts for hours (below); NaN or infinity would make every deadline "now" and spin the loop.
MIN_SCALE = 1e-3
MAX_SCALE = 1e4
#: The longest single `step` of device time: the models process every event due in between, so a
#: bounded step keeps one step bounded in work (and float time keeps sub-microsecond resolution).
MAX_STEP = 3600.0


def check_scale(scale: float) -> float:
    """`scale` if it is a finite number in [MIN_SCALE, MAX_SCALE]; else ValueError saying so."""
    return _checked(scale, "time scale", MIN_SCALE, MAX_SCALE, "")


def check_step(seconds: float) -> float:
    """`seconds` if it is a finite number in [0, MAX_STEP]; else ValueError saying so."""
    return _checked(seconds, "step", 0.0, MAX_STEP, " s")


def _checked(value: float, what: str, low: float, high: float, unit: str) -> float:
    if not finite_number(value):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    if not low <= value <= high:
        bounds = f"between {show_number(low)} and {show_number(high)}{unit}"
        raise ValueError(f"{what} must be {bounds}, got {show_number(value)}")
    return float(value)


class Clock(ABC):
    """Device time, and how long to wait in wall time until a device instant."""

    def __init__(self) -> None:
        self._listeners: list[Callable[[], None]] = []

    @abstractmethod
    def now(self) -> float:
        """Current device time in seconds."""

    def device_span(self, wall_seconds: float) -> float:
        """Device seconds that pass in `wall_seconds` of wall time (0 when time does not run)."""
        return 0.0

    @abstractmethod
    def wall_delay(self, device_time: float) -> float | None:
        """Wall seconds until `device_time` (0 if past), or None if time does not run on its own."""

    def on_change(self, listener: Callable[[], None]) -> None:
        """Call `listener` whenever the device-time/wall-time relation changes (scale, pause, step)."""
        self._listeners.append(listener)

    def _changed(self) -> None:
        for listener in list(self._listeners):
            listener()


class ScaledClock(Clock):
    """Wall-clock-driven device time at `scale` device seconds per wall second (1.0 = real time)."""

    def __init__(self, scale: float = 1.0, wall: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self._wall = wall
        self._scale = check_scale(scale)
        self._anchor_wall = wall()
        self._anchor_device = 0.0
        self._paused = False

    @property
    def scale(self) -> float:
        return self._scale

    @property
    def paused(self) -> bool:
        return self._paused

    def now(self) -> float:
        if self._paused:
            return self._anchor_device
        return self._anchor_device + (self._wall() - self._anchor_wall) * self._scale

    def device_span(self, wall_seconds: float) -> float:
        return 0.0 if self._paused else wall_seconds * self._scale

    def wall_delay(self, device_time: float) -> float | None:
        if self._paused:
            return None
        return max(0.0, (device_time - self.now()) / self._scale)

    def _rebase(self) -> None:
        self._anchor_device = self.now()
        self._anchor_wall = self._wall()

    def set_scale(self, scale: float) -> None:
        scale = check_scale(scale)
        self._rebase()
        self._scale = scale
        self._changed()

    def pause(self) -> None:
        self._rebase()
        self._paused = True
        self._changed()

    def resume(self) -> None:
        self._anchor_wall = self._wall()
        self._paused = False
        self._changed()

    def step(self, seconds: float) -> None:
        """Advance device time by `seconds` at once (meant for a paused clock)."""
        seconds = check_step(seconds)
        self._rebase()
        self._anchor_device += seconds
        self._changed()


class ManualClock(Clock):
    """Time that moves only when a test says so."""

    def __init__(self, start: float = 0.0) -> None:
        super().__init__()
        self._now = start

    def now(self) -> float:
        return self._now

    def wall_delay(self, device_time: float) -> float | None:
        return None

    def advance(self, seconds: float) -> float:
        if seconds < 0:
            raise ValueError(f"cannot step time backwards ({seconds} s)")
        self._now += seconds
        self._changed()
        return self._now

    def set(self, device_time: float) -> None:
        if device_time < self._now:
            raise ValueError(f"cannot set time backwards ({device_time} < {self._now})")
        self._now = device_time
        self._changed()


class VirtualClock(ManualClock):
    """Device time that passes only when its host moves it: an in-process port in virtual time
    advances it to the next thing due whenever the host program waits (a read with a timeout, a
    write the wire has no room for), so a 10 s move costs no wall time and every instant is exact.

    It takes the control channel's clock requests as a scaled clock does: `step` moves it, while
    `scale`, `pause` and `resume` are kept and reported but change nothing (time here runs only as
    fast as the host waits)."""

    def __init__(self, start: float = 0.0) -> None:
        super().__init__(start)
        self.scale = 1.0
        self.paused = False

    def set_scale(self, scale: float) -> None:
        self.scale = check_scale(scale)

    def pause(self) -> None:
        self.paused = True

    def resume(self) -> None:
        self.paused = False

    def step(self, seconds: float) -> None:
        self.advance(check_step(seconds))


class ControlledClock(Protocol):
    """What the control channel's clock requests drive (`ScaledClock`, `VirtualClock`)."""

    @property
    def scale(self) -> float: ...

    @property
    def paused(self) -> bool: ...

    def now(self) -> float: ...

    def set_scale(self, scale: float) -> None: ...

    def pause(self) -> None: ...

    def resume(self) -> None: ...

    def step(self, seconds: float) -> None: ...
