"""One port of a hosted device as the runner keeps it (emulator/runner.py): its transport, the host
seen on it, pacing in both directions, injected faults and what it lost.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from emulator.device import HostLine
from emulator.line import REALISTIC, Pacer
from emulator.schema import finite_number, show_number
from emulator.transports.base import Transport

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


@dataclass
class Faults:
    """Injected port faults (control channel `fault`)."""

    hung: bool = False
    drop_replies: int = 0
    corrupt_bytes: int = 0
    latency_s: float = 0.0
    vanished: bool = False

    def describe(self) -> dict[str, Any]:
        return {
            "hung": self.hung,
            "drop_replies": self.drop_replies,
            "corrupt_bytes": self.corrupt_bytes,
            "latency_ms": self.latency_s * 1000,
            "disconnected": self.vanished,
        }


@dataclass
class PortStats:
    """What one port lost because its host did not keep up (counted since the daemon started)."""

    #: device output the host's full receive buffer could not take (an overrun)
    output_dropped: int = 0
    #: host input discarded before the device received it: left in the port, or still on the
    #: emulated wire, when the host hung up
    input_discarded: int = 0
    #: output is being dropped now (the warning is logged once, when this starts)
    dropping: bool = False

    def describe(self) -> dict[str, Any]:
        return {"output_dropped": self.output_dropped, "input_discarded": self.input_discarded}


@dataclass
class Channel:
    """One port of the device: its transport, host state, pacing in both directions and faults."""

    name: str
    timing: str = REALISTIC
    transport: Transport | None = None
    attached: bool = False
    host: HostLine | None = None
    to_host: Pacer = field(default_factory=Pacer)
    from_host: Pacer = field(default_factory=Pacer)
    faults: Faults = field(default_factory=Faults)
    stats: PortStats = field(default_factory=PortStats)
    #: the line mismatch last warned about, and one not yet warned about because no byte has
    #: crossed the line since the settings began to differ (emulator/runner.py `_check_mismatch`)
    reported_mismatch: tuple[Any, ...] = ()
    pending_mismatch: tuple[Any, ...] = ()
    #: what the pacing was last computed from (paced, device settings, host settings)
    paced_for: tuple[Any, ...] = ()
    #: the (host, device) settings last checked for a mismatch
    checked_for: tuple[Any, ...] = ()
    #: the port was told it had no room (`DeviceRunner.input_room`) and has stopped reading
    throttled: bool = False


def unsent(ch: Channel) -> str | None:
    """Why output on `ch` goes nowhere now, or None when it is sent."""
    if not ch.attached:
        return "no host attached"
    if ch.faults.hung:
        return "hang fault"
    if ch.faults.vanished:
        return "the port is disconnected (fault)"
    return None


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
