"""A stand-in for the device host in model-level tests: a manual clock, host bytes delivered at the end
of their wire time (or in whole chunks when unpaced), device output paced one character time apart,
as emulator/runner.py does. Times are device seconds."""

from __future__ import annotations

from typing import Any

from emulator.device import Emission, HostServices, LineSettings
from emulator.devices.mp285 import Mp285Device
from emulator.line import Pacer, settings_char_time
from emulator.profile import load_profile
from emulator.registry import family

CHAR = 10 / 9600  # one 8N1 character at 9600 baud
SAME = object()  # host settings: the device's own


class Bench:
    def __init__(
        self,
        profile: str = "mp285",
        overrides: dict[str, Any] | None = None,
        host: Any = SAME,
        paced: bool = True,
    ) -> None:
        loaded = load_profile(profile, overrides)
        device = family("mp285").factory("mp285-0", loaded, 0.0, HostServices())  # type: ignore[union-attr]
        assert isinstance(device, Mp285Device)
        self.device = device
        self.now = 0.0
        own = device.line_settings()
        self.host: LineSettings | None = own if host is SAME else host
        if self.host is not None:
            device.line_changed(self.host, 0.0)
        self.paced = paced
        self.rx = Pacer()
        self.tx = Pacer()
        self._refresh_pacing()
        self._emissions: list[Emission] = []
        self._received: list[tuple[float, int]] = []

    # ---- host actions ----------------------------------------------------------------------------

    def write(self, data: bytes, at: float | None = None, done_at: float | None = None) -> None:
        """The host writes `data` at `at` (default now), or so that its last byte is processed at
        `done_at`."""
        if done_at is not None:
            at = done_at - len(data) * self.rx.per_char
        if at is not None:
            self.run(at)
        self._refresh_pacing()
        self.rx.push(self.now, data)

    def run(self, until: float) -> None:
        """Let device time pass up to `until`, handling everything due on the way in order."""
        while True:
            due = [
                t
                for t in (self.rx.next_due(), self.device.next_deadline(), self.tx.next_due())
                if t is not None
            ]
            step = min(due) if due else None
            if step is None or step > until:
                break
            self._step(max(step, self.now))
        self._step(max(until, self.now))

    def settle(self, extra: float = 1.0) -> None:
        """Run until nothing is scheduled, then `extra` seconds more."""
        for _ in range(10_000):
            due = [
                t
                for t in (self.rx.next_due(), self.device.next_deadline(), self.tx.next_due())
                if t is not None
            ]
            if not due:
                break
            self.run(max(min(due), self.now))
        self.run(self.now + extra)

    def control(self, name: str, **params: Any) -> Any:
        self.device.advance(self.now)
        result = self.device.control_input(name, params, self.now)
        self._collect()
        return result

    # ---- what came out ---------------------------------------------------------------------------

    def emissions(self) -> list[tuple[float, str]]:
        """Drain the device's emissions as (due, hex), due rounded to the microsecond."""
        out = [(round(e.due, 6), e.data.hex(" ").upper()) for e in self._emissions]
        self._emissions.clear()
        return out

    def take(self) -> bytes:
        """Drain the bytes the host has received so far."""
        data = bytes(b for _, b in self._received)
        self._received.clear()
        return data

    def take_timed(self) -> list[tuple[float, int]]:
        out = list(self._received)
        self._received.clear()
        return out

    def snapshot(self) -> dict[str, Any]:
        self.device.advance(self.now)
        return self.device.snapshot(self.now)

    # ---- the host loop ---------------------------------------------------------------------------

    def _refresh_pacing(self) -> None:
        """As the runner does on every pump: the device may turn pacing off (garbled line)."""
        own = self.device.line_settings()
        realistic = self.paced and self.device.pace_line
        self.rx.per_char = settings_char_time(self.host or own, own) if realistic else 0.0
        self.tx.per_char = settings_char_time(own, own) if realistic else 0.0

    def _step(self, t: float) -> None:
        self._refresh_pacing()
        if self.rx.per_char > 0:
            for when, byte in self.rx.take_each_due(t):
                self.device.advance(when)
                self.device.receive(bytes((byte,)), when)
        else:
            for when, data in self.rx.take_due(t):
                self.device.advance(when)
                self.device.receive(data, when)
        self.device.advance(t)
        self._collect()
        for when, data in self.tx.take_due(t):
            first = when - (len(data) - 1) * self.tx.per_char
            self._received.extend((first + i * self.tx.per_char, b) for i, b in enumerate(data))
        self.now = t

    def _collect(self) -> None:
        for emission in sorted(self.device.take_output(), key=lambda e: e.due):
            self._emissions.append(emission)
            self.tx.push(emission.due, emission.data)


def hexs(data: bytes) -> str:
    return data.hex(" ").upper()
