"""The MP-285's serial port (docs/mp285.md §1, MP-1 ... MP-7): what reaches the controller's receiver,
when, and what leaves its transmitter.

- framing mismatches go through the bit-level UART model (MP-6, emulator/uart.py). While traffic is
  garbled the port times the line itself (exact start bits and stop samples in both directions), so
  it clears `pace_line` and the host delivers and forwards bytes unpaced;
- a USB host without RTS/CTS meets a one-character receive register (MP-7): while the controller is
  busy it keeps one byte and flags an overrun on the next;
- replies are stamped with the instant they are handed to the transmitter and remembered for the
  traffic log's summaries.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Callable
from fractions import Fraction
from typing import Any

from emulator.device import ControlError, Emission, HostLine, LineSettings
from emulator.devices.mp285.schema import BAUDS
from emulator.line import char_time, mismatches
from emulator.uart import Framing, Wire
from protocols import mp285 as proto

#: `on_char(byte, framing_error, t)`: one character received at `t` (framing_error: not a data byte)
OnChar = Callable[[int, bool, float], None]

FRAMING_SETTINGS = ("baud", "data_bits", "parity", "stop_bits")
#: a host byte completing within this of the end of a transmission counts as after it (float clocks)
TIME_TOLERANCE = 1e-9
#: replies remembered for traffic-log summaries (bounded: nothing drains them without a traffic log)
TX_LOG_LENGTH = 64
#: what the front-panel menu sets on the RS-232 port (MP-1)
MENU: dict[str, tuple[Any, ...]] = {
    "baud": BAUDS,
    "parity": ("none", "even", "odd"),
    "stop_bits": (1, 1.5, 2),
}


def after(value: Fraction) -> float:
    """The smallest float strictly greater than `value`."""
    result = float(value)
    while Fraction(result) <= value:
        result = math.nextafter(result, math.inf)
    return result


def menu_settings(current: LineSettings, params: dict[str, Any]) -> LineSettings:
    """`current` with the front-panel menu's changes (MP-1); ControlError for anything else."""
    changes = {}
    for key, value in params.items():
        if key not in MENU:
            raise ControlError(f"set_line takes {', '.join(MENU)}; not {key!r}")
        if value not in MENU[key] or isinstance(value, bool):
            raise ControlError(f"{key} must be one of {', '.join(map(str, MENU[key]))}, got {value!r}")
        changes[key] = value
    return dataclasses.replace(current, **changes)


