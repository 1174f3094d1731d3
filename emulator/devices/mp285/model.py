"""Sutter MP-285 / MP-285A controller: the sans-I/O device model (docs/mp285.md; rule IDs MP-n).

The wire format lives in protocols.mp285; the controller's parts live beside this module, one
concern each: serial_line.py the serial port (MP-1 ... MP-7); receiver.py frames, and bytes while a move
is outstanding (§7); commands.py the dispatch table (§2 ... §10); motion.py geometry, runs and
programs (§4, §6, §10); status.py the status block and display (§9, §11); faults.py crash
signature, recovery and the ROE (§12); movelog.py the traffic log's `move` records.

This module wires them into `Mp285Device`, the state machine of the reference's states (`State`),
which alone enters and leaves states: moves and programs, reset (§8), power cycle, crash, lock-up.

Every output is stamped with the instant its event was due. Internal events (`Event`: end of a move,
end of a busy period, power-on, lock-up, garbled characters becoming complete) are found by
`_next_event` and run in time order by `advance`.

While explaining (a traffic log is kept) the receiver notes each unit of input it parses, this module
what is lost or stray outside it, `send` summarises each output as a reply to `_cause` (the item
being executed, or the command that started a run), and runs and rests become `move` records.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from emulator.device import (
    FRAMING_ERROR,
    MAIN,
    ControlError,
    Device,
    DeviceServices,
    Emission,
    HostLine,
    LineSettings,
    ModemLines,
)
from emulator.devices.mp285.commands import run_item
from emulator.devices.mp285.faults import Crash, Roe, crash_signature, roe_turn
from emulator.devices.mp285.motion import INTERRUPTED_REPLIES, Halt, Program, Run, Stage, Xyz
from emulator.devices.mp285.movelog import rest_record, run_record
from emulator.devices.mp285.receiver import Receiver
from emulator.devices.mp285.schema import Mp285Config, speed_limits
from emulator.devices.mp285.serial_line import SerialLine
from emulator.devices.mp285.states import DEAF_REASONS, FRAME_STATES, LISTENING, ROE_REFUSED, Event, State
from emulator.devices.mp285.status import Display, Status
from emulator.profiles.profile import Profile
from protocols import mp285 as proto
from protocols.mp285 import ErrorCode, Item, StatusBlock, Vector, Velocity

#: control-channel inputs (`ctl input`), see docs/mp285.md
INPUTS = ("crash", "power_cycle", "roe", "set_line")


class Mp285Device(Device):
    """One MP-285 or MP-285A controller with its stage. It holds its `State` in `_state` and makes
    every transition (states.py lists them); `_run` is set exactly while MOVING."""

    def __init__(
        self, name: str, profile: Profile[Mp285Config], now: float, services: DeviceServices
    ) -> None:
        super().__init__(name, profile, now, services)
        config = profile.config
        self.controller = config.controller
        self.knobs = config.knobs
        self.speed_limits = speed_limits(self.controller)
        line = profile.line
        settings = LineSettings(
            line.baud, line.data_bits, line.parity, line.stop_bits, line.flow_control == "rtscts", False
        )
        self._line = SerialLine(settings, self.controller, self.knobs, self._emit, self.notes)
        self.pace_line = self._line.pace_line
        self.stage = Stage(config.stage, self.knobs)
        self.status = Status(self.controller, config.stage, self.knobs)
        self.display = Display(self.stage.factors)
        self.programs: dict[int, tuple[Vector, ...]] = {}
        self.relative = False
        self.velocity = Velocity.from_word(self.controller.power_on_velocity_word)
        self._receiver = Receiver(
            self.knobs, self.notes, self._run_item, self._ack_interrupt, self._current_run
        )
        self._crash = Crash(self.knobs)
        self._roe = Roe(self.knobs)
        self._state = State.IDLE
        self._run: Run | None = None
        self._paused: Program | None = None
        self._deaf_until = -math.inf
        self._powering_until = -math.inf
        #: a crash injected while POWERING_ON (CRASHED once powered) or LOCKED (shown, nothing else)
        self._crash_latched = False
        #: what replies answer now, and what the run's final reply will answer (while explaining)
        self._cause: str | None = None
        self._run_cause: str | None = None
        self._enter_power_on_state(now)  # MP-76: at daemon start, at once

    # ---- Device contract ------------------------------------------------------------------------

    def _receive(self, data: bytes, now: float, channel: str) -> None:
        on_char = self._on_char
        if self._line.garbled:
            self._line.receive_garbled(data, now, on_char)
            return
        for byte in data:
            on_char(byte, False, now)

    def _receive_line_error(self, byte: int, kind: str, now: float, channel: str) -> None:
        # a real line's error (a serial port): MP-6 item 4, a framing error is not a data byte
        # (error '1'); item 3, a parity error is ignored and the data bits kept
        self._on_char(byte, kind == FRAMING_ERROR, now)

    def _advance(self, now: float) -> None:
        while True:
            event = self._next_event()
            if event is None or event[0] > now:
                break
            self._handle(*event)
        self._line.flush_tx(now)

    def next_deadline(self) -> float | None:
        event = self._next_event()
        return None if event is None else event[0]

    def line_settings(self, channel: str = MAIN) -> LineSettings:
        return self._line.settings

    def line_changed(self, host: HostLine | None, now: float, channel: str = MAIN) -> None:
        self._line.host_changed(host, now)
        self.pace_line = self._line.pace_line

    def mismatch_effect(self, host: HostLine, channel: str = MAIN) -> str:
        return self._line.mismatch_effect(host)

    def modem_lines(self, channel: str = MAIN) -> ModemLines:
        return self._line.modem_lines()  # MP-1, MP-2

    def snapshot(self, now: float) -> dict[str, Any]:
        velocity = self.velocity
        return {
            "model": self.controller.model,
            "interface": self.controller.interface,
            "state": self.state(now).value,
            "parser": self._receiver.parser.state.value,
            **self.stage.snapshot(self._run, now),
            "mode": "relative" if self.relative else "absolute",
            "velocity": {
                "word": velocity.word,
                "speed_um_s": velocity.speed,
                "resolution": "high" if velocity.high else "low",
            },
            "display": list(self.display.lines),
            "programs": {
                str(number): [dataclasses.asdict(v) for v in vectors]
                for number, vectors in sorted(self.programs.items())
            },
            "program": self._program_state(),
            "crashed": self._state is State.CRASHED or self._crash_latched,
            "locked": self._state is State.LOCKED,
            "status": self.status_block().pack().hex(" ").upper(),
            "line": self._line.snapshot(),
        }

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        if name == "power_cycle":
            self._power_cycle(now)
            return {"powered_at": self._powering_until}
        if name == "crash":
            self._enter_crashed(now, crash_signature(params, self.knobs.crash_signature), "control input")
            return True
        if name == "roe":
            return self._turn_roe(params, now)
        if name == "set_line":
            if self._line.usb:
                raise ControlError(f"{self.name}: the USB virtual COM port is fixed at 9600 8N1 (MP-2)")
            self._line.set_menu(params, now)
            self.pace_line = self._line.pace_line
            return {"line": self._line.settings.describe()}
        raise ControlError(f"{self.name}: no input {name!r}; known: {', '.join(INPUTS)}")

    def control_names(self) -> dict[str, list[str]]:
        return {"inputs": list(INPUTS), "observables": sorted(self.snapshot(self.now))}

    # ---- state -----------------------------------------------------------------------------------

    def state(self, t: float) -> State:
        """The reference's state at `t` (see `State`)."""
        state = self._state
        if state is State.MOVING:
            assert self._run is not None
            return State.MOVING if self._run.moving(t) else State.STOPPING
        if state is State.DEAF and t >= self._deaf_until:
            state = State.IDLE
        if state is State.IDLE or state is State.PAUSED:
            return FRAME_STATES.get(self._receiver.parser.state, state)
        return state

    def _rest(self) -> None:
        """Nothing outstanding: PAUSED while a program waits for `e` (MP-71), else IDLE."""
        self._run = None
        self._state = State.PAUSED if self._paused is not None else State.IDLE

    def take_paused(self) -> Program | None:
        """The paused program, which `e` resumes and `k` or ^C abandon (MP-70, MP-71)."""
        program, self._paused = self._paused, None
        if self._state is State.PAUSED:
            self._state = State.IDLE
        return program

    # ---- time-ordered internal events -----------------------------------------------------------

    def _next_event(self) -> tuple[float, Event] | None:
        candidates: list[tuple[float, Event]] = []
        if self._state is State.POWERING_ON:
            candidates.append((self._powering_until, Event.POWER_ON))
        line = self._line
        if self._run is not None:
            if self._run.final_at < math.inf:
                candidates.append((self._run.final_at, Event.FINAL))
        elif line.register_used:
            candidates.append((line.reply_tx_end, Event.BUSY_END))
        lockup_at = self._receiver.lockup_at
        if lockup_at is not None:
            candidates.append((lockup_at, Event.LOCKUP))
        if line.garbled:
            rx, tx = line.rx_due(), line.tx_due()
            if rx is not None:
                candidates.append((rx, Event.RX))
            if tx is not None:
                candidates.append((tx, Event.TX))
        return min(candidates) if candidates else None

    def _handle(self, t: float, kind: Event) -> None:
        if kind is Event.RX:
            self._line.pump_rx(t, self._on_char)
        elif kind is Event.TX:
            self._line.flush_tx(t)
        elif kind is Event.FINAL:
            self._on_final(t)
        elif kind is Event.BUSY_END:
            self._on_busy_end(t)
        elif kind is Event.LOCKUP:
            self._lock(t)
        else:
            self._powered_on()

    # ---- output ----------------------------------------------------------------------------------

    def _emit(self, emission: Emission) -> None:
        self._outbox.append(emission)

    def send(self, t: float, data: bytes, reply: bool = True, unsolicited: str | None = None) -> None:
        """Hand bytes to the transmitter at `t`. `reply`: ends an MP-7 busy period once sent.
        `unsolicited`: why the device sends them on its own (else they answer `_cause`)."""
        summary = None
        if self.notes.on:
            if unsolicited is None:
                summary = proto.summarize_device(data, self._cause)
            else:
                summary = f"{unsolicited}: {proto.summarize_device(data)}"
        self._line.send(t, data, reply, summary, unsolicited is not None)

    def error(self, t: float, code: int) -> None:
        self.send(t, proto.error_reply(code))
        self.display.show_error(code)

    def reported(self, t: float) -> Xyz:
        return self.stage.reported(self.stage.at(self._run, t))

    def status_block(self) -> StatusBlock:
        return self.status.block(self.relative, self.velocity)

    def refresh_display(self) -> None:
        self.display.refresh(self.stage.reported(self.stage.physical))

    # ---- bytes in --------------------------------------------------------------------------------

    def _on_char(self, byte: int, framing_error: bool, t: float) -> None:
        """One character received at `t` (framing_error: not a data byte, MP-6 item 4)."""
        state = self._state
        if state not in LISTENING:
            if state is State.CRASHED:
                self._crashed_input(byte, framing_error, t)
                return
            if state is not State.DEAF or t < self._deaf_until:
                if self.notes.on:
                    self._receiver.lost(t, byte, DEAF_REASONS[state])
                return  # MP-56 (DEAF), MP-76 (POWERING_ON), MP-80 (LOCKED)
            self._state = State.IDLE  # the DEAF period is over
        if self._roe.last is not None and self._roe.crash_due(t):  # MP-79
            self._enter_crashed(t, self._crash.profile_signature, "a byte in the ROE crash window")
            self._crashed_input(byte, framing_error, t)
            return
        line = self._line
        if line.flow_starved and not line.admit(byte, framing_error, t, self._run is not None):
            if self.notes.on and line.overrun:
                self._receiver.lost(t, byte, "overrun: busy, receive register full (MP-7)")
            return  # MP-7
        self._receiver.dispatch(byte, framing_error, t, self._run)

    def _on_busy_end(self, t: float) -> None:
        kept, overrun = self._line.end_busy()
        if overrun:
            self.send(t, proto.error_reply(ErrorCode.SP_OVERRUN), False, "receive register overrun")  # MP-7
            self.display.show_error(ErrorCode.SP_OVERRUN)
            self._receiver.forget_frame(t, b"" if kept is None else bytes((kept[0],)))
        elif kept is not None:
            self._receiver.dispatch(kept[0], kept[1], t, self._run)

    def _run_item(self, item: Item, t: float) -> None:
        if self.notes.on:
            self._cause = proto.describe_item(item)
        run_item(self, item, t)

    def _ack_interrupt(self, t: float) -> None:
        """MP-48: ^C during a move is acknowledged at once."""
        if self.notes.on:
            self._cause = "^C during a move"
        self.send(t, bytes((proto.ACK_INTERRUPT,)), reply=False)

    def _current_run(self) -> Run | None:
        return self._run

    # ---- moves and programs ----------------------------------------------------------------------

    def start_run(self, t: float, target: Xyz, program: Program | None) -> None:
        """MOVING towards `target` (MP-43 ... MP-47), for `m` or a program's move vector."""
        self._run = self.stage.start(t, target, self.velocity.speed, program)
        self._run_cause = self._cause
        self._state = State.MOVING
        self._events.append({"ev": "move_started", "target_usteps": self.stage.reported(target)})
        if self.notes.on:
            self._events.append(run_record(self._run.motion, self.stage))

    def _log_rest(self, t: float) -> None:
        """The stage rests at its physical position from `t` (a traffic-log `move` record)."""
        if self.notes.on:
            self._events.append(rest_record(t, self.stage.physical, self.stage))

    def _on_final(self, t: float) -> None:
        run = self._run
        assert run is not None
        self._cause = self._run_cause
        self.stage.physical = run.position(t)
        halted = None if run.cause is None else run.cause.value
        if halted is not None:  # written now, stamped with the halt's instant
            self._log_rest(run.motion_end)
        self._events.append({"ev": "move_ended", "position_usteps": self.reported(t), "halted": halted})
        if run.program is not None and run.cause is None:
            self.continue_program(t, run.program)
            return
        self._rest()
        reply = INTERRUPTED_REPLIES[self.knobs.move_interrupt_reply] if run.cause is Halt.BYTE else b"\r"
        if reply != b"\r":
            self.display.show_error(reply[0])
        self._finish(t, reply)

    def continue_program(self, t: float, program: Program) -> None:
        """Run vectors from `program.next` until a move starts, a pause or the end (MP-68 ... MP-70)."""
        self._rest()
        while program.next < len(program.vectors):
            vector = program.vectors[program.next]
            program.next += 1
            if vector.is_pause:
                self._paused = program
                self._state = State.PAUSED
                self._finish(t, b"\r" if self.knobs.k_reply_at_pause else None)
                return
            target = self.stage.vector_target(vector, self.relative, self.velocity.high)
            if target is None:
                self.error(t, ErrorCode.BAD_COMMAND)  # MP-36 error4 abandons the program
                self._finish(t, None)
                return
            self.start_run(t, target, program)
            return
        self._finish(t, b"\r")

    def _finish(self, t: float, reply: bytes | None) -> None:
        """The outstanding command is over: send its final reply, then replay held input (MP-52)."""
        if reply is not None:
            self.send(t, reply)
        else:
            self._line.nothing_sent(t)
        self._receiver.release(t)

    def _program_state(self) -> dict[str, Any] | None:
        program = self._run.program if self._run is not None else self._paused
        if program is None:
            return None
        return {"number": program.number, "next_vector": program.next + 1, "paused": program is self._paused}

    # ---- reset, power, faults --------------------------------------------------------------------

    def _enter_power_on_state(self, t: float) -> None:
        """MP-76: the profile's status (ROE direction included) and what a reset restores."""
        self.status.power_on()
        self._restore_defaults(t, "power-on (MP-76)")

    def _restore_defaults(self, t: float, why: str) -> None:
        """MP-57: absolute mode, power-on V word, no pending input, no paused program, display
        refreshed."""
        self.relative = False
        self.velocity = Velocity.from_word(self.controller.power_on_velocity_word)
        self._drop_input(t, why)
        self._paused = None
        self.refresh_display()

    def _drop_input(self, t: float, why: str) -> None:
        """Partial frames, held input and the MP-7 register (`why`: for the traffic log).
        Characters still on a garbled line are not received yet: they arrive in their time, like
        bytes on a clean line."""
        kept = self._line.clear_register()
        self._receiver.drop(t, why, b"" if kept is None else bytes((kept[0],)))

    def soft_reset(self, t: float, deaf: bool) -> None:
        """MP-57: defaults restored; positions, origin, programs (MP-73) and status fields kept.
        Then DEAF for `reset_deaf_s` (MP-56), or for what is left of an earlier DEAF period."""
        self._restore_defaults(t, "reset (MP-57)")
        if self.knobs.program_retention == "reset":  # MP-73
            self.programs.clear()
        self._events.append({"ev": "reset"})
        if deaf:
            self._deaf_until = t + self.knobs.reset_deaf_s  # MP-56
            if self.knobs.reset_emits_nul:  # MP-58
                self.send(t, b"\x00", False, "reset (MP-58)")
        self._state = State.DEAF if t < self._deaf_until else State.IDLE

    def _stop_everything(self, t: float, why: str) -> None:
        """Motion stops where it is; no pending reply will ever be sent. The caller sets the state."""
        if self._run is not None:
            self.stage.physical = self._run.position(t)
            self._run = None
            self._log_rest(t)
        self._drop_input(t, why)

    def _power_cycle(self, t: float) -> None:
        """MP-76: silent and deaf for `power_on_s`, then the power-on state; positions kept."""
        self._stop_everything(t, "power cycle (MP-76)")
        self._crash_latched = False
        self._deaf_until = -math.inf
        self._roe.last = None
        if self.knobs.program_retention != "always":  # MP-73
            self.programs.clear()
        self._enter_power_on_state(t)
        self._powering_until = t + self.knobs.power_on_s
        self._state = State.POWERING_ON
        self._events.append({"ev": "power_cycle", "powered_at": self._powering_until})

    def _powered_on(self) -> None:
        self._state = State.CRASHED if self._crash_latched else State.IDLE
        self._crash_latched = False
        self._events.append({"ev": "powered_on"})

    def _enter_crashed(self, t: float, signature: bytes, why: str) -> None:
        """MP-77: motion stops, 16 signature bytes, then one per received byte."""
        self._stop_everything(t, "crash (MP-77)")
        if self._state is State.POWERING_ON or self._state is State.LOCKED:
            self._crash_latched = True
        else:
            self._state = State.CRASHED
        self._roe.last = None
        data = self._crash.start(signature)
        if data:
            self.send(t, data, False, f"crash signature after {why} (MP-77)")
        self._events.append({"ev": "crashed"})

    def _crashed_input(self, byte: int, framing_error: bool, t: float) -> None:
        recovered, reply = self._crash.on_byte(byte, framing_error)  # MP-78
        if self.notes.on:
            self._cause = f"{byte:02X} while CRASHED"
            self._receiver.stray(t, byte, self._cause + (": recovers (MP-78)" if recovered else ""))
        if recovered:
            self.soft_reset(t, deaf=False)
            if reply:
                self.send(t, reply)
        elif reply:
            self.send(t, reply, reply=False)

    def _lock(self, t: float) -> None:
        """MP-80: silent, ignoring all input, until power cycle."""
        self._stop_everything(t, "lock-up (MP-80)")
        self._state = State.LOCKED
        self._events.append({"ev": "locked"})

    def _turn_roe(self, params: dict[str, Any], t: float) -> dict[str, Any]:
        """MP-79: the rotary encoder moves one axis by clicks × ROE_VARI µsteps, at once."""
        axis, clicks = roe_turn(params)
        state = self.state(t)
        if state in ROE_REFUSED:
            raise ControlError(
                f"{self.name}: the ROE acts only while the controller is idle (now {state.value})"
            )
        self.stage.turn(axis, clicks * self.status.template.roe_vari)
        self._log_rest(t)
        if clicks:
            self.status.roe_negative = clicks < 0
        self._roe.last = t
        self.refresh_display()
        return {"position_usteps": dict(zip(proto.AXES, self.reported(t), strict=True))}
