"""Sutter MP-285 / MP-285A controller: the sans-I/O device model (docs/mp285.md).

Rule IDs (MP-n) refer to the behaviour reference in docs/mp285.md. The wire format lives in
protocols/mp285.py; this module decides what the controller does with it and when:

- line layer: framing mismatches go through the bit-level UART model (MP-6, emulator/uart.py); a
  USB host without RTS/CTS meets a one-character receive register (MP-7). While traffic is garbled
  the model times the line itself (exact start bits and stop samples in both directions), so it
  clears `pace_line` and the host delivers and forwards bytes unpaced;
- frame layer: `FrameParser` delimits frames; while a move is outstanding bytes are treated per §7
  (interrupts, answers to `c`/`s`, held frames replayed after the final reply);
- motion: straight-line moves with optional acceleration, settle time, interpolated positions;
- programs, reset, status block, display, and the field failure modes of §12.

Every output is stamped with the instant its event was due. Internal events (end of a move, end of a
busy period, power-on, lock-up, garbled characters becoming complete) are found by `_next_event`
and run in time order by `advance`.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from emulator.device import MAIN, ControlError, Device, Emission, HostServices, LineSettings
from emulator.devices.mp285.schema import BAUDS, SIGNATURE_BYTES
from emulator.line import char_time, mismatches
from emulator.motion import Trapezoid, round_half_away
from emulator.profile import Profile
from emulator.uart import Framing, Wire
from protocols import mp285 as proto
from protocols.mp285 import (
    CR,
    CTRL_C,
    LF,
    BadFrame,
    BufferOverrun,
    CtrlC,
    ErrorCode,
    Frame,
    FrameParser,
    ParseState,
    StatusBlock,
    StrayTerminator,
    Vector,
)

CR_BURST = 200  # MP-78
SIGNATURE_LENGTH = 16  # MP-77
QUERY_BYTES = (proto.GetPosition.BYTE, proto.GetStatus.BYTE)
FRAMING_SETTINGS = ("baud", "data_bits", "parity", "stop_bits")
#: a host byte completing within this of the end of a transmission counts as after it (float clocks)
TIME_TOLERANCE = 1e-9
#: replies remembered for traffic-log summaries (bounded: nothing drains them without a traffic log)
TX_LOG_LENGTH = 64
#: final reply of a move halted by a byte other than ^C, by `move_interrupt_reply` (MP-53)
INTERRUPTED_REPLIES = {
    "cr": b"\r",
    "error8": proto.error_reply(ErrorCode.MOVE_INTERRUPTED),
    "error8_4": proto.error_reply(proto.combine_errors(ErrorCode.MOVE_INTERRUPTED, ErrorCode.BAD_COMMAND)),
}
#: control-channel inputs (`ctl input`), see docs/mp285.md
INPUTS = ("crash", "power_cycle", "roe", "set_line")
#: stands in held input for the `error8_4` drop of the frame being parsed, so that the drop is
#: replayed in its turn (MP-53, MP-52)
ABANDON_FRAME = (-1, False)


# ---- motion (MP-43 ... MP-46) ----------------------------------------------------------------------

Xyz = tuple[int, int, int]


@dataclass(frozen=True)
class _Motion:
    """A straight-line move from `p0` by `delta` (µsteps) starting at `start`. Each axis follows its
    profile from its own offset (all 0 when the axes move together); None = speed 0, never moves."""

    start: float
    p0: Xyz
    delta: Xyz
    profiles: tuple[tuple[float, Trapezoid | None], ...]
    duration: float

    @classmethod
    def plan(
        cls, start: float, p0: Xyz, target: Xyz, factors: tuple[float, ...], speed: int, knobs: Any
    ) -> _Motion:
        delta = tuple(t - p for t, p in zip(target, p0, strict=True))
        distances = [abs(d) / f for d, f in zip(delta, factors, strict=True)]
        if not any(delta):
            return cls(start, p0, delta, ((0.0, None),) * 3, 0.0)
        if speed == 0:  # MP-40: never ends on its own
            return cls(start, p0, delta, ((0.0, None),) * 3, math.inf)
        ramp = speed / knobs.accel_um_s2 if knobs.accel_um_s2 > 0 else 0.0
        if knobs.axis_motion == "sequential":
            profiles, offset = [], 0.0
            for distance in distances:
                profile = Trapezoid(distance, speed, ramp)
                profiles.append((offset, profile))
                offset += profile.duration
            return cls(start, p0, delta, tuple(profiles), offset)
        profile = Trapezoid(max(distances), speed, ramp)
        return cls(start, p0, delta, ((0.0, profile),) * 3, profile.duration)

    def position(self, t: float) -> Xyz:
        """MP-46: P(t) = P_start + round(ΔP · s(t)), s = share of the path covered."""
        result = []
        for p, d, (offset, profile) in zip(self.p0, self.delta, self.profiles, strict=True):
            share = 0.0 if profile is None else profile.fraction(t - self.start - offset)
            result.append(p + round_half_away(d * share) if d else p)
        return tuple(result)  # type: ignore[return-value]

    @property
    def target(self) -> Xyz:
        return tuple(p + d for p, d in zip(self.p0, self.delta, strict=True))  # type: ignore[return-value]


@dataclass
class _Program:
    """A program being executed or paused: its vectors (a copy) and the next one to run."""

    number: int
    vectors: tuple[Vector, ...]
    next: int = 0


CTRL_C_HALT = "ctrl_c"
BYTE_HALT = "byte"


@dataclass
class _Run:
    """An outstanding `m`, or the current move of a program started by `k` or `e` (§7)."""

    motion: _Motion
    motion_end: float
    final_at: float
    program: _Program | None = None
    cause: str | None = None  # why it was halted: None (ran to the end), CTRL_C_HALT, BYTE_HALT

    def moving(self, t: float) -> bool:
        return t < self.motion_end

    def position(self, t: float) -> Xyz:
        return self.motion.position(min(t, self.motion_end))


def _after(value: Fraction) -> float:
    """The smallest float strictly greater than `value`."""
    result = float(value)
    while Fraction(result) <= value:
        result = math.nextafter(result, math.inf)
    return result


# ---- the device ------------------------------------------------------------------------------------


class Mp285Device(Device):
    """One MP-285 or MP-285A controller with its stage."""

    def __init__(self, name: str, profile: Profile, now: float, services: HostServices) -> None:
        super().__init__(name, profile, now, services)
        config = profile.config
        self.controller = config.controller
        self.stage = config.stage
        self.knobs = config.knobs
        self.pace_line = self.knobs.pace_line
        self._template = StatusBlock.unpack(bytes.fromhex(self.controller.status_template))
        self._factors = proto.axis_factors(self.stage.device_type, self.stage.z_usteps_per_um)
        self._travel: Xyz = tuple(self.stage.travel_usteps)  # type: ignore[assignment]
        line = profile.line
        self._line = LineSettings(
            line.baud, line.data_bits, line.parity, line.stop_bits, line.flow_control == "rtscts", False
        )
        self._host: LineSettings | None = None
        self._now = now
        self._phys: list[int] = list(self.stage.power_on_physical_usteps)
        self._origin: list[int] = list(self.stage.origin_usteps_from_bot)
        self._programs: dict[int, tuple[Vector, ...]] = {}
        self._roe_negative = self._template.roe_negative
        self._last_roe: float | None = None
        self._parser = FrameParser(self.knobs.input_buffer_size)
        self._epoch = 0  # bumped whenever queued input is thrown away (reset, power cycle, crash)
        # transmitter and line layer
        self._tx_free = -math.inf
        self._rx_wire: Wire | None = None
        self._tx_wire: Wire | None = None
        self._rx_queue: deque[tuple[float, int, bool]] = deque()
        self._tx_log: deque[list[Any]] = deque(maxlen=TX_LOG_LENGTH)  # [bytes not yet logged, summary]
        # MP-7 one-character receive register
        self._reply_tx_end = -math.inf
        self._register_used = False
        self._kept: tuple[int, bool] | None = None
        self._overrun = False
        # states
        self._run: _Run | None = None
        self._paused: _Program | None = None
        self._hold: list[tuple[int, bool]] | None = None
        self._deaf_until = -math.inf
        self._powering_until: float | None = None
        self._crashed = False
        self._signature = SIGNATURE_BYTES[self.knobs.crash_signature]
        self._cr_run = 0
        self._locked = False
        self._lockup_at: float | None = None
        self._relative = False
        self._velocity_word = self.controller.power_on_velocity_word
        self._display = ["", ""]
        self._enter_power_on_state()  # MP-76: at daemon start, at once

    # ---- Device contract ------------------------------------------------------------------------

    def receive(self, data: bytes, now: float, channel: str = MAIN) -> None:
        self._now = max(self._now, now)
        if self._rx_wire is None:
            for byte in data:
                self._on_char(byte, False, now)
            return
        for byte in data:  # unpaced while garbling: the host wrote them now
            self._rx_wire.send(byte, Fraction(now))
        self._pump_rx(now)

    def advance(self, now: float) -> None:
        while True:
            event = self._next_event()
            if event is None or event[0] > now:
                break
            self._handle(*event)
        self._flush_tx(now)
        self._now = max(self._now, now)

    def next_deadline(self) -> float | None:
        event = self._next_event()
        return None if event is None else event[0]

    def line_settings(self, channel: str = MAIN) -> LineSettings:
        return self._line

    def line_changed(self, host: LineSettings | None, now: float, channel: str = MAIN) -> None:
        self._host = host
        self._rebuild_wires(now)

    def mismatch_effect(self, host: LineSettings, channel: str = MAIN) -> str:
        effects = []
        framing = [name for name in mismatches(self._line, host) if name in FRAMING_SETTINGS]
        if framing and self.knobs.line_mismatch == "ignore":
            effects.append("traffic passes unchanged (line_mismatch=ignore)")
        elif framing == ["stop_bits"]:
            effects.append("only the stop bits differ, which corrupts nothing (line_mismatch=garble)")
        elif framing:
            effects.append("traffic will be garbled (line_mismatch=garble)")
        if self._usb() and host.rtscts is False:
            if self.controller.require_rtscts:
                effects.append("bytes sent while the device is busy are lost, then '0' (require_rtscts)")
            else:
                effects.append("no input is lost (require_rtscts=false)")
        elif not self._usb() and host.rtscts:
            effects.append("the 3-wire RS-232 port has no handshake lines; RTS/CTS has no effect")
        if host.xonxoff:
            effects.append("the device never sends XON/XOFF; software flow control has no effect")
        return "; ".join(effects)

    def snapshot(self) -> dict[str, Any]:
        t = self._now
        physical = self._physical(t)
        reported = [p - o for p, o in zip(physical, self._origin, strict=True)]
        run = self._run
        velocity = proto.Velocity.from_word(self._velocity_word)
        return {
            "model": self.controller.model,
            "interface": self.controller.interface,
            "state": self._state(t),
            "parser": self._parser.state.value,
            "position": {
                "usteps": dict(zip(proto.AXES, reported, strict=True)),
                "um": {
                    a: round(p / f, 4) for a, p, f in zip(proto.AXES, reported, self._factors, strict=True)
                },
            },
            "physical_usteps": dict(zip(proto.AXES, physical, strict=True)),
            "origin_usteps_from_bot": dict(zip(proto.AXES, self._origin, strict=True)),
            "travel_usteps": dict(zip(proto.AXES, self._travel, strict=True)),
            "target_usteps": None
            if run is None
            else {a: p - o for a, p, o in zip(proto.AXES, run.motion.target, self._origin, strict=True)},
            "mode": "relative" if self._relative else "absolute",
            "velocity": {
                "word": self._velocity_word,
                "speed_um_s": velocity.speed,
                "resolution": "high" if velocity.high else "low",
            },
            "display": list(self._display),
            "programs": {
                str(number): [dataclasses.asdict(v) for v in vectors]
                for number, vectors in sorted(self._programs.items())
            },
            "program": self._program_state(),
            "crashed": self._crashed,
            "locked": self._locked,
            "status": self._status_block().pack().hex(" ").upper(),
            "line": {
                "device": self._line.describe(),
                "host": None if self._host is None else self._host.describe(),
                "garbled": self._rx_wire is not None,
                "input_unprotected": self._flow_starved(),
            },
        }

    def observe(self, name: str, now: float) -> Any:
        self._now = max(self._now, now)
        return super().observe(name, now)

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        self._now = max(self._now, now)
        if name == "power_cycle":
            self._power_cycle(now)
            return {"powered_at": self._powering_until}
        if name == "crash":
            signature = params.get("signature", params.get("crash_signature", self.knobs.crash_signature))
            if not isinstance(signature, str) or signature not in SIGNATURE_BYTES:
                raise ControlError(
                    f"signature must be one of {', '.join(SIGNATURE_BYTES)}, got {signature!r}"
                )
            self._crash(now, SIGNATURE_BYTES[signature])
            return True
        if name == "roe":
            return self._roe(params, now)
        if name == "set_line":
            return self._set_line(params, now)
        raise ControlError(f"{self.name}: no input {name!r}; known: {', '.join(INPUTS)}")

    def control_names(self) -> dict[str, list[str]]:
        return {"inputs": list(INPUTS), "observables": sorted(self.snapshot())}

    def summarize(self, direction: str, data: bytes) -> str | None:
        """Host bytes are read from command position; device bytes, paced out one at a time, are
        matched to the replies that were sent: a reply is summarised with its last byte."""
        if direction == "rx":
            return proto.summarize_host(data)
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

    # ---- time-ordered internal events -----------------------------------------------------------

    def _next_event(self) -> tuple[float, str] | None:
        candidates = []
        if self._powering_until is not None:
            candidates.append((self._powering_until, "power_on"))
        if self._run is not None and self._run.final_at < math.inf:
            candidates.append((self._run.final_at, "final"))
        if self._run is None and (self._register_used or self._overrun):
            candidates.append((self._reply_tx_end, "busy_end"))
        if self._lockup_at is not None:
            candidates.append((self._lockup_at, "lockup"))
        if self._rx_queue:
            candidates.append((self._rx_queue[0][0], "rx"))
        if self._rx_wire is not None and self._rx_wire.needed is not None:
            candidates.append((_after(self._rx_wire.needed), "rx"))
        if self._tx_wire is not None and self._tx_wire.needed is not None:
            candidates.append((_after(self._tx_wire.needed), "tx"))
        return min(candidates) if candidates else None

    def _handle(self, t: float, kind: str) -> None:
        if kind == "power_on":
            self._powering_until = None
            self._events.append({"ev": "powered_on"})
        elif kind == "final":
            self._on_final(t)
        elif kind == "busy_end":
            self._on_busy_end(t)
        elif kind == "lockup":
            self._lock(t)
        elif kind == "rx":
            self._pump_rx(t)
        else:
            self._flush_tx(t)

    # ---- line layer (MP-3 ... MP-7) ---------------------------------------------------------------

    def _usb(self) -> bool:
        return self.controller.interface == "usb_vcp"

    def _char_time(self) -> float:
        line = self._line
        return char_time(line.baud, line.data_bits, line.parity, line.stop_bits)

    def _flow_starved(self) -> bool:
        """MP-7: a USB host that did not enable RTS/CTS, with `require_rtscts`."""
        host = self._host
        return self._usb() and self.controller.require_rtscts and host is not None and host.rtscts is False

    def _rebuild_wires(self, now: float) -> None:
        """Garble both directions when the host frames characters differently (MP-6)."""
        self._rx_wire = self._tx_wire = None
        self._rx_queue.clear()
        self.pace_line = self.knobs.pace_line
        host = self._host
        if host is None or self.knobs.line_mismatch != "garble":
            return
        if not any(name in FRAMING_SETTINGS for name in mismatches(self._line, host)):
            return
        device, other = Framing.of(self._line), Framing.of(host, self._line)
        start = Fraction(now)
        self._rx_wire = Wire(other, device, start)
        self._tx_wire = Wire(device, other, start)
        self.pace_line = False  # the wires time both directions exactly

    def _pump_rx(self, t: float) -> None:
        """Decode garbled host input whose levels are all known by `t` (MP-6); process what is due."""
        wire = self._rx_wire
        if wire is not None:
            for char in wire.take(max(wire.line_free, Fraction(t))):
                self._rx_queue.append((max(float(char.time), t), char.value, char.framing_error))
        while self._rx_queue and self._rx_queue[0][0] <= t:
            when, value, framing_error = self._rx_queue.popleft()
            self._on_char(value, framing_error, when)

    def _flush_tx(self, t: float) -> None:
        """Emit what the host's receiver makes of the device's bytes, once final (MP-6 item 5)."""
        wire = self._tx_wire
        if wire is None:
            return
        for char in wire.take(max(wire.line_free, Fraction(t))):
            value = 0 if char.framing_error else char.value
            self._outbox.append(Emission(float(char.time), bytes((value,))))

    def _send(self, t: float, data: bytes, reply: bool = True) -> None:
        """Hand bytes to the transmitter at `t`. `reply`: ends an MP-7 busy period once sent."""
        if self._tx_wire is not None:
            for byte in data:
                self._tx_wire.send(byte, Fraction(t))
            self._tx_free = float(self._tx_wire.line_free)
            self._flush_tx(t)
        else:
            self._outbox.append(Emission(t, data))
            self._tx_log.append([data, proto.summarize_device(data)])
            paced = max(t, self._tx_free) + len(data) * self._char_time()
            self._tx_free = paced if self.knobs.pace_line else t
        if reply:
            self._reply_tx_end = self._tx_free

    def _busy(self, t: float) -> bool:
        """MP-7: from a frame's last byte until its final reply has been transmitted (a byte
        completing within a nanosecond of that end counts as after it: float clocks)."""
        return self._run is not None or t < self._reply_tx_end - TIME_TOLERANCE

    def _clear_register(self) -> None:
        self._register_used = False
        self._kept = None
        self._overrun = False

    def _on_busy_end(self, t: float) -> None:
        kept, overrun = self._kept, self._overrun
        self._clear_register()
        if overrun:
            self._send(t, proto.error_reply(ErrorCode.SP_OVERRUN), reply=False)
            self._show_error(ErrorCode.SP_OVERRUN)
            self._parser.reset()
            self._lockup_at = None
        elif kept is not None:
            self._dispatch(kept[0], kept[1], t)

    # ---- bytes in --------------------------------------------------------------------------------

    def _on_char(self, byte: int, framing_error: bool, t: float) -> None:
        """One character received at `t` (framing_error: not a data byte, MP-6 item 4)."""
        if self._powering_until is not None or self._locked:
            return
        if self._crashed:
            self._crashed_input(byte, framing_error, t)
            return
        if t < self._deaf_until:
            return  # MP-56
        if self._roe_crash_due(t):
            self._crash(t, SIGNATURE_BYTES[self.knobs.crash_signature])
            self._crashed_input(byte, framing_error, t)
            return
        if self._flow_starved() and self._busy(t):
            if self._register_used:
                self._overrun = True
                return
            self._register_used = True
            if self._run is None:
                self._kept = (byte, framing_error)  # parsed when the busy period ends
                return
        self._dispatch(byte, framing_error, t)

    def _dispatch(self, byte: int, framing_error: bool, t: float) -> None:
        if self._run is not None:
            self._byte_during_move(byte, framing_error, t)
        else:
            item = self._parser.feed_byte(byte, framing_error)
            if item is not None:
                self._execute(item, t)
        limit = self.knobs.lockup_incomplete_frame_s
        in_frame = self._parser.state is not ParseState.COMMAND
        self._lockup_at = t + limit if limit is not None and in_frame else None

    def _byte_during_move(self, byte: int, framing_error: bool, t: float) -> None:
        """§7: a byte while an `m`, `k` or `e` is outstanding."""
        run = self._run
        assert run is not None
        parser = self._parser
        clean = not framing_error
        at_command = parser.state is ParseState.COMMAND
        if at_command and clean and byte == CTRL_C:
            self._ctrl_c_during_move(run, t)  # MP-48, even behind a held frame (MP-52)
            return
        if run.moving(t) and self._interrupts(byte, clean, at_command):
            self._halt(run, t, BYTE_HALT)  # MP-51
            if self.knobs.move_interrupt_reply == "error8_4":  # MP-53: the interrupting frame is dropped
                if not (at_command and clean and byte in (CR, LF)):
                    self._abandon_frame()
                    self._frame_during_move(byte, framing_error, t)
                return
        self._frame_during_move(byte, framing_error, t)

    def _interrupts(self, byte: int, clean: bool, at_command: bool) -> bool:
        """Does this byte halt a move in MOVING (MP-50, MP-51)?"""
        if at_command:
            if clean and byte in (CR, LF):
                return self.knobs.terminators_interrupt_move
            return not (clean and byte in QUERY_BYTES and not self.knobs.query_interrupts_move)
        # inside a `c`/`s` frame that was let through: only a bad terminator interrupts
        return self._parser.expects_terminator and not (clean and byte == CR)

    def _frame_during_move(self, byte: int, framing_error: bool, t: float) -> None:
        """MP-52: `c`/`s` frames are answered at once; anything else is held, with all that follows,
        until the final reply has been sent."""
        parser = self._parser
        if self._hold is not None:
            parser.feed_byte(byte, framing_error)  # keep delimiting, to spot ^C in command position
            self._hold.append((byte, framing_error))
            return
        if parser.state is ParseState.DISCARDING:  # the silently dropped frame of MP-53 error8_4
            item = parser.feed_byte(byte, framing_error)
            if item is not None:
                self._execute(item, t)
            return
        before = parser.frame_bytes
        item = parser.feed_byte(byte, framing_error)
        if isinstance(item, Frame) and item.raw[0] in QUERY_BYTES:
            self._execute(item, t)
            return
        if item is None and parser.command_byte in QUERY_BYTES:
            return
        self._hold = [(b, False) for b in before] + [(byte, framing_error)]

    def _abandon_frame(self) -> None:
        """MP-53 `error8_4`: drop the frame being parsed (at most its command byte, so never an
        overrun) through its CR; behind held input the drop waits its turn."""
        self._parser.abandon(None)
        if self._hold is not None:
            self._hold.append(ABANDON_FRAME)

    def _release_hold(self, t: float) -> None:
        """Replay held bytes as if they arrived now, in order (MP-52); a reset among them clears the
        rest (MP-57)."""
        held, self._hold = self._hold, None
        if not held:
            return
        self._parser.reset()
        epoch = self._epoch
        for byte, framing_error in held:
            if self._epoch != epoch:
                break
            if (byte, framing_error) == ABANDON_FRAME:
                self._abandon_frame()
            else:
                self._dispatch(byte, framing_error, t)

    # ---- items and commands ----------------------------------------------------------------------

    def _execute(self, item: Any, t: float) -> None:
        if isinstance(item, Frame):
            self._command(item.command, t)
        elif isinstance(item, CtrlC):
            self._paused = None  # MP-71: abandons a paused program
            self._send(t, b"\r")  # MP-49
        elif isinstance(item, StrayTerminator):
            if self.knobs.stray_terminator_reply == "cr":  # MP-20
                self._send(t, b"\r")
        elif isinstance(item, BadFrame):
            if item.error is not None:
                self._error(t, item.error)
        elif isinstance(item, BufferOverrun):
            self._error(t, ErrorCode.BUFFER_OVERRUN)  # MP-23

    def _command(self, command: proto.Command, t: float) -> None:
        handler = getattr(self, f"_cmd_{type(command).__name__.lower()}")
        handler(command, t)

    def _cmd_getposition(self, command: proto.GetPosition, t: float) -> None:
        self._send(t, proto.encode_position(*self._reported(t)))  # MP-35

    def _cmd_move(self, command: proto.Move, t: float) -> None:
        values = (command.x, command.y, command.z)
        if self._relative:  # MP-33, MP-36: 64-bit arithmetic
            raw = [p + v for p, v in zip(self._phys, values, strict=True)]
        else:
            raw = [v + o for v, o in zip(values, self._origin, strict=True)]
        target = self._limit(raw)
        if target is None:
            self._error(t, ErrorCode.BAD_COMMAND)
            return
        self._start_run(t, target, None)

    def _cmd_setvelocity(self, command: proto.SetVelocity, t: float) -> None:
        velocity = command.velocity  # MP-37
        high = self.controller.max_speed_high_um_s
        limit = high if velocity.high else self.controller.max_speed_low_um_s  # MP-38
        if velocity.speed > limit:
            if self.knobs.velocity_over_limit == "error4":  # MP-39
                self._error(t, ErrorCode.BAD_COMMAND)
                return
            velocity = proto.Velocity(limit, velocity.high)
        self._velocity_word = velocity.word
        self._send(t, b"\r")

    def _cmd_setorigin(self, command: proto.SetOrigin, t: float) -> None:
        self._origin = list(self._phys)  # MP-32
        self._send(t, b"\r")

    def _cmd_absolute(self, command: proto.Absolute, t: float) -> None:
        self._relative = False
        self._send(t, b"\r")

    def _cmd_relative(self, command: proto.Relative, t: float) -> None:
        self._relative = True
        self._send(t, b"\r")

    def _cmd_refresh(self, command: proto.Refresh, t: float) -> None:
        self._refresh_display()  # MP-74
        self._send(t, b"\r")

    def _cmd_reset(self, command: proto.Reset, t: float) -> None:
        self._reset(t, deaf=True)

    def _cmd_getstatus(self, command: proto.GetStatus, t: float) -> None:
        self._send(t, self._status_block().reply())  # MP-60

    def _cmd_download(self, command: proto.Download, t: float) -> None:
        lenient = self.knobs.program_vector_types == "lenient"  # MP-67
        valid = all(v.is_move or v.is_pause or (lenient and v.descriptor) for v in command.vectors)
        if not 1 <= command.program <= proto.MAX_PROGRAM or not valid:
            self._error(t, ErrorCode.BAD_COMMAND)
            return
        self._programs[command.program] = command.vectors  # MP-66
        self._send(t, b"\r")

    def _cmd_execute(self, command: proto.Execute, t: float) -> None:
        if not 1 <= command.program <= proto.MAX_PROGRAM:
            self._error(t, ErrorCode.BAD_COMMAND)  # MP-72
            return
        self._paused = None  # MP-71: a new k abandons a paused program
        vectors = self._programs.get(command.program)
        if vectors is None:
            self._send(t, b"\r")  # MP-72: never downloaded
            return
        self._continue_program(t, _Program(command.program, vectors))

    def _cmd_upload(self, command: proto.Upload, t: float) -> None:
        if not 1 <= command.program <= proto.MAX_PROGRAM:
            self._error(t, ErrorCode.BAD_COMMAND)
            return
        self._send(t, proto.encode_program(self._programs.get(command.program, ())))  # MP-72

    def _cmd_continue(self, command: proto.Continue, t: float) -> None:
        program, self._paused = self._paused, None
        if program is None:
            self._send(t, b"\r")  # MP-70
            return
        if not self.knobs.k_reply_at_pause:
            self._send(t, b"\r")  # MP-68: e answers at once, k's reply comes at the end
        self._continue_program(t, program)

    def _error(self, t: float, code: int) -> None:
        self._send(t, proto.error_reply(code))
        self._show_error(code)

    # ---- motion and programs ---------------------------------------------------------------------

    def _limit(self, raw: list[int]) -> Xyz | None:
        """Physical targets after MP-42 quantisation and MP-36 travel limits; None = reject ('4')."""
        quantum = self.knobs.coarse_step_quantum_usteps
        if quantum > 1 and not self._velocity_word & proto.HIGH_RESOLUTION_BIT:
            raw = [p + _round_to(r - p, quantum) for r, p in zip(raw, self._phys, strict=True)]
        inside = all(0 <= r <= length for r, length in zip(raw, self._travel, strict=True))
        if not inside and self.knobs.out_of_range == "error4":
            return None
        return tuple(min(max(r, 0), length) for r, length in zip(raw, self._travel, strict=True))  # type: ignore[return-value]

    def _start_run(self, t: float, target: Xyz, program: _Program | None) -> None:
        speed = self._velocity_word & 0x7FFF
        motion = _Motion.plan(t, tuple(self._phys), target, self._factors, speed, self.knobs)  # type: ignore[arg-type]
        end = t + motion.duration
        self._run = _Run(motion, end, end + self.knobs.settle_s, program)
        self._events.append({"ev": "move_started", "target_usteps": self._reported_of(target)})

    def _halt(self, run: _Run, t: float, cause: str) -> None:
        """Stop the axes where they are; STOPPING lasts `settle_s` from now (MP-48, MP-51)."""
        run.motion = dataclasses.replace(run.motion, p0=run.position(t), delta=(0, 0, 0))
        run.motion_end = t
        run.final_at = t + self.knobs.settle_s
        run.cause = cause

    def _ctrl_c_during_move(self, run: _Run, t: float) -> None:
        self._send(t, bytes((proto.ACK_INTERRUPT,)), reply=False)
        if run.moving(t):
            self._halt(run, t, CTRL_C_HALT)
        elif run.cause is None:
            run.cause = CTRL_C_HALT  # STOPPING ends as planned, but a program is abandoned (MP-54)

    def _on_final(self, t: float) -> None:
        run = self._run
        assert run is not None
        self._phys = list(run.position(t))
        self._events.append({"ev": "move_ended", "position_usteps": self._reported(t), "halted": run.cause})
        if run.program is not None and run.cause is None:
            self._continue_program(t, run.program)
            return
        self._run = None
        reply = INTERRUPTED_REPLIES[self.knobs.move_interrupt_reply] if run.cause == BYTE_HALT else b"\r"
        if reply != b"\r":
            self._show_error(reply[0])
        self._finish(t, reply)

    def _continue_program(self, t: float, program: _Program) -> None:
        """Run vectors from `program.next` until a move starts, a pause or the end (MP-68 ... MP-70)."""
        self._run = None
        while program.next < len(program.vectors):
            vector = program.vectors[program.next]
            program.next += 1
            if vector.is_pause:
                self._paused = program
                self._finish(t, b"\r" if self.knobs.k_reply_at_pause else None)
                return
            target = self._limit(self._vector_target(vector))
            if target is None:
                self._error(t, ErrorCode.BAD_COMMAND)  # MP-36 error4 abandons the program
                self._finish(t, None)
                return
            self._start_run(t, target, program)
            return
        self._finish(t, b"\r")

    def _vector_target(self, vector: Vector) -> list[int]:
        """MP-69: displacements, or absolute targets in absolute mode with `follow_mode`."""
        if self.knobs.program_vectors == "follow_mode" and not self._relative:
            return [v + o for v, o in zip(vector.xyz, self._origin, strict=True)]
        return [p + v for p, v in zip(self._phys, vector.xyz, strict=True)]

    def _finish(self, t: float, reply: bytes | None) -> None:
        """The outstanding command is over: send its final reply, then replay held input."""
        if reply is not None:
            self._send(t, reply)
        else:
            self._reply_tx_end = max(self._reply_tx_end, t)
        self._release_hold(t)

    # ---- reset, power, faults --------------------------------------------------------------------

    def _enter_power_on_state(self) -> None:
        """MP-76: the profile's status (ROE direction included) and what a reset restores."""
        self._roe_negative = self._template.roe_negative
        self._restore_defaults()

    def _restore_defaults(self) -> None:
        """MP-57: absolute mode, power-on V word, no pending input, no paused program, display
        refreshed."""
        self._relative = False
        self._velocity_word = self.controller.power_on_velocity_word
        self._drop_input()
        self._paused = None
        self._refresh_display()

    def _drop_input(self) -> None:
        """Partial frames, held input and the MP-7 register. Characters still on a garbled line
        (`_rx_queue`) are not received yet: they arrive in their time, like bytes on a clean line."""
        self._epoch += 1
        self._parser.reset()
        self._hold = None
        self._clear_register()
        self._lockup_at = None

    def _reset(self, t: float, deaf: bool) -> None:
        """MP-57: defaults restored; positions, origin, programs (MP-73) and status fields kept."""
        self._restore_defaults()
        if self.knobs.program_retention == "reset":  # MP-73
            self._programs.clear()
        self._events.append({"ev": "reset"})
        if deaf:
            self._deaf_until = t + self.knobs.reset_deaf_s  # MP-56
            if self.knobs.reset_emits_nul:  # MP-58
                self._send(t, b"\x00", reply=False)

    def _stop_everything(self, t: float) -> None:
        """Motion stops where it is; no pending reply will ever be sent."""
        if self._run is not None:
            self._phys = list(self._run.position(t))
            self._run = None
        self._drop_input()

    def _power_cycle(self, t: float) -> None:
        """MP-76: silent and deaf for `power_on_s`, then the power-on state; positions kept."""
        self._stop_everything(t)
        self._crashed = self._locked = False
        self._deaf_until = -math.inf
        self._last_roe = None
        if self.knobs.program_retention != "always":  # MP-73
            self._programs.clear()
        self._enter_power_on_state()
        self._powering_until = t + self.knobs.power_on_s
        self._events.append({"ev": "power_cycle", "powered_at": self._powering_until})

    def _crash(self, t: float, signature: bytes) -> None:
        """MP-77: motion stops, 16 signature bytes, then one per received byte."""
        self._stop_everything(t)
        self._crashed = True
        self._signature = signature
        self._cr_run = 0
        self._last_roe = None
        if signature:
            self._send(t, signature * SIGNATURE_LENGTH, reply=False)
        self._events.append({"ev": "crashed"})

    def _crashed_input(self, byte: int, framing_error: bool, t: float) -> None:
        recovery = self.knobs.crash_recovery  # MP-78
        clean = not framing_error
        if recovery == "ctrl_c" and clean and byte == CTRL_C:
            self._recover(t)
            self._send(t, b"\r")
            return
        if recovery == "cr_burst":
            self._cr_run = self._cr_run + 1 if clean and byte == CR else 0
            if self._cr_run >= CR_BURST:
                self._recover(t)
                return
        if self._signature:
            self._send(t, self._signature, reply=False)

    def _recover(self, t: float) -> None:
        self._crashed = False
        self._reset(t, deaf=False)

    def _lock(self, t: float) -> None:
        """MP-80: silent, ignoring all input, until power cycle."""
        self._stop_everything(t)
        self._locked = True
        self._events.append({"ev": "locked"})

    def _roe_crash_due(self, t: float) -> bool:
        if not self.knobs.roe_crash or self._last_roe is None:
            return False
        low, high = self.knobs.roe_crash_window_s
        return low <= t - self._last_roe < high  # MP-79

    def _roe(self, params: dict[str, Any], t: float) -> dict[str, Any]:
        """MP-79: the rotary encoder moves one axis by clicks × ROE_VARI µsteps, at once."""
        axis = str(params.get("axis", "")).upper()
        clicks = params.get("clicks")
        if axis not in proto.AXES:
            raise ControlError(f"roe needs axis X, Y or Z, got {params.get('axis')!r}")
        if isinstance(clicks, bool) or not isinstance(clicks, int):
            raise ControlError(f"roe needs clicks (an integer), got {clicks!r}")
        state = self._state(t)
        if self._run is not None or state in ("POWERING_ON", "CRASHED", "LOCKED"):
            raise ControlError(f"{self.name}: the ROE acts only while the controller is idle (now {state})")
        index = proto.AXES.index(axis)
        moved = self._phys[index] + clicks * self._template.roe_vari
        self._phys[index] = min(max(moved, 0), self._travel[index])
        if clicks:
            self._roe_negative = clicks < 0
        self._last_roe = t
        self._refresh_display()
        return {"position_usteps": dict(zip(proto.AXES, self._reported(t), strict=True))}

    def _set_line(self, params: dict[str, Any], now: float) -> dict[str, Any]:
        """The front-panel menu (MP-1): baud, parity and stop bits of the RS-232 port."""
        if self._usb():
            raise ControlError(f"{self.name}: the USB virtual COM port is fixed at 9600 8N1 (MP-2)")
        allowed = {"baud": BAUDS, "parity": ("none", "even", "odd"), "stop_bits": (1, 1.5, 2)}
        changes = {}
        for key, value in params.items():
            if key not in allowed:
                raise ControlError(f"set_line takes {', '.join(allowed)}; not {key!r}")
            if value not in allowed[key] or isinstance(value, bool):
                raise ControlError(f"{key} must be one of {', '.join(map(str, allowed[key]))}, got {value!r}")
            changes[key] = value
        self._line = dataclasses.replace(self._line, **changes)
        self._rebuild_wires(now)
        return {"line": self._line.describe()}

    # ---- observables -----------------------------------------------------------------------------

    def _physical(self, t: float) -> Xyz:
        return self._run.position(t) if self._run is not None else tuple(self._phys)  # type: ignore[return-value]

    def _reported_of(self, physical: Xyz) -> Xyz:
        return tuple(p - o for p, o in zip(physical, self._origin, strict=True))  # type: ignore[return-value]

    def _reported(self, t: float) -> Xyz:
        return self._reported_of(self._physical(t))

    def _state(self, t: float) -> str:
        if self._powering_until is not None:
            return "POWERING_ON"
        if self._locked:
            return "LOCKED"
        if self._crashed:
            return "CRASHED"
        if t < self._deaf_until:
            return "DEAF"
        if self._run is not None:
            return "MOVING" if self._run.moving(t) else "STOPPING"
        if self._parser.state is not ParseState.COMMAND:
            return self._parser.state.name
        return "PAUSED" if self._paused is not None else "IDLE"

    def _program_state(self) -> dict[str, Any] | None:
        program = self._run.program if self._run is not None else self._paused
        if program is None:
            return None
        return {"number": program.number, "next_vector": program.next + 1, "paused": program is self._paused}

    def _status_block(self) -> StatusBlock:
        """MP-60 ... MP-64: the template with the live fields filled in."""
        template = self._template
        flags = template.flags & ~0x10 | (0x10 if self._roe_negative else 0)
        if self.knobs.flags_bit5_tracks_move_mode:
            set_bit = self._relative == self.knobs.flags_bit5_relative_is_set
            flags = flags & ~0x20 | (0x20 if set_bit else 0)
        high = self._velocity_word & proto.HIGH_RESOLUTION_BIT
        step_div, step_mul = proto.step_fields(
            proto.XY_USTEPS_PER_UM[self.stage.device_type], self.controller.step_fields_format
        )
        return dataclasses.replace(
            template,
            flags=flags,
            flags_2=template.flags_2 & ~0x04 | (0x04 if high else 0),
            step_div=step_div,
            step_mul=step_mul,
            xspeed=self._velocity_word,
            version=self.controller.firmware_version,
        )

    def _refresh_display(self) -> None:
        """MP-75: line 1 shows the coordinates in µm as of now (never during a move); line 2 is cleared."""
        reported = self._reported_of(tuple(self._phys))  # type: ignore[arg-type]
        self._display = [
            " ".join(
                f"{a}:{p / f:+.2f}" for a, p, f in zip(proto.AXES, reported, self._factors, strict=True)
            ),
            "",
        ]

    def _show_error(self, code: int) -> None:
        """MP-75: line 2 shows the error; an ORed '8' shows the other code, as the unit shows '4'
        for '<'."""
        shown = code & ~0x08 if 0x39 <= code <= 0x3C else code
        self._display[1] = f"ERR {chr(shown)}"


def _round_to(value: int, quantum: int) -> int:
    """Nearest multiple of `quantum`, ties away from zero, in integer arithmetic (MP-42)."""
    magnitude = (2 * abs(value) + quantum) // (2 * quantum) * quantum
    return magnitude if value >= 0 else -magnitude