class Line:
    """One controller's port: its settings, the host's, the wires of a mismatched line, the
    transmitter and the MP-7 receive register."""

    def __init__(
        self, settings: LineSettings, controller: Any, knobs: Any, emit: Callable[[Emission], None]
    ) -> None:
        self.usb: bool = controller.interface == "usb_vcp"
        self._require_rtscts: bool = controller.require_rtscts
        self._pace: bool = knobs.pace_line
        self._garble = knobs.line_mismatch == "garble"
        self._emit = emit
        self.settings = settings
        self._char_time = 0.0
        self.host: HostLine | None = None
        #: MP-7: a USB host that did not enable RTS/CTS, with `require_rtscts`
        self.flow_starved = False
        self.pace_line = self._pace
        #: the host frames characters differently: traffic goes through the wires (MP-6)
        self.garbled = False
        self._rx_wire: Wire | None = None
        self._tx_wire: Wire | None = None
        self._rx_queue: deque[tuple[float, int, bool]] = deque()
        self._tx_log: deque[list[Any]] = deque(maxlen=TX_LOG_LENGTH)  # [bytes not yet logged, summary]
        self._tx_free = -math.inf
        #: when the last reply has been transmitted: the end of an MP-7 busy period
        self.reply_tx_end = -math.inf
        #: MP-7: the register holds a byte or has overrun; acted on when the busy period ends
        self.register_used = False
        self._kept: tuple[int, bool] | None = None
        self._overrun = False
        self._set(settings, 0.0)

    # ---- settings (MP-1 ... MP-6) --------------------------------------------------------------

    def host_changed(self, host: HostLine | None, now: float) -> None:
        self.host = host
        self.flow_starved = self.usb and self._require_rtscts and host is not None and host.rtscts is False
        self._rebuild_wires(now)

    def set_menu(self, params: dict[str, Any], now: float) -> None:
        """The front-panel menu (MP-1): baud, parity and stop bits of the RS-232 port."""
        self._set(menu_settings(self.settings, params), now)

    def _set(self, settings: LineSettings, now: float) -> None:
        self.settings = settings
        baud, bits, parity, stop = settings.baud, settings.data_bits, settings.parity, settings.stop_bits
        assert baud is not None and bits is not None and parity is not None and stop is not None
        self._char_time = char_time(baud, bits, parity, stop)
        self._rebuild_wires(now)

    def _rebuild_wires(self, now: float) -> None:
        """Garble both directions when the host frames characters differently (MP-6)."""
        self._rx_wire = self._tx_wire = None
        self._rx_queue.clear()
        self.garbled = False
        self.pace_line = self._pace
        host = self.host
        if host is None or not self._garble:
            return
        if not any(name in FRAMING_SETTINGS for name in mismatches(self.settings, host)):
            return
        device, other = Framing.of(self.settings), Framing.of(host, self.settings)
        start = Fraction(now)
        self._rx_wire = Wire(other, device, start)
        self._tx_wire = Wire(device, other, start)
        self.garbled = True
        self.pace_line = False  # the wires time both directions exactly

    def mismatch_effect(self, host: HostLine) -> str:
        effects = []
        framing = [name for name in mismatches(self.settings, host) if name in FRAMING_SETTINGS]
        if framing and not self._garble:
            effects.append("traffic passes unchanged (line_mismatch=ignore)")
        elif framing == ["stop_bits"]:
            effects.append("only the stop bits differ, which corrupts nothing (line_mismatch=garble)")
        elif framing:
            effects.append("traffic will be garbled (line_mismatch=garble)")
        if self.usb and host.rtscts is False:
            if self._require_rtscts:
                effects.append("bytes sent while the device is busy are lost, then '0' (require_rtscts)")
            else:
                effects.append("no input is lost (require_rtscts=false)")
        elif not self.usb and host.rtscts:
            effects.append("the 3-wire RS-232 port has no handshake lines; RTS/CTS has no effect")
        if host.xonxoff:
            effects.append("the device never sends XON/XOFF; software flow control has no effect")
        return "; ".join(effects)

    def snapshot(self) -> dict[str, Any]:
        return {
            "device": self.settings.describe(),
            "host": None if self.host is None else self.host.describe(),
            "garbled": self.garbled,
            "input_unprotected": self.flow_starved,
        }

    # ---- receiving -----------------------------------------------------------------------------

    def receive_garbled(self, data: bytes, now: float, on_char: OnChar) -> None:
        """Bytes the host wrote now, unpaced, on a garbled line: they reach `on_char` as the receiver
        decodes them (on a clean line the device takes them itself, complete at `now`)."""
        wire = self._rx_wire
        assert wire is not None
        start = Fraction(now)
        for byte in data:
            wire.send(byte, start)
        self.pump_rx(now, on_char)

    def pump_rx(self, t: float, on_char: OnChar) -> None:
        """Decode garbled host input whose levels are all known by `t` (MP-6); process what is due."""
        wire = self._rx_wire
        if wire is not None:
            for char in wire.take(max(wire.line_free, Fraction(t))):
                self._rx_queue.append((max(float(char.time), t), char.value, char.framing_error))
        while self._rx_queue and self._rx_queue[0][0] <= t:
            when, value, framing_error = self._rx_queue.popleft()
            on_char(value, framing_error, when)

    def rx_due(self) -> float | None:
        """When garbled input next needs decoding or processing."""
        due = [self._rx_queue[0][0]] if self._rx_queue else []
        if self._rx_wire is not None and self._rx_wire.needed is not None:
            due.append(after(self._rx_wire.needed))
        return min(due) if due else None

    # ---- the MP-7 receive register -------------------------------------------------------------

    def admit(self, byte: int, framing_error: bool, t: float, outstanding: bool) -> bool:
        """MP-7, on a flow-starved port: may the controller parse this byte now? Busy from a
        frame's last byte until its final reply has been transmitted (`outstanding`: a move is;
        a byte completing within a nanosecond of that end counts as after it), it keeps one byte
        (parsed now during a move, at the end of the busy period otherwise); any more overrun."""
        if not (outstanding or t < self.reply_tx_end - TIME_TOLERANCE):
            return True
        if self.register_used:
            self._overrun = True
            return False
        self.register_used = True
        if outstanding:
            return True
        self._kept = (byte, framing_error)
        return False

    def end_busy(self) -> tuple[tuple[int, bool] | None, bool]:
        """Empty the register: the byte it kept (or None) and whether it overran."""
        kept, overrun = self._kept, self._overrun
        self.clear_register()
        return kept, overrun

    def clear_register(self) -> None:
        self.register_used = False
        self._kept = None
        self._overrun = False

    # ---- transmitting --------------------------------------------------------------------------

    def send(self, t: float, data: bytes, reply: bool = True) -> None:
        """Hand bytes to the transmitter at `t`. `reply`: ends an MP-7 busy period once sent."""
        wire = self._tx_wire
        if wire is not None:
            start = Fraction(t)
            for byte in data:
                wire.send(byte, start)
            self._tx_free = float(wire.line_free)
            self.flush_tx(t)
        else:
            self._emit(Emission(t, data))
            self._tx_log.append([data, proto.summarize_device(data)])
            paced = max(t, self._tx_free) + len(data) * self._char_time
            self._tx_free = paced if self._pace else t
        if reply:
            self.reply_tx_end = self._tx_free

    def nothing_sent(self, t: float) -> None:
        """A command ended without a reply: its busy period ends now at the latest (MP-7)."""
        self.reply_tx_end = max(self.reply_tx_end, t)

    def flush_tx(self, t: float) -> None:
        """Emit what the host's receiver makes of the device's bytes, once final (MP-6 item 5)."""
        wire = self._tx_wire
        if wire is None:
            return
        for char in wire.take(max(wire.line_free, Fraction(t))):
            value = 0 if char.framing_error else char.value
            self._emit(Emission(float(char.time), bytes((value,))))

    def tx_due(self) -> float | None:
        """When the host's view of garbled output next becomes final."""
        wire = self._tx_wire
        return None if wire is None or wire.needed is None else after(wire.needed)

    def summarize_tx(self, data: bytes) -> str | None:
        """Device bytes, paced out one at a time, are matched to the replies that were sent: a reply
        is summarised with its last byte."""
        parts, rest = [], data
        while rest and self._tx_log:
            entry = self._tx_log[0]
            count = min(len(rest), len(entry[0]))
            if rest[:count] != entry[0][:count]:  # a port fault dropped or changed bytes
                self._tx_log.clear()
                break
            rest, entry[0] = rest[count:], entry[0][count:]
            if not entry[0]:
                parts.append(self._tx_log.popleft()[1])
        if rest:
            return proto.summarize_device(data)
        return "; ".join(parts) or None
