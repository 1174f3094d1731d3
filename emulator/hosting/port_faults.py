"""Port faults injected from the control channel (`fault`): their parameters, what each does to a
port, and their expiry in device time.

Owns: what a fault does to each port's `Faults` (`Port.faults`, emulator/hosting/port.py), the checks on
a fault's parameters, and the schedule of expiries (`PortFaults.after`, due at `PortFaults.due`).
Output faults act on each emission the runner routes (`outgoing`: not sent, dropped, corrupted,
delayed); a hung port's input is heard by nobody (emulator/hosting/pacing.py drops it).

Asks of the runner (the callables given to `PortFaults`): to clear a port's wire (a hang) and to
detach its host (a disconnect); `changed` after every injection and expiry, so that what depends on
the faults (the runner's direct step) follows; and to call `run_due` at the start of each step and
keep its timer no later than `due`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from emulator.device import Emission
from emulator.hosting.clock import Clock
from emulator.hosting.explain import Explainer
from emulator.hosting.port import Faults, Port
from emulator.profiles.schema import finite_number, show_number

#: the value each corrupted byte is XORed with (`corrupt` fault)
CORRUPT_MASK = 0xFF

#: Fault parameters: the ones each fault takes, and the range of each (a day, a million replies or
#: bytes, a minute). JSON lets NaN, Infinity and 1e300 through; these ranges keep them out.
FAULT_PARAMS: dict[str, tuple[str, ...]] = {
    "disconnect": ("seconds",),
    "hang": ("seconds",),
    "drop": ("count",),
    "corrupt": ("count",),
    "latency": ("ms",),
    "clear": (),
}
PARAM_RANGES: dict[str, tuple[int, int]] = {
    "seconds": (0, 86400),
    "count": (1, 1_000_000),
    "ms": (0, 60000),
}


def fault_params(fault: str, params: dict[str, Any]) -> dict[str, float]:
    """The fault's parameters, checked: known names only, each a finite number in its range."""
    if fault not in FAULT_PARAMS:
        raise ValueError(f"unknown fault {fault!r}; one of: {', '.join(FAULT_PARAMS)}")
    allowed = FAULT_PARAMS[fault]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        takes = f"takes only {', '.join(allowed)}" if allowed else "takes no parameters"
        raise ValueError(f"{fault} {takes}; got {', '.join(unknown)}")
    values: dict[str, float] = {}
    for name, value in params.items():
        low, high = PARAM_RANGES[name]
        if not finite_number(value) or not low <= value <= high:
            raise ValueError(f"{name} must be a number >= {low} and <= {high}, got {value!r}")
        if name == "count" and value != int(value):
            raise ValueError(f"count must be a whole number, got {show_number(value)}")
        values[name] = value
    return values


def outgoing(ch: Port, emission: Emission, tap: Explainer | None) -> tuple[bytes, float, int] | None:
    """What the port's faults make of an emission: None when it goes nowhere (recorded through
    `tap`; a drop fault is used up by it), else its bytes (the corrupt fault's next ones flipped),
    when they are handed to the wire (with the latency fault's delay) and how many were corrupted.
    No output while detached: a real UART would send into the void."""
    faults = ch.faults
    if not ch.attached:
        why = "no host attached"
    elif faults.hung:
        why = "hang fault"
    elif faults.vanished:
        why = "the port is disconnected (fault)"
    elif faults.drop_replies > 0:
        faults.drop_replies -= 1
        why = "drop fault"
    else:
        data = emission.data
        count = 0
        if faults.corrupt_bytes > 0:
            count = min(faults.corrupt_bytes, len(data))
            faults.corrupt_bytes -= count
            data = bytes(b ^ CORRUPT_MASK for b in data[:count]) + data[count:]
        return data, emission.due + faults.latency_s, count
    if tap is not None:
        tap.withheld(emission, why)
    return None


class PortFaults:
    """Injects faults into one runner's ports and expires them in device time."""

    def __init__(
        self,
        clock: Clock,
        clear_wire: Callable[[Port, str, bool], None],
        detach: Callable[[Port], None],
        changed: Callable[[], None],
    ) -> None:
        self._clock = clock
        self._clear_wire = clear_wire
        self._detach = detach
        self._changed = changed
        #: device-time actions (expiries), earliest first
        self._actions: list[tuple[float, Callable[[], None]]] = []
        #: the device time of the earliest action (infinity: none)
        self.due = math.inf

    def inject(self, ch: Port, fault: str, params: dict[str, Any]) -> None:
        """Apply a fault to `ch`. Raises ValueError for bad input, leaving the port as it was."""
        values = fault_params(fault, params)
        seconds = values.get("seconds")
        if fault == "disconnect":
            self._disconnect(ch, seconds)
        elif fault == "hang":
            ch.faults.hung = True
            self._clear_wire(ch, "hang fault", True)
            if seconds is not None:
                self.after(seconds, lambda: setattr(ch.faults, "hung", False))
        elif fault == "drop":
            ch.faults.drop_replies += int(values.get("count", 1))
        elif fault == "corrupt":
            ch.faults.corrupt_bytes += int(values.get("count", 1))
        elif fault == "latency":
            if "ms" not in values:
                raise ValueError("latency needs ms=M, the delay added to every reply (0 to 60000 ms)")
            ch.faults.latency_s = values["ms"] / 1000
        else:  # clear
            if ch.faults.vanished and ch.transport is not None:
                ch.transport.reappear()
            ch.faults = Faults()
        self._changed()

    def _disconnect(self, ch: Port, seconds: float | None) -> None:
        if ch.transport is None or ch.faults.vanished:
            return
        ch.faults.vanished = True
        ch.transport.vanish()
        if ch.attached:
            self._detach(ch)

        def back() -> None:
            if ch.faults.vanished and ch.transport is not None:
                ch.faults.vanished = False
                ch.transport.reappear()

        if seconds is not None:
            self.after(seconds, back)

    def after(self, seconds: float, action: Callable[[], None]) -> None:
        """Run `action` once `seconds` of device time have passed (at the first step from then)."""
        self._actions.append((self._clock.now() + seconds, action))
        self._actions.sort(key=lambda item: item[0])
        self.due = self._actions[0][0]

    def run_due(self, now: float) -> None:
        """Run the actions due by `now`, earliest first."""
        actions = self._actions
        while actions and actions[0][0] <= now:
            _, action = actions.pop(0)
            action()
        self.due = actions[0][0] if actions else math.inf
        self._changed()
