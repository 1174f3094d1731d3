"""What every command group shares: the controller as the commands see it (`CommandsOwner`), reply
rendering, item collection."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from functools import partial
from typing import TYPE_CHECKING, Any, Protocol

from emulator.devices.ms2000.axis import Axis
from emulator.devices.ms2000.calls import (
    Call,
    Param,
    Reply,
    axis_items,
    run_settings,
)
from protocols.ms2000 import Fmt, Item, Shape

if TYPE_CHECKING:
    from emulator.devices.ms2000.activity import Activity
    from emulator.devices.ms2000.buttons import Buttons
    from emulator.devices.ms2000.calls import Rendered
    from emulator.devices.ms2000.interpreter import Interpreter
    from emulator.devices.ms2000.lowlevel import LowLevel
    from emulator.devices.ms2000.modules.moduleset import ModuleSet
    from emulator.devices.ms2000.power import Power
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.schema import Ms2000Config
    from emulator.devices.ms2000.sections import Ms2000Knobs
    from emulator.devices.ms2000.settings import CardAuto, CardSettings
    from emulator.devices.ms2000.ttl import Ttl


class CommandsOwner(Protocol):
    """All the base command handlers use of their controller: its parts, the state commands set (the
    attributes) and the motion and reply services."""

    last_relative: list[tuple[str, float | None]]
    ensync_level: int
    user_counter: int
    log_since: float
    moves: int
    az_fail: set[str]
    lcd_text: str | None
    lcd_inches: bool

    @property
    def cfg(self) -> Ms2000Config: ...

    @property
    def knobs(self) -> Ms2000Knobs: ...

    @property
    def card(self) -> CardSettings: ...

    @property
    def card_auto(self) -> CardAuto: ...

    @property
    def axes(self) -> Sequence[Axis]: ...

    @property
    def modules(self) -> ModuleSet: ...

    @property
    def power(self) -> Power: ...

    @property
    def ttl(self) -> Ttl: ...

    @property
    def buttons(self) -> Buttons: ...

    @property
    def low(self) -> LowLevel: ...

    @property
    def interpreter(self) -> Interpreter: ...

    @property
    def joystick(self) -> tuple[float, float]:
        """The deflection `RA X`/`RA Y` read (MS-117)."""

    @property
    def trajectory_log(self) -> deque[str]: ...

    @property
    def error_log(self) -> deque[int]: ...

    def ack(self) -> Reply: ...

    def error(self, code: int) -> Reply: ...

    def render(self, key: str, shape: Shape | None = None) -> Rendered: ...

    def where(self, units: float) -> str: ...

    def at(self, due: float, action: Callable[[float], None]) -> Timer: ...

    def axis_named(self, letter: str) -> Axis | None: ...

    def left_char(self, axis: Axis, t: float) -> str: ...

    def manual_inverted(self, axis: Axis) -> bool: ...

    def relative_goal(self, axis: Axis, delta_mm: float, t: float) -> float: ...

    def start_moves(self, goals: list[tuple[Axis, float]], t: float, activity: Activity = ...) -> None: ...

    def leave_group(self, axis: Axis) -> None: ...

    def busy(self, t: float) -> bool: ...

    def halt_all(self, t: float) -> bool: ...

    def zero_all(self, t: float) -> None: ...

    def enable_motor(self, axis: Axis, t: float) -> None: ...

    def disable_motor(self, axis: Axis, t: float) -> None: ...

    def set_manual_enabled(self, axis: Axis, enabled: bool, t: float) -> None: ...

    def positions_changed(self) -> None: ...

    def out0_modes(self) -> set[int]: ...

    def in0_available(self, mode: int) -> bool: ...


class CommandSet:
    """Helpers of the command handlers; the handlers themselves live in the sibling modules."""

    def __init__(self, controller: CommandsOwner) -> None:
        self.controller = controller

    @property
    def _order(self) -> str:
        return "".join(a.letter for a in self.controller.axes)

    def _settings(self, call: Call, params: dict[str, Param], order: str | None = None) -> Reply:
        controller = self.controller
        return run_settings(call, params, order or self._order, controller.render(call.key), controller.ack())

    def _per_axis(
        self,
        get: Callable[[Axis], Any],
        set_: Callable[[Axis, float], None] | None = None,
        check: Callable[[Axis, float], float] | None = None,
        fmt: Fmt = Fmt.F6,
        plus: Callable[[Axis], None] | None = None,
        minus: Callable[[Axis], None] | None = None,
    ) -> dict[str, Param]:
        params = {}
        for a in self.controller.axes:
            params[a.letter] = Param(
                get=partial(get, a),
                set=partial(set_, a) if set_ else None,
                check=partial(check, a) if check else (lambda v: v),
                fmt=fmt,
                plus=partial(plus, a) if plus else None,
                minus=partial(minus, a) if minus else None,
            )
        return params

    def _axis_items(self, call: Call, require: bool = True) -> list[tuple[Axis, Item]]:
        return axis_items(call, self.controller.axes, require)

    def _list(self, call: Call, values: list[str]) -> Reply:
        return self.controller.render(call.key, Shape.A_LIST).items(("", v) for v in values)
