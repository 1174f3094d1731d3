"""RING BUFFER: stored positions visited in turn (§9.2, MS-RB-1…MS-RB-7).

`LD` stores a position (units, like `M`; `L+` the current one) in the next free slot; `RM` clears,
reports, selects the played axes (`RM Y`, also the axes IN0 mode 5 reports), sets the pointer and
the playback mode. A "next" trigger (IN0 pulse in mode 1, bare `RM`, `@` press) moves the selected
axes to the slot at the pointer (mode 1), or plays the buffer every `RT Z` ms once (mode 2) or in a
loop until the next trigger (mode 3). Buffer contents are volatile; `RM Y` and `RM F` are saved by
`SS Z`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.buttons import EXTRA, LONG, NORMAL
from emulator.devices.ms2000.calls import (
    Call,
    CommandError,
    Param,
    Reply,
    axis_items,
    number,
    one_of,
    run_settings,
)
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import (
    ControlChannel,
    LcdSegment,
    PanelButtons,
    Playback,
    ReportAxes,
    RmXServer,
    TtlIn,
)
from emulator.devices.ms2000.modules.events import Halt, Reset, RmX, on
from emulator.profiles.schema import Bool, Choice, Field
from protocols.ms2000 import ErrorCode, Kind

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

FACTORY_MASK = 3  # X and Y (MS-RB-4)
FACTORY_MODE = 1
AUTOPLAY_FLAG = 128
#: BE F function numbers (Appendix B)
FN_NEXT, FN_STORE, FN_CLEAR = 4, 5, 6


@register
class RingBuffer(Module, ReportAxes, Playback, TtlIn, PanelButtons, LcdSegment, ControlChannel):
    name = "RING BUFFER"
    profile_fields = (
        Field(
            "ring_buffer_size", Choice((50, 250)), 50, "MS-RB-1", "ring buffer capacity (RING BUFFER module)"
        ),
    )
    knob_fields = (
        Field("bu_x_ring_buffer_size", Bool(), True, "MS-102", "BU X prints `RING BUFFER <size>`"),
    )
    in0_modes = frozenset({1})
    button_priority = 70
    observable = "ring_buffer"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.size: int = controller.cfg.ring_buffer_size
        self.slots: list[dict[str, float]] = []
        self.pointer = 0
        self.axis_mask = self._factory_mask()
        self.mode = FACTORY_MODE
        self._play: Timer | None = None

    def _factory_mask(self) -> int:
        return min(FACTORY_MASK, (1 << len(self.controller.axes)) - 1)

    def handlers(self) -> dict[str, Handler]:
        return {"LD": self.load, "RM": self.rbmode}

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {FN_NEXT: self.trigger, FN_STORE: self.store_here, FN_CLEAR: self.clear}

    def bu_line(self) -> str:
        return f"{self.name} {self.size}" if self.controller.knobs.bu_x_ring_buffer_size else self.name

    def lcd_segment(self, now: float) -> str | None:
        return f"RB {self.pointer}/{len(self.slots)}"

    def observe(self, now: float) -> Any:
        return {
            "count": len(self.slots),
            "pointer": self.pointer,
            "mode": self.mode,
            "axis_mask": self.axis_mask,
            "playing": self.playing,
            "slots": [dict(slot) for slot in self.slots],
        }

    def report_mask(self) -> int:
        return self.axis_mask

    def save(self) -> dict[str, Any]:
        return {"axis_mask": self.axis_mask, "mode": self.mode}

    def restore(self, data: dict[str, Any] | None) -> None:
        data = data or {}
        mask = data.get("axis_mask", self._factory_mask())
        mode = data.get("mode", FACTORY_MODE)
        self.axis_mask = mask if isinstance(mask, int) else self._factory_mask()
        self.mode = mode if mode in (1, 2, 3) else FACTORY_MODE

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self.slots.clear()
        self.pointer = 0
        self._stop()

    @on(Halt)
    def halt(self, event: Halt) -> None:
        self._stop()

    @property
    def playing(self) -> bool:
        return self._play is not None

    def _stop(self) -> None:
        if self._play is not None:
            self._play.cancel()
            self._play = None

    # ---- commands -----------------------------------------------------------------------------

    def load(self, call: Call) -> Reply:
        """LOAD: store a position in the next slot; `L?` reads the slot at the pointer (MS-RB-2/3)."""
        controller = self.controller
        slot: dict[str, float] = {}
        queries: list[str] = []
        for axis, item in axis_items(call, controller.axes):
            if item.kind is Kind.QUERY:
                queries.append(axis.letter)
            elif item.kind is Kind.PLUS:
                slot[axis.hw_letter] = axis.units(call.now)
            else:
                slot[axis.hw_letter] = number(item)
        if slot:
            if len(self.slots) >= self.size:
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            self.slots.append(slot)
        if not queries:
            return controller.ack()
        current = self.slots[self.pointer] if self.slots else {}
        pairs = []
        for axis in controller.axes:
            if axis.letter in queries:
                units = current.get(axis.hw_letter, axis.units(call.now) if current else 0.0)
                pairs.append((axis.letter, controller.where(units)))
        return controller.render(call.key).items(pairs)

    def rbmode(self, call: Call) -> Reply:
        """RBMODE: X clear/count, Y axes, Z pointer, F mode; bare RM is a trigger (MS-RB-4/5)."""
        controller = self.controller
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            controller.in0_function(controller.card.ttl_in or 1, call.now)
            return controller.ack()

        # `RM X=1` starts ARRAY's commanded stepping; without a module serving it `:N-4` (MS-ARRAY-6)
        starts = one_of(0, *(v for m in controller.modules_of(RmXServer) for v in m.rm_x_values))

        def pointer(value: float) -> float:
            if value != int(value) or not 0 <= value <= max(len(self.slots) - 1, 0):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def mask(value: float) -> float:
            if value != int(value) or not 1 <= value <= (1 << len(controller.axes)) - 1:
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return value

        def mode(value: float) -> float:
            if value != int(value) or not 0 <= value <= 255 or int(value) & 0x7F not in (1, 2, 3):
                raise CommandError(ErrorCode.OUT_OF_RANGE)
            return float(int(value) & 0x7F)

        params = {
            "X": Param(lambda: len(self.slots), lambda v: self._rm_x(int(v), call.now), starts),
            "Y": Param(lambda: self.axis_mask, lambda v: setattr(self, "axis_mask", int(v)), mask),
            "Z": Param(lambda: self.pointer, self._set_pointer, pointer),
            "F": Param(lambda: self.mode | (AUTOPLAY_FLAG if self.playing else 0), self._set_mode, mode),
        }
        return run_settings(call, params, "XYZF", controller.render(call.key), controller.ack())

    def _set_mode(self, value: float) -> None:
        self.mode = int(value)

    def _set_pointer(self, value: float) -> None:
        # checked against the slots before `X=0` of the same command cleared them: stay inside
        self.pointer = min(int(value), max(len(self.slots) - 1, 0))

    def _rm_x(self, value: int, now: float) -> None:
        if value == 0:
            self.clear(now)
        self.controller.emit(RmX(now, value))

    def playback_mode(self) -> int:
        return self.mode

    # ---- triggers and buttons -----------------------------------------------------------------

    def in0_trigger(self, mode: int, now: float) -> None:
        self.trigger(now)

    def button(self, name: str, press: str, now: float) -> bool:
        """`@` normal: next; joystick held 1–3 s: store; home held > 1 s: clear (MS-RB-6)."""
        if (name, press) == ("at", NORMAL):
            self.trigger(now)
        elif (name, press) == ("joystick", LONG):
            self.store_here(now)
        elif name == "home" and press in (LONG, EXTRA):
            self.clear(now)
        else:
            return False
        return True

    def clear(self, now: float) -> None:
        self.slots.clear()
        self.pointer = 0
        self._stop()

    def store_here(self, now: float) -> None:
        if len(self.slots) < self.size:
            self.slots.append({a.hw_letter: a.units(now) for a in self.controller.axes})

    def trigger(self, now: float) -> None:
        if not self.slots:
            return
        if self.playing:
            self._stop()
        elif self.mode == 1:
            self._visit(now)
        else:
            self._autoplay(now)

    def _visit(self, now: float) -> None:
        slot = self.slots[self.pointer]
        self.pointer = (self.pointer + 1) % len(self.slots)
        goals = [
            (a, a.counts_of_units(slot[a.hw_letter]))
            for a in self.controller.axes
            if self.axis_mask & (1 << a.index) and a.hw_letter in slot
        ]
        self.controller.start_moves(goals, now)

    def _autoplay(self, now: float) -> None:
        self._play = None
        self._visit(now)
        if self.pointer == 0 and self.mode == 2:
            return
        # `RT Z=0` is allowed: the next step still waits one servo period rather than loop forever
        interval = max(self.controller.card.rt_delay_ms / 1000, self.controller.servo_s)
        self._play = self.controller.at(now + interval, self._autoplay)
