"""The control channel of the controller (Appendix B): inputs, observables and the LCD. Modules add
theirs through the controller's ModuleSet."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from emulator.device import ControlError, HostLine
from emulator.devices.ms2000.activity import LOWER, UPPER, Activity
from emulator.devices.ms2000.axis import Axis
from emulator.devices.ms2000.buttons import NAMES as BUTTON_NAMES
from emulator.devices.ms2000.status import status_byte
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.buttons import Buttons
    from emulator.devices.ms2000.interpreter import Interpreter
    from emulator.devices.ms2000.modules.moduleset import ModuleSet
    from emulator.devices.ms2000.power import Power
    from emulator.devices.ms2000.schema import Ms2000Config
    from emulator.devices.ms2000.sections import Ms2000Knobs
    from emulator.devices.ms2000.ttl import Ttl

#: LCD lines are 20 characters (MS-116)
LCD_WIDTH = 20


class ControlsOwner(Protocol):
    """All the control channel reads and drives of its controller."""

    @property
    def name(self) -> str: ...

    @property
    def cfg(self) -> Ms2000Config: ...

    @property
    def knobs(self) -> Ms2000Knobs: ...

    @property
    def axes(self) -> Sequence[Axis]: ...

    @property
    def modules(self) -> ModuleSet:
        """Their observables, inputs and LCD segments."""

    @property
    def ttl(self) -> Ttl: ...

    @property
    def buttons(self) -> Buttons: ...

    @property
    def interpreter(self) -> Interpreter: ...

    @property
    def power(self) -> Power:
        """`power_cycle`."""

    @property
    def dip(self) -> dict[str, str]:
        """Set by the `dip` input, read at the next power-up (MS-2)."""

    @property
    def az_fail(self) -> set[str]:
        """Axes whose `AZ` fails (the `az_fail` input)."""

    @property
    def error_log(self) -> Sequence[int]: ...

    @property
    def baud(self) -> int: ...

    @property
    def booted_at(self) -> float: ...

    @property
    def ensync_level(self) -> int: ...

    @property
    def lcd_text(self) -> str | None: ...

    @property
    def lcd_inches(self) -> bool: ...

    def axis_named(self, letter: str) -> Axis | None: ...

    def axis_finished(self, axis: Axis, t: float) -> None: ...

    def busy(self, t: float) -> bool: ...

    def where(self, units: float) -> str: ...

    def log_error(self, code: int) -> None: ...

    def set_joystick(self, x: float, y: float, t: float) -> None: ...

    def turn_wheel(self, counts: float, t: float) -> None: ...

    def garbles(self) -> bool: ...

    def host_line(self) -> HostLine | None: ...

    def declare_host(self, settings: dict[str, Any]) -> None: ...


class Controls:
    """The `in`/`get` vocabulary of the controller's control channel."""

    def __init__(self, controller: ControlsOwner) -> None:
        self.controller = controller

    def lcd(self, t: float) -> list[str]:
        """Two 20-character lines [choice]: positions, then module status (DIP 2 UP) or text."""
        controller = self.controller
        scale = 25.4 if controller.lcd_inches else 1.0
        top = " ".join(f"{a.letter}{a.user_mm(t) / scale:.3f}" for a in controller.axes)
        if controller.dip["sw2"] == "down":
            bottom = controller.lcd_text if controller.lcd_text is not None else controller.cfg.version
        else:
            up = int(t - controller.booted_at)
            clock = f"{up // 3600 % 100:02d}:{up // 60 % 60:02d}:{up % 60:02d}"
            bottom = " ".join([*controller.modules.lcd_segments(t), clock])
        return [top[:LCD_WIDTH].rstrip(), bottom[:LCD_WIDTH].rstrip()]

    def _axes_state(self, t: float) -> dict[str, Any]:
        controller = self.controller
        state = {}
        for axis in controller.axes:
            axis.sample(t)
            state[axis.letter] = {
                "machine_counts": round_half_away(axis.physical(t)),
                "target_counts": round_half_away(axis.physical_target(t)),
                "user_mm": axis.user_mm(t),
                "target_user_mm": axis.user_mm_of(axis.target),
                "min_user_mm": axis.ext_min,
                "max_user_mm": axis.ext_max,
                "status_byte": status_byte(axis, t, controller.knobs.status_bit5_up_is_one),
                "position": controller.where(axis.units(t)),
                "activity": axis.activity.value,
                "enabled": axis.enabled,
            }
        return state

    def observables(self) -> dict[str, Callable[[float], Any]]:
        controller = self.controller
        table: dict[str, Callable[[float], Any]] = {
            "baud": lambda t: controller.baud,
            "axes": self._axes_state,
            "busy": controller.busy,
            "ttl_out0": lambda t: controller.ttl.level,
            "ttl_out0_pwm": lambda t: controller.ttl.pwm(),
            "ttl_in0": lambda t: controller.ttl.in0,
            "ensync_out": lambda t: controller.ensync_level,
            "lcd": self.lcd,
            "error_log": lambda t: list(reversed(controller.error_log)),
            "dip": lambda t: dict(controller.dip),
            "mode": lambda t: controller.interpreter.mode,
            "host_line": lambda t: None if (h := controller.host_line()) is None else h.describe(),
        }
        table.update(controller.modules.observables())
        return table

    def observe(self, name: str, t: float) -> Any:
        table = self.observables()
        if name not in table:
            raise ControlError(
                f"{self.controller.name}: no observable {name!r}; known: {', '.join(sorted(table))}"
            )
        return table[name](t)

    def snapshot(self, t: float) -> dict[str, Any]:
        return {name: get(t) for name, get in self.observables().items()}

    def control_input(self, name: str, params: dict[str, Any], t: float) -> Any:
        handler = self._inputs().get(name)
        if handler is not None:
            return handler(params, t)
        if name not in self.controller.modules.inputs():
            known = self.names()["inputs"]
            raise ControlError(f"{self.controller.name}: no input {name!r}; known: {', '.join(known)}")
        return self.controller.modules.control_input(name, params, t)

    def names(self) -> dict[str, list[str]]:
        inputs = {*self._inputs(), *self.controller.modules.inputs()}
        return {"inputs": sorted(inputs), "observables": sorted(self.observables())}

    def _inputs(self) -> dict[str, Callable[[dict[str, Any], float], Any]]:
        return {
            "host_line": self._in_host_line,
            "dip": self._in_dip,
            "power_cycle": self._in_power_cycle,
            "joystick": self._in_joystick,
            "wheel": self._in_wheel,
            "button": self._in_button,
            "ttl_in0": self._in_ttl_in0,
            "ttl_in1": self._in_ttl_in1,
            "limit": self._in_limit,
            "disturb": self._in_disturb,
            "stall": self._in_stall,
            "log_error": self._in_log_error,
            "az_fail": self._in_az_fail,
        }

    def _in_power_cycle(self, params: dict[str, Any], t: float) -> Any:
        self.controller.power.power_cycle(t)
        return True

    def _axis_param(self, params: dict[str, Any]) -> Axis:
        letter = params.get("axis")
        axis = self.controller.axis_named(letter.upper()) if isinstance(letter, str) else None
        if axis is None:
            known = ", ".join(a.letter for a in self.controller.axes)
            raise ControlError(f"axis must be one of {known}, got {letter!r}")
        return axis

    def _in_host_line(self, params: dict[str, Any], t: float) -> Any:
        allowed = {
            "baud": lambda v: isinstance(v, int) and not isinstance(v, bool) and v > 0,
            "data_bits": lambda v: v in (5, 6, 7, 8),
            "parity": lambda v: v in ("none", "even", "odd", "mark", "space"),
            "stop_bits": lambda v: v in (1, 1.5, 2),
        }
        for key, value in params.items():
            if key not in allowed:
                raise ControlError(f"host_line: unknown parameter {key!r}; use {', '.join(allowed)}")
            if not allowed[key](value):
                raise ControlError(f"host_line: bad {key} {value!r}")
        self.controller.declare_host(params)
        host = self.controller.host_line()
        return {"host": None if host is None else host.describe(), "garbled": self.controller.garbles()}

    def _in_dip(self, params: dict[str, Any], t: float) -> Any:
        for key, value in params.items():
            if key not in self.controller.dip or value not in ("up", "down"):
                raise ControlError(f"dip: expected sw1…sw8 set to 'up' or 'down', got {key}={value!r}")
        self.controller.dip.update(params)
        return dict(self.controller.dip)

    def _in_joystick(self, params: dict[str, Any], t: float) -> Any:
        x = _number(params, "x", 0.0, -1.0, 1.0, "joystick")
        y = _number(params, "y", 0.0, -1.0, 1.0, "joystick")
        self.controller.set_joystick(x, y, t)
        return True

    def _in_wheel(self, params: dict[str, Any], t: float) -> Any:
        self.controller.turn_wheel(_number(params, "counts", None, -1e6, 1e6, "wheel"), t)
        return True

    def _in_button(self, params: dict[str, Any], t: float) -> Any:
        name = params.get("name")
        if name not in BUTTON_NAMES:
            raise ControlError(f"button: name must be one of {', '.join(BUTTON_NAMES)}, got {name!r}")
        ms = _number(params, "ms", 100.0, 0.0, 3_600_000.0, "button")
        self.controller.buttons.press(name, ms, t)
        return True

    def _in_ttl_in0(self, params: dict[str, Any], t: float) -> Any:
        if "pulse_ms" in params:
            self.controller.ttl.pulse_in0(_number(params, "pulse_ms", None, 0.0, 3_600_000.0, "ttl_in0"), t)
        elif "level" in params:
            self.controller.ttl.set_in0(int(_number(params, "level", None, 0, 1, "ttl_in0")), t)
        else:
            raise ControlError("ttl_in0 needs pulse_ms (a pulse) or level (0 or 1)")
        return True

    def _in_ttl_in1(self, params: dict[str, Any], t: float) -> Any:
        self.controller.ttl.set_in1(int(_number(params, "level", None, 0, 1, "ttl_in1")), t)
        return True

    def _in_limit(self, params: dict[str, Any], t: float) -> Any:
        axis = self._axis_param(params)
        end = params.get("end")
        if end not in (UPPER, LOWER):
            raise ControlError(f"limit: end must be 'upper' or 'lower', got {end!r}")
        closed = params.get("closed", True)
        if not isinstance(closed, bool):
            raise ControlError("limit: closed must be true or false")
        axis.switch[end] = closed
        if closed and axis.traj.moving(t) and (axis.traj.vel(t) > 0) == (end == UPPER):
            moving = axis.activity in (Activity.MOVE, Activity.HOME, Activity.SPIN, Activity.VELOCITY)
            axis.stop(t)
            if moving:
                self.controller.log_error(34 if end == UPPER else 35)
                self.controller.axis_finished(axis, t)
        return True

    def _in_disturb(self, params: dict[str, Any], t: float) -> Any:
        axis = self._axis_param(params)
        um = _number(params, "um", None, -1e6, 1e6, "disturb")
        hold = params.get("hold", False)
        if not isinstance(hold, bool):
            raise ControlError("disturb: hold must be true or false")
        axis.disturb(t, um, hold)
        return True

    def _in_stall(self, params: dict[str, Any], t: float) -> Any:
        axis = self._axis_param(params)
        group = axis.group
        stalled = axis.stall(t)
        if stalled and group is not None:
            self.controller.axis_finished(axis, t)
        return stalled

    def _in_log_error(self, params: dict[str, Any], t: float) -> Any:
        self.controller.log_error(int(_number(params, "code", None, 0, 65535, "log_error")))
        return list(reversed(self.controller.error_log))

    def _in_az_fail(self, params: dict[str, Any], t: float) -> Any:
        self.controller.az_fail.add(self._axis_param(params).hw_letter)
        return True


def _number(
    params: dict[str, Any], key: str, default: float | None, low: float, high: float, what: str
) -> float:
    value = params.get(key, default)
    if value is None:
        raise ControlError(f"{what}: {key} is required")
    if isinstance(value, bool) or not isinstance(value, int | float) or not low <= value <= high:
        raise ControlError(f"{what}: {key} must be a number in {low:g}…{high:g}, got {value!r}")
    return float(value)
