"""SEQUENCER: programmed sequences of blocks and outputs (§9.10, MS-SEQ-1…MS-SEQ-8).

The program (blocks with START/REPEAT conditions, delay, repetitions and a completion action; TTL,
analog and stage-stepper outputs) arrives whole through the control input `sequencer`
(sequencer_program.py checks it), since ASI's serial programming commands are not public: those
answer `:N-1` like any unknown command. The block engine is sequencer_engine.py; this file wires it
to the controller: `ARM` (raise ARM_COMMAND_RCVD; `X` re-initialise; `Y=1/0` block-transition
events on/off; `Z` stop everything), IN0 edges, the `@` button, the stage going idle and ARRAY's
arrivals as conditions; completion actions; TTL0 on the OUT0 BNC; the LCD line. The program outlives
resets (it is the rig's wiring, not a controller setting); the engine starts idle after each.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.buttons import NORMAL
from emulator.devices.ms2000.calls import NUMBER_LIMIT, Call, Reply, first_error, number
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, LcdLine, PanelButtons, TtlOut
from emulator.devices.ms2000.modules.events import ArrayArrival, Halt, In0Edge, MoveComplete, Reset, RmX, on
from emulator.devices.ms2000.modules.sequencer_engine import Engine
from emulator.devices.ms2000.modules.sequencer_program import (
    ARM_COMMAND,
    ARRAY_MOVE_DONE,
    AT_BUTTON,
    AVO_MAX_V,
    STAGE_NOT_BUSY,
    TTL_COUNT,
    TTL_TRIGGER,
    Output,
    Program,
    parse,
)
from emulator.profiles.schema import Choice, Field
from protocols.ms2000 import ErrorCode, Item, Kind
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

#: BE F function: the sequencer's `@` event (Appendix B)
FN_AT = 15
#: OUT0 mode in which TTL0 of a program drives the BNC (MS-SEQ-1 [choice])
FREE_OUT0_MODE = 0
#: completion actions (MS-SEQ-5)
RING_BUFFER_NEXT, AUTOFOCUS, ARRAY_NEXT, ARRAY_START, SEND_WHERE, SEND_TIME, SEND_STATE = range(1, 8)
#: the IN0 functions and `RM X` value the module actions reuse (MS-90, MS-RB-5, MS-ARRAY-6)
RING_BUFFER_IN0_MODE, AUTOFOCUS_IN0_MODE, ARRAY_IN0_MODE, ARRAY_START_RM_X = 1, 3, 7, 1
#: line 2 of the LCD is 20 characters and ends with ` hh:mm:ss` (§9.0, MS-SEQ-8)
SEGMENT_WIDTH = 20 - len(" hh:mm:ss")
#: the modules whose state characters lead the segment, in this order (MS-SEQ-8)
SEGMENT_MODULES = ("PLANAR CORRECTION", "ARRAY MODULE")


@register
class Sequencer(Module, LcdLine, TtlOut, PanelButtons, ControlChannel):
    name = "SEQUENCER"
    knob_fields = (
        Field(
            "sequencer_send_actions",
            Choice(("noop", "emit")),
            "noop",
            "MS-SEQ-5",
            "SEQUENCER actions 5–7 (send WHERE, timestamp, statestamp) do nothing or send a line",
        ),
    )
    out0_modes = frozenset({FREE_OUT0_MODE})
    button_priority = 10  # first of all (MS-85)
    observable = "sequencer"
    inputs = frozenset({"sequencer"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.engine = Engine(self, Program())
        #: block-transition events on the control channel (`ARM Y`, MS-SEQ-6 [choice: on at reset])
        self.log = True
        self.armed_at = 0.0
        self.ttl = [0] * TTL_COUNT
        self.avo: dict[int, float] = {}
        self.stage_steps: dict[str, int] = {}

    @property
    def program(self) -> Program:
        return self.engine.program

    def handlers(self) -> dict[str, Handler]:
        return {"ARM": self.arm}

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {FN_AT: self.at_press}

    # ---- the program (MS-SEQ-8) -----------------------------------------------------------------

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """`sequencer {blocks, outputs}` replaces the whole program, or changes nothing."""
        axes = [a.letter for a in self.controller.axes]
        program = parse(params, self.controller.cfg.modules, axes)
        self.engine.initialise(False, now)
        self.engine = Engine(self, program)
        self._rest_outputs(now)
        return program.describe()

    def observe(self, now: float) -> Any:
        return {
            "program": self.program.describe(),
            "blocks": [{"state": b.state, "repetition": b.repetition} for b in self.engine.blocks],
            "running": self.engine.running,
            "log": self.log,
            "ttl": list(self.ttl),
            "avo": {str(k): v for k, v in sorted(self.avo.items())},
            "stage_steps": dict(self.stage_steps),
        }

    # ---- ARM (MS-SEQ-6) ------------------------------------------------------------------------

    def arm(self, call: Call) -> Reply:
        """Bare: ARM_COMMAND_RCVD. `X` re-initialises, `Y=1`/`Y=0` turns the log on/off (`Y?` reads
        it), `Z` stops the sequence and the stage. Every item is checked before any acts."""
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            self.armed_at = call.now
            self.engine.outside(ARM_COMMAND, call.now)
            return self.controller.ack()
        codes: list[int] = []
        chosen: dict[str, Item] = {}
        for item in items:
            if item.kind is Kind.MALFORMED:
                codes.append(ErrorCode.UNDEFINED)
            elif item.letter not in ("X", "Y", "Z"):
                codes.append(ErrorCode.BAD_AXIS)
            elif item.kind is Kind.QUERY and item.letter != "Y":
                codes.append(ErrorCode.OUT_OF_RANGE)  # only the log flag has a value to read
            elif item.kind is Kind.SET and abs(item.value or 0.0) > NUMBER_LIMIT:
                codes.append(ErrorCode.OUT_OF_RANGE)  # beyond the 32-bit variable (MS-26)
            elif item.letter == "Y" and item.kind is not Kind.QUERY and number(item) not in (0, 1):
                codes.append(ErrorCode.OUT_OF_RANGE)
            else:
                chosen[item.letter or ""] = item  # a repeated letter: the last wins (MS-27)
        first_error(codes)
        log = chosen.get("Y")
        if log is not None and log.kind is not Kind.QUERY:
            self.log = number(log) == 1
        if "X" in chosen:
            self.reinitialise(call.now)
        if "Z" in chosen:
            self.stop(call.now)
        if log is not None and log.kind is Kind.QUERY:
            return self.controller.render(call.key).items([("Y", str(int(self.log)))])
        return self.controller.ack()

    def reinitialise(self, now: float) -> None:
        """`ARM X`: blocks idle, ALWAYS blocks ready (and so started), outputs at rest."""
        self.armed_at = now
        self._rest_outputs(now)
        self.engine.initialise(True, now)

    def stop(self, now: float) -> None:
        """`ARM Z`, `@` while running, a recursion error: every motion halts (MS-76) and the
        sequencer re-initialises with its ALWAYS blocks idle; the halt hook below does the latter."""
        self.controller.halt_all(now)

    @on(Halt)
    def halt(self, event: Halt) -> None:
        """HALT stops the sequence too: it is one of the sequences MS-76 ends [choice]."""
        now = event.t
        self.engine.initialise(False, now)

    @on(Reset)
    def reset(self, event: Reset) -> None:
        now = event.t
        self.log = True
        self.armed_at = now
        self.engine.initialise(False, now)
        self._rest_outputs(now)

    # ---- conditions from the controller (MS-SEQ-2) ---------------------------------------------

    @on(In0Edge)
    def in0_edge(self, event: In0Edge) -> None:
        self.engine.outside(TTL_TRIGGER, event.t)

    @on(ArrayArrival)
    def array_arrival(self, event: ArrayArrival) -> None:
        self.engine.outside(ARRAY_MOVE_DONE, event.t)

    @on(MoveComplete)
    def move_complete(self, event: MoveComplete) -> None:
        """XYZ_STAGE_NOT_BUSY: the busy→idle transition, seen when a move ends with nothing else
        still moving [choice]."""
        now = event.t
        if not any(a.busy(now) for a in self.controller.axes):
            self.engine.outside(STAGE_NOT_BUSY, now)

    def button(self, name: str, press: str, now: float) -> bool:
        """`@` (normal press) while running stops it; while idle it is AT_BUTTON_PRESSED when the
        program waits for it, else it is left to the other modules (MS-SEQ-7, MS-85)."""
        if (name, press) != ("at", NORMAL):
            return False
        if not self.engine.running and AT_BUTTON not in {c.code for c in self.program.conditions()}:
            return False
        self.at_press(now)
        return True

    def at_press(self, now: float) -> None:
        if self.engine.running:
            self.stop(now)
        else:
            self.engine.outside(AT_BUTTON, now)

    # ---- what the engine does (sequencer_engine.EngineSide) --------------------------------------

    def at(self, due: float, action: Callable[[float], None]) -> Timer:
        return self.controller.at(due, action)

    def transition(self, block: int, transition: str, repetition: int | None, now: float) -> None:
        if self.log:
            event: dict[str, Any] = {"ev": "seq_block", "block": block, "transition": transition, "t": now}
            if repetition is not None:
                event["repetition"] = repetition
            self.controller.push_event(event)

    def recursion_error(self, now: float) -> None:
        """MS-SEQ-4: the sequencer stops as with `ARM Z` [choice: no error-log code is known]."""
        self.controller.push_event({"ev": "seq_recursion_error", "t": now})
        self.stop(now)

    def act(self, action: int, now: float) -> None:
        """A completion action (MS-SEQ-5); module actions do what their IN0 function or `RM X=1` does."""
        controller = self.controller
        if action == RING_BUFFER_NEXT:
            controller.in0_function(RING_BUFFER_IN0_MODE, now)
        elif action == AUTOFOCUS:
            controller.in0_function(AUTOFOCUS_IN0_MODE, now)
        elif action == ARRAY_NEXT:
            controller.in0_function(ARRAY_IN0_MODE, now)
        elif action == ARRAY_START:
            controller.emit(RmX(now, ARRAY_START_RM_X))
        elif action >= SEND_WHERE and controller.knobs.sequencer_send_actions == "emit":
            self._send(self._report(action, now), now)

    def _report(self, action: int, now: float) -> str:
        if action == SEND_WHERE:
            return ":A " + " ".join(self.controller.where(a.units(now)) for a in self.controller.axes)
        if action == SEND_TIME:
            return f"T {round_half_away((now - self.armed_at) * 1000)}"
        return "S " + " ".join(self.engine.state_chars())

    def _send(self, text: str, now: float) -> None:
        """After the reply of the command that caused it (a line is never cut into, MS-96)."""
        self.controller.at(now, lambda due: self.controller.unsolicited(text, due))

    def output(self, output: Output, start: bool, now: float) -> None:
        if output.kind == "ttl":
            assert isinstance(output.index, int)
            self.ttl[output.index] = 1 if start else 0
            if output.index == 0:
                self.controller.refresh_out0(now)
        elif output.kind == "avo":
            assert isinstance(output.index, int)
            value = self.avo.get(output.index, output.initial) + output.step_size if start else output.initial
            self.avo[output.index] = min(max(value, 0.0), AVO_MAX_V)
        else:
            self._stage(output, start, now)

    def _stage(self, output: Output, step: bool, now: float) -> None:
        """STG: a commanded move by `step_size` units from the target, or back to `initial`."""
        axis = self.controller.axis_named(str(output.index))
        if axis is None:
            return
        if step:
            goal = self.controller.relative_goal(axis, output.step_size / axis.s.unit_multiplier, now)
            self.stage_steps[axis.letter] = self.stage_steps.get(axis.letter, 0) + 1
        else:
            goal = round_half_away(axis.counts_of_units(output.initial))
            self.stage_steps[axis.letter] = 0
        self.controller.start_moves([(axis, float(goal))], now)

    def _rest_outputs(self, now: float) -> None:
        """TTLs low, analog outputs at their start values, step counts 0."""
        self.ttl = [0] * TTL_COUNT
        self.avo = {int(o.index): o.initial for o in self.program.outputs if o.kind == "avo"}
        self.stage_steps = {str(o.index): 0 for o in self.program.outputs if o.kind == "stg"}
        self.controller.refresh_out0(now)

    # ---- OUT0 and the LCD ------------------------------------------------------------------------

    def out0_level(self) -> int | None:
        """TTL0 drives the BNC in OUT0 mode 0 when the program uses it; else OUT0 is the base's."""
        drives = any(o.kind == "ttl" and o.index == 0 for o in self.program.outputs)
        return self.ttl[0] if drives else None

    def lcd_line(self, now: float, states: Mapping[str, str]) -> str | None:
        """The planar and array state characters of those present, then as many block state
        characters as fit before the uptime (MS-SEQ-8, MS-ARRAY-7)."""
        line = " ".join(states[name] for name in SEGMENT_MODULES if name in states)
        for char in self.engine.state_chars():
            longer = f"{line} {char}" if line else char
            if len(longer) > SEGMENT_WIDTH:
                break
            line = longer
        return line
