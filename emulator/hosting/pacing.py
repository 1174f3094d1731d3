"""Pacing of a hosted device's ports: the character times of each port's two pacers
(emulator/wire_time.py), following the line settings of both ends, and the host input whose wire time
has ended, ready for the model.

Owns: `Port.to_host.per_char`, `Port.from_host.per_char` and what they were computed from
(`Port.paced_for`), the line errors among each port's queued input (emulator/hosting/line_errors.py), and
the one reading of the device's own line settings per step: the pacers, a serial port that runs at
those settings (`Transport.device_line_changed`) and the mismatch check (emulator/hosting/mismatch.py) all
take it from `follow`.

Asks of the runner: to call `follow` after every step (the model may have changed its settings) and
before a step when a host's settings, the model or a port changed in between; to take the host's
bytes through `due_input` in device-time order, and to `clear` a port's input when its wire is
cleared. A port is paced (`timing: realistic`) unless its timing is fast, the model does not pace
its line (`Device.pace_line`), or the port's own UARTs pace it (`Transport.wire_paces`).
"""

from __future__ import annotations

from emulator.device import Device, LineSettings
from emulator.hosting import mismatch
from emulator.hosting.explain import Explainer
from emulator.hosting.line_errors import LineErrors
from emulator.hosting.port import Port
from emulator.wire_time import REALISTIC, settings_char_time

#: host input ready for the model: (device time, port, bytes, line error kind or None); a
#: character received with a line error comes alone
Arrival = tuple[float, str, bytes, str | None]


class Pacing:
    """The pacers of one runner's ports and the input they hold."""

    def __init__(self, channels: dict[str, Port]) -> None:
        self._channels = channels
        #: per port, the characters with line errors among its queued input (a serial port's)
        self._line_errors: dict[str, LineErrors] = {}

    def follow(self, device: Device, check: bool = True) -> bool:
        """Bring every port up to the current settings of both ends, reading the device's once per
        port, and (`check`) look for a mismatch between them; returns whether a port's pacing
        changed."""
        changed = False
        pace_line = device.pace_line
        for ch in self._channels.values():
            own = device.line_settings(ch.name)
            wire_paces = ch.transport is not None and ch.transport.wire_paces
            realistic = ch.timing == REALISTIC and pace_line and not wire_paces
            if (realistic, own, ch.host) != ch.paced_for:
                self._pace(ch, realistic, own)
                changed = True
            if check:
                mismatch.check(ch, own)
        return changed

    @staticmethod
    def _pace(ch: Port, realistic: bool, own: LineSettings) -> None:
        if ch.paced_for and ch.paced_for[1] != own and ch.transport is not None:
            ch.transport.device_line_changed()  # a serial port follows the device's settings
        ch.paced_for = (realistic, own, ch.host)
        ch.to_host.per_char = settings_char_time(own, own) if realistic else 0.0
        ch.from_host.per_char = settings_char_time(ch.host or own, own) if realistic else 0.0

    def line_error(self, ch: Port, byte: int, kind: str, now: float) -> None:
        """A character the port's UART received with a line error, after the bytes queued so far:
        it takes its wire time and its place in the input like any byte."""
        self._line_errors.setdefault(ch.name, LineErrors()).add(len(ch.from_host), kind)
        ch.from_host.push(now, bytes((byte,)))

    def clear(self, ch: Port) -> None:
        """The port's input is gone (its wire was cleared): its line errors go with it."""
        ch.from_host.clear()
        self._line_errors.pop(ch.name, None)

    def due_input(self, now: float, tap: Explainer | None) -> list[Arrival]:
        """Host bytes whose wire time has ended by `now`, merged across ports in time order; bytes
        that complete at the same instant (fast timing) stay together. A hung port's bytes are
        taken and heard by nobody (recorded through `tap`)."""
        due: list[Arrival] = []
        for ch in self._channels.values():
            if ch.from_host.per_char > 0:
                arrived = [(t, bytes([b])) for t, b in ch.from_host.take_each_due(now)]
            else:
                arrived = ch.from_host.take_due(now)
            if not arrived:
                continue
            errors = self._line_errors.get(ch.name)
            if ch.faults.hung:  # a hung device hears nothing that arrives
                if errors:
                    for _, data in arrived:
                        errors.split(data)  # their marks go with them
                if tap is not None:
                    tap.unheard(arrived[-1][0], ch.name, b"".join(data for _, data in arrived))
                continue
            if errors:
                due += [
                    (t, ch.name, piece, kind) for t, data in arrived for piece, kind in errors.split(data)
                ]
            else:
                for t, data in arrived:
                    due.append((t, ch.name, data, None))
        if len(self._channels) > 1:
            due.sort(key=lambda item: item[0])
        return due
