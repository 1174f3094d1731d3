"""The MP-285's serial port (docs/mp285.md §1, MP-1 ... MP-7): what reaches the controller's receiver,
when, and what leaves its transmitter.

- framing mismatches go through the bit-level UART model (MP-6, emulator/uart.py). While traffic is
  garbled the port times the line itself (exact start bits and stop samples in both directions), so
  it clears `pace_line` and the host delivers and forwards bytes unpaced;
- a USB host without RTS/CTS meets a one-character receive register (MP-7): while the controller is
  busy it keeps one byte and flags an overrun on the next;
- replies are stamped with the instant they are handed to the transmitter.

While explaining, the port notes each garbled character as the device read it, and summarises each
character the host reads off a garbled line, naming the character it was sent as (`Sources`).
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Callable
from fractions import Fraction
from typing import Any

from emulator.device import (
    GARBLED,
    REPLY,
    UNSOLICITED,
    ControlError,
    Emission,
    HostLine,
    LineSettings,
    ModemLines,
    Notes,
)
from emulator.devices.mp285.schema import BAUDS, Mp285Controller, Mp285Knobs
from emulator.uart import HALF, Char, Framing, Wire
from emulator.wire_time import char_time, mismatches

#: `on_char(byte, framing_error, t)`: one character received at `t` (framing_error: not a data byte)
OnChar = Callable[[int, bool, float], None]

FRAMING_SETTINGS = ("baud", "data_bits", "parity", "stop_bits")
#: a host byte completing within this of the end of a transmission counts as after it (float clocks)
TIME_TOLERANCE = 1e-9
#: MP-1: the RS-232 port has three wires (TxD, RxD, ground): no modem line is ever asserted
RS232_LINES = ModemLines()
#: MP-2, MP-7: on the USB virtual COM port CTS is the device's flow control, driven by the transport
#: from its room for input (ModemLines); DSR, CD and RI are never asserted [inferred: the quick
#: reference asks the host for RTS/CTS alone and names no other line; unused modem inputs of a
#: USB-serial bridge read as not asserted]
USB_LINES = ModemLines(cts=True)
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


class Sources:
    """The characters sent on a garbled wire, to name the one a received character came from (its
    start edge falls within it). Kept only while explaining: each entry is (start, end, byte, the
    summary of the send it opens or None)."""

    def __init__(self) -> None:
        self._sent: deque[tuple[Fraction, Fraction, int, str | None]] = deque()

    def add(self, start: Fraction, end: Fraction, byte: int, summary: str | None) -> None:
        self._sent.append((start, end, byte, summary))

    def of(self, char: Char, receiver: Framing) -> tuple[int, str | None] | None:
        """The sent byte `char` started in (its start bit's falling edge lies within it), with the
        summary of its send; None when it was not recorded (sent before explaining began)."""
        bit = receiver.bit_time
        edge = char.time - (1 + receiver.data_bits + receiver.parity_bits) * bit - bit * HALF
        while self._sent and self._sent[0][1] <= edge:
            self._sent.popleft()
        if self._sent and self._sent[0][0] <= edge:
            return self._sent[0][2], self._sent[0][3]
        return None

    def clear(self) -> None:
        self._sent.clear()


class SerialLine:
    """One controller's port: its settings, the host's, the wires of a mismatched line, the
    transmitter and the MP-7 receive register."""

    def __init__(
        self,
        settings: LineSettings,
        controller: Mp285Controller,
        knobs: Mp285Knobs,
        emit: Callable[[Emission], None],
        notes: Notes,
    ) -> None:
        self.usb: bool = controller.interface == "usb_vcp"
        self._require_rtscts: bool = controller.require_rtscts
        self._pace: bool = knobs.pace_line
        self._garble = knobs.line_mismatch == "garble"
        self._emit = emit
        self._notes = notes
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
        self._rx_queue: deque[tuple[float, int, bool, str | None]] = deque()
        self._rx_sources = Sources()
        self._tx_sources = Sources()
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
        self._rx_sources.clear()
        self._tx_sources.clear()
        self.garbled = False
        self.pace_line = self._pace
        host = self.host
        if host is None or not self._garble:
            return
        if not any(name in FRAMING_SETTINGS for name in mismatches(self.settings, host)):
            return
        device, other = Framing.of(self.settings), Framing.of(host.filled(self.settings))
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

    def modem_lines(self) -> ModemLines:
        return USB_LINES if self.usb else RS232_LINES

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
        explain = self._notes.on
        for byte in data:
            begins = wire.send(byte, start)
            if explain:
                self._rx_sources.add(begins, begins + wire.sender.char_time, byte, None)
        self.pump_rx(now, on_char)

    def pump_rx(self, t: float, on_char: OnChar) -> None:
        """Decode garbled host input whose levels are all known by `t` (MP-6); process what is due."""
        wire = self._rx_wire
        if wire is not None:
            for char in wire.take(max(wire.line_free, Fraction(t))):
                note = self._garbled_note(char, self._rx_sources, wire.receiver, "host")
                self._rx_queue.append((max(float(char.time), t), char.value, char.framing_error, note))
        while self._rx_queue and self._rx_queue[0][0] <= t:
            when, value, framing_error, note = self._rx_queue.popleft()
            if note is not None:
                self._notes.rx(when, GARBLED, bytes((value,)), note)
            on_char(value, framing_error, when)

    def _garbled_note(self, char: Char, sources: Sources, receiver: Framing, sender: str) -> str | None:
        """While explaining: how one end read a character the other end (`sender`) sent (MP-6).
        None for a host's character the device read as sent: only the unit it joins is noted."""
        if not self._notes.on:
            return None
        source = sources.of(char, receiver)
        intact = source is not None and source[0] == char.value and not char.framing_error
        if intact and sender == "host":
            return None
        assert self.host is not None
        reader = "host" if sender == "device" else "device"
        lines = {"host": self.host.filled(self.settings).describe(), "device": self.settings.describe()}
        read = f"{char.value:02X}"
        if char.framing_error:
            read += " with a framing error" + (" (delivered as 00)" if reader == "host" else "")
        origin = "an unrecorded character" if source is None else f"the {sender}'s {source[0]:02X}"
        text = f"garbled: the {reader} at {lines[reader]} read {read} from {origin} sent at {lines[sender]}"
        if source is not None and source[1] is not None:
            text += f"; the first byte of {source[1]}"
        return text

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
        overrun = self._overrun
        return self.clear_register(), overrun

    @property
    def overrun(self) -> bool:
        """The register has overrun in this busy period: every further byte is lost (MP-7)."""
        return self._overrun

    def clear_register(self) -> tuple[int, bool] | None:
        """Empty the register; returns the byte it kept, if any."""
        kept = self._kept
        self.register_used = False
        self._kept = None
        self._overrun = False
        return kept

    # ---- transmitting --------------------------------------------------------------------------

    def send(self, t: float, data: bytes, reply: bool, summary: str | None, unsolicited: bool) -> None:
        """Hand bytes to the transmitter at `t`. `reply`: ends an MP-7 busy period once sent.
        `summary` (while explaining) and `unsolicited` describe them for the traffic log."""
        wire = self._tx_wire
        if wire is not None:
            start = Fraction(t)
            explain = self._notes.on
            for byte in data:
                begins = wire.send(byte, start)
                if explain:
                    self._tx_sources.add(begins, begins + wire.sender.char_time, byte, summary)
                    summary = None  # named once, with the first character
            self._tx_free = float(wire.line_free)
            self.flush_tx(t)
        else:
            self._emit(Emission(t, data, kind=UNSOLICITED if unsolicited else REPLY, summary=summary))
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
            note = self._garbled_note(char, self._tx_sources, wire.receiver, "device")
            self._emit(Emission(float(char.time), bytes((value,)), kind=GARBLED, summary=note))

    def tx_due(self) -> float | None:
        """When the host's view of garbled output next becomes final."""
        wire = self._tx_wire
        return None if wire is None or wire.needed is None else after(wire.needed)
