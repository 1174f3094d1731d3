"""One host for model-level tests: drives any `Device` on a manual clock the way emulator/hosting/runner.py
does, with no transport, traffic log or faults in between. Times are device seconds.

- The time cursor `now` only moves forward. `advance(until)` stops at every instant something is due
  on the way (a host byte's wire time ending, a model deadline, a device byte leaving), in order, and
  does there what the runner's `pump` does: hand over the host bytes now complete, advance the model,
  collect its output and events, deliver the device bytes now complete.
- Host bytes (`write`) go onto the line as the runner's port puts them: paced, each byte is received
  alone at the end of its wire time at the host's settings, a write's bytes back to back; unpaced
  (`paced=False`, or while the model clears `pace_line`), a write is received whole at the instant it
  is made.
- Device output is kept twice: as the model's `Emission`s (`take_emissions`) and as the bytes the
  host has received (`take_received`), paced at the device's own character time or delivered at the
  emission's instant.
- Control requests (`control`, `get`, `snapshot`) run as the runner's `call` does: the model brought
  up to `now` first, its effects collected after.

Pacing is emulator/wire_time.py's `Pacer` with `settings_char_time`, so unseen host settings are filled in
by `HostLine.filled` as everywhere else. One channel (main). Notes on received bytes stay on the
model (`device.take_rx_notes()`): there is no traffic log to give them to.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Generic, TypeVar

from emulator.device import MAIN, Device, Emission, HostLine
from emulator.wire_time import Pacer, settings_char_time

D = TypeVar("D", bound=Device)
T = TypeVar("T")

#: gives up settling after this many due instants (a model that never goes quiet)
SETTLE_STEPS = 10_000


class ModelHarness(Generic[D]):
    """Drives the model `make_device(t0)` on a manual clock, as emulator/hosting/runner.py hosts it."""

    def __init__(self, make_device: Callable[[float], D], *, t0: float = 0.0, paced: bool = True) -> None:
        self.make_device = make_device
        self.device: D = make_device(t0)
        #: the device time everything has been brought to
        self.now = t0
        #: what the host's end of the line is set to (`line_changed`); None: never reported
        self.host: HostLine | None = None
        #: False: bytes cross the line at once in both directions (`timing: fast`)
        self.paced = paced
        #: host -> device and device -> host sides of the line
        self.rx = Pacer()
        self.tx = Pacer()
        #: drained by `take_emissions`, `take_received`, `take_events`
        self.emitted: list[Emission] = []
        self.received: list[tuple[float, int]] = []
        self.events: list[dict[str, Any]] = []
        self._refresh_pacing()

    # ---- the host's side ---------------------------------------------------------------------

    def write(self, data: bytes, at: float | None = None, done_at: float | None = None) -> None:
        """The host writes `data` at `at` (default now), or so that its last byte is complete at
        `done_at` (at the pacing in effect when called)."""
        if done_at is not None:
            self._refresh_pacing()
            at = done_at - len(data) * self.rx.per_char
        if at is not None:
            self.advance(at)
        self._refresh_pacing()
        self.rx.push(self.now, data)
        self._pump(self.now)

    def line_changed(self, host: HostLine | None) -> None:
        """The host's settings as a transport sees them (None: the host went away)."""
        self._pump(self.now)
        self.host = host
        self.device.line_changed(host, self.now)
        self._pump(self.now)

    def restart(self) -> None:
        """A new model from `make_device` at the current time (an emulator restart): what is on the
        wire is lost; a host's settings are reported to the new model."""
        self.device = self.make_device(self.now)
        self.rx.clear()
        self.tx.clear()
        if self.host is not None:
            self.device.line_changed(self.host, self.now)
        self._pump(self.now)

    # ---- time ----------------------------------------------------------------------------------

    def next_due(self) -> float | None:
        """The next instant anything is due: a host byte received, a model deadline, a byte sent."""
        times = (self.rx.next_due(), self.device.next_deadline(), self.tx.next_due())
        present = [t for t in times if t is not None]
        return min(present) if present else None

    def advance(self, until: float) -> None:
        """Let device time pass up to `until`, handling everything due on the way in order."""
        while (due := self.next_due()) is not None and due <= until:
            self._pump(max(due, self.now))
        self._pump(max(until, self.now))

    def wait(self, seconds: float) -> None:
        self.advance(self.now + seconds)

    def settle(self, extra: float = 1.0) -> None:
        """Run until nothing is due any more, then `extra` seconds more."""
        for _ in range(SETTLE_STEPS):
            due = self.next_due()
            if due is None:
                break
            self.advance(max(due, self.now))
        self.advance(self.now + extra)

    # ---- the control channel -------------------------------------------------------------------

    def call(self, action: Callable[[float], T]) -> T:
        """Run `action(now)` on the model brought up to now, then let its effects flow."""
        self._pump(self.now)
        result = action(self.now)
        self._pump(self.now)
        return result

    def control(self, name: str, /, **params: Any) -> Any:
        return self.call(lambda now: self.device.control_input(name, params, now))

    def get(self, name: str) -> Any:
        return self.call(lambda now: self.device.observe(name, now))

    def snapshot(self) -> dict[str, Any]:
        return self.call(self.device.snapshot)

    # ---- what came out ---------------------------------------------------------------------------

    def take_emissions(self) -> list[Emission]:
        """Drain the model's emissions, in the order they were due."""
        out, self.emitted = self.emitted, []
        return out

    def take_received(self) -> bytes:
        """Drain the bytes the host has received."""
        return bytes(b for _, b in self.take_received_timed())

    def take_received_timed(self) -> list[tuple[float, int]]:
        """Drain the bytes the host has received, each with the instant its stop bit ended."""
        out, self.received = self.received, []
        return out

    def take_events(self, name: str | None = None) -> list[dict[str, Any]]:
        """Drain the model's pushed events (only those called `name`, if given)."""
        taken = [e for e in self.events if name is None or e["ev"] == name]
        self.events = [e for e in self.events if not (name is None or e["ev"] == name)]
        return taken

    # ---- the runner's pump -----------------------------------------------------------------------

    def _refresh_pacing(self) -> None:
        """As the runner does on every pump: the model may turn pacing off (MP-285 garbled line)."""
        own = self.device.line_settings()
        realistic = self.paced and self.device.pace_line
        self.rx.per_char = settings_char_time(self.host or own, own) if realistic else 0.0
        self.tx.per_char = settings_char_time(own, own) if realistic else 0.0

    def _pump(self, t: float) -> None:
        self._refresh_pacing()
        if self.rx.per_char > 0:
            arrived = [(when, bytes((b,))) for when, b in self.rx.take_each_due(t)]
        else:
            arrived = self.rx.take_due(t)
        for when, data in arrived:
            self.device.receive(data, when)
        self.device.advance(t)
        self._collect()
        self.received.extend(self.tx.take_each_due(t))
        self.now = t

    def _collect(self) -> None:
        for emission in sorted(self.device.take_output(), key=lambda e: e.due):
            self.emitted.append(emission)
            if emission.channel == MAIN:
                self.tx.push(emission.due, emission.data)
        self.events.extend(self.device.take_events())
