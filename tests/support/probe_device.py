"""A small test-only device that exercises the device-host contract (never shipped as a profile).

Line commands, CR-terminated:
- `E <text>`      echo `<text>` CR at once
- `B <n>`         send n bytes `x` at once (pacing tests)
- `D <ms> <text>` send `<text>` CR after ms milliseconds (timers, next_deadline)
Anything else: `?` CR. Control: input `say {text}` sends text unsolicited; event `line` per command.
While explaining, each line is noted as a frame and each reply names its line.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from emulator.device import (
    FRAME,
    MAIN,
    UNSOLICITED,
    ControlError,
    Device,
    DeviceServices,
    Emission,
    LineSettings,
)
from emulator.profiles import registry
from emulator.profiles.profile import Config, Line, Profile, line_section
from emulator.profiles.schema import Bool, Schema, Section, setting

#: the probe's profile (tests/support/probe.yaml)
PROBE_PROFILE = str(Path(__file__).with_name("probe.yaml"))

LINE = line_section("ProbeLine", (1200, 2400, 4800, 9600, 19200, 115200), 9600, "T-1")


@dataclass(frozen=True)
class ProbeKnobs(Schema):
    pace_line: bool = setting(Bool(), True, "T-2", "pace output")


@dataclass(frozen=True)
class ProbeConfig(Config):
    line: Line = setting(Section(LINE))
    knobs: ProbeKnobs = setting(Section(ProbeKnobs))


class ProbeDevice(Device):
    def __init__(
        self, name: str, profile: Profile[ProbeConfig], now: float, services: DeviceServices
    ) -> None:
        super().__init__(name, profile, now, services)
        self.pace_line = profile.config.knobs.pace_line
        self._buffer = bytearray()
        self._timers: list[tuple[float, bytes, str]] = []
        self.host: LineSettings | None = None
        self.received: list[tuple[float, bytes]] = []
        self.lines = 0

    def _receive(self, data: bytes, now: float, channel: str) -> None:
        self.received.append((now, data))
        for byte in data:
            if byte == 0x0D:
                line = bytes(self._buffer).decode("latin-1")
                if self.notes.on:
                    self.notes.rx(now, FRAME, bytes(self._buffer) + b"\r", f"line {line!r}")
                self._command(line, now)
                self._buffer.clear()
            else:
                self._buffer.append(byte)

    def _reply(self, t: float, data: bytes, line: str) -> None:
        self._outbox.append(Emission(t, data, summary=f"reply to {line!r}" if self.notes.on else None))

    def _command(self, line: str, now: float) -> None:
        self.lines += 1
        self._events.append({"ev": "line", "text": line})
        word, _, rest = line.partition(" ")
        if word == "E":
            self._reply(now, rest.encode("latin-1") + b"\r", line)
        elif word == "B" and rest.isdigit():
            self._reply(now, b"x" * int(rest), line)
        elif word == "D" and rest.partition(" ")[0].isdigit():
            ms, _, text = rest.partition(" ")
            self._timers.append((now + int(ms) / 1000, text.encode("latin-1") + b"\r", line))
            self._timers.sort()
        else:
            self._reply(now, b"?\r", line)

    def _advance(self, now: float) -> None:
        while self._timers and self._timers[0][0] <= now:
            due, data, line = self._timers.pop(0)
            self._reply(due, data, line)

    def next_deadline(self) -> float | None:
        return self._timers[0][0] if self._timers else None

    def line_settings(self, channel: str = MAIN) -> LineSettings:
        line = self.profile.line
        return LineSettings(line.baud, line.data_bits, line.parity, line.stop_bits, False, False)

    def line_changed(self, host: LineSettings | None, now: float, channel: str = MAIN) -> None:
        self.host = host

    def mismatch_effect(self, host: LineSettings, channel: str = MAIN) -> str:
        return "the probe ignores it"

    def snapshot(self, now: float) -> dict[str, Any]:
        return {"lines": self.lines, "host": None if self.host is None else self.host.describe()}

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        if name != "say":
            raise ControlError(f"{self.name}: no input {name!r}; known: say")
        text = params.get("text")
        if not isinstance(text, str):
            raise ControlError("say needs text (a string)")
        self._outbox.append(Emission(now, text.encode("latin-1"), kind=UNSOLICITED, summary="say"))
        return True

    def control_names(self) -> dict[str, list[str]]:
        return {"inputs": ["say"], "observables": sorted(self.snapshot(self.now))}


registry.register(registry.Family("probe", "test-only line device", ProbeConfig, ProbeDevice))
