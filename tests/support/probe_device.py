"""A small test-only device that exercises the device-host contract (never shipped as a profile).

Line commands, CR-terminated:
- `E <text>`      echo `<text>` CR at once
- `B <n>`         send n bytes `x` at once (pacing tests)
- `D <ms> <text>` send `<text>` CR after ms milliseconds (timers, next_deadline)
Anything else: `?` CR. Control: input `say {text}` sends text unsolicited; event `line` per command.
"""

from __future__ import annotations

from typing import Any

from emulator import registry
from emulator.device import MAIN, ControlError, Device, Emission, HostServices, LineSettings
from emulator.profile import Profile, line_struct
from emulator.schema import Bool, Field, Struct

SCHEMA = Struct(
    "Probe",
    (
        Field("line", line_struct((1200, 2400, 4800, 9600, 19200, 115200), 9600, "T-1")),
        Field("knobs", Struct("ProbeKnobs", (Field("pace_line", Bool(), True, "T-2", "pace output"),))),
    ),
)


class ProbeDevice(Device):
    def __init__(self, name: str, profile: Profile, now: float, services: HostServices) -> None:
        super().__init__(name, profile, now, services)
        self.pace_line = profile.config.knobs.pace_line
        self._buffer = bytearray()
        self._timers: list[tuple[float, bytes]] = []
        self.host: LineSettings | None = None
        self.received: list[tuple[float, bytes]] = []
        self.lines = 0

    def receive(self, data: bytes, now: float, channel: str = MAIN) -> None:
        self.received.append((now, data))
        for byte in data:
            if byte == 0x0D:
                self._command(bytes(self._buffer).decode("latin-1"), now)
                self._buffer.clear()
            else:
                self._buffer.append(byte)

    def _command(self, line: str, now: float) -> None:
        self.lines += 1
        self._events.append({"ev": "line", "text": line})
        word, _, rest = line.partition(" ")
        if word == "E":
            self._outbox.append(Emission(now, rest.encode("latin-1") + b"\r"))
        elif word == "B" and rest.isdigit():
            self._outbox.append(Emission(now, b"x" * int(rest)))
        elif word == "D" and rest.partition(" ")[0].isdigit():
            ms, _, text = rest.partition(" ")
            self._timers.append((now + int(ms) / 1000, text.encode("latin-1") + b"\r"))
            self._timers.sort()
        else:
            self._outbox.append(Emission(now, b"?\r"))

    def advance(self, now: float) -> None:
        while self._timers and self._timers[0][0] <= now:
            due, data = self._timers.pop(0)
            self._outbox.append(Emission(due, data))

    def next_deadline(self) -> float | None:
        return self._timers[0][0] if self._timers else None

    def line_settings(self, channel: str = MAIN) -> LineSettings:
        line = self.profile.line
        return LineSettings(line.baud, line.data_bits, line.parity, line.stop_bits, False, False)

    def line_changed(self, host: LineSettings | None, now: float, channel: str = MAIN) -> None:
        self.host = host

    def mismatch_effect(self, host: LineSettings, channel: str = MAIN) -> str:
        return "the probe ignores it"

    def snapshot(self) -> dict[str, Any]:
        return {"lines": self.lines, "host": None if self.host is None else self.host.describe()}

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        if name != "say":
            raise ControlError(f"{self.name}: no input {name!r}; known: say")
        text = params.get("text")
        if not isinstance(text, str):
            raise ControlError("say needs text (a string)")
        self._outbox.append(Emission(now, text.encode("latin-1")))
        return True

    def control_names(self) -> dict[str, list[str]]:
        return {"inputs": ["say"], "observables": sorted(self.snapshot())}

    def summarize(self, direction: str, data: bytes) -> str | None:
        return f"{direction} {data!r}"


registry.register(registry.Family("probe", "test-only line device", SCHEMA, ProbeDevice))
