"""The control channel of the controller (Appendix B): inputs, observables and the LCD, mixed into
MS2000."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from emulator.device import ControlError
from emulator.devices.ms2000.axis import LOWER, UPPER, Activity, Axis
from emulator.devices.ms2000.buttons import NAMES as BUTTON_NAMES
from emulator.motion import round_half_away

#: LCD lines are 20 characters (MS-116)
LCD_WIDTH = 20


class ControlSurfaceMixin:
    """Part of MS2000: the `in`/`get` vocabulary of its control channel."""

    def lcd(self, t: float) -> list[str]:
        """Two 20-character lines [choice]: positions, then module status (DIP 2 UP) or text."""
        scale = 25.4 if self.lcd_inches else 1.0
        top = " ".join(f"{a.letter}{a.user_mm(t) / scale:.3f}" for a in self.axes)
        if self.dip["sw2"] == "down":
            bottom = self.lcd_text if self.lcd_text is not None else self.cfg.version
        else:
            segments = [s for m in self.modules.values() if (s := m.lcd_segment(t))]
            up = int(t - self._booted_at)
            clock = f"{up // 3600 % 100:02d}:{up // 60 % 60:02d}:{up % 60:02d}"
            bottom = " ".join([*segments, clock])
        return [top[:LCD_WIDTH].rstrip(), bottom[:LCD_WIDTH].rstrip()]

    def _axes_state(self, t: float) -> dict[str, Any]:
        state = {}
        for axis in self.axes:
            axis.sample(t)
            state[axis.letter] = {
                "machine_counts": round_half_away(axis.pos(t)),
                "target_counts": axis.target,
                "user_mm": axis.user_mm(t),
                "target_user_mm": axis.user_mm_of(axis.target),
                "min_user_mm": axis.ext_min,
                "max_user_mm": axis.ext_max,
                "status_byte": axis.status_byte(t, self.knobs.status_bit5_up_is_one),
                "position": self.where(axis.units(t)),
                "activity": axis.activity.value,
                "enabled": axis.enabled,
            }
        return state

    def _observables(self) -> dict[str, Callable[[float], Any]]:
        table: dict[str, Callable[[float], Any]] = {
            "baud": lambda t: self.baud,
            "axes": self._axes_state,
            "busy": self.busy,
            "ttl_out0": lambda t: self.ttl.level,
            "ttl_out0_pwm": lambda t: self.ttl.pwm(),
            "ttl_in0": lambda t: self.ttl.in0,
            "ensync_out": lambda t: self.ensync_level,
            "lcd": self.lcd,
            "error_log": lambda t: list(reversed(self.error_log)),
            "dip": lambda t: dict(self.dip),
            "mode": lambda t: "silent" if self._silenced else "low" if self.low_level else "high",
            "host_line": lambda t: None if (h := self.host_line()) is None else h.describe(),
        }
        for module in self.modules.values():
            if module.observable:
                table[module.observable] = module.observe
        return table

    def observe(self, name: str, now: float) -> Any:
        self._touch(now)
        table = self._observables()
        if name not in table:
            raise ControlError(f"{self.name}: no observable {name!r}; known: {', '.join(sorted(table))}")
        return table[name](self._now)

    def snapshot(self) -> dict[str, Any]:
        return {name: get(self._now) for name, get in self._observables().items()}

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        self._touch(now)
        handler = self._inputs().get(name)
        if handler is not None:
            result = handler(params, now)
        else:
            module = next((m for m in self.modules.values() if name in m.inputs), None)
            if module is None:
                known = self.control_names()["inputs"]
                raise ControlError(f"{self.name}: no input {name!r}; known: {', '.join(known)}")
            result = module.control_input(name, params, now)
        self.scheduler.run_due(now)
        return result

    def control_names(self) -> dict[str, list[str]]:
        inputs = {*self._inputs(), *(i for m in self.modules.values() for i in m.inputs)}
        return {"inputs": sorted(inputs), "observables": sorted(self._observables())}

    def _inputs(self) -> dict[str, Callable[[dict[str, Any], float], Any]]:
        return {
            "host_line": self._in_host_line,
            "dip": self._in_dip,
            "power_cycle": lambda p, t: self.power_cycle(t) or True,
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

    def _axis_param(self, params: dict[str, Any]) -> Axis:
        letter = params.get("axis")
        axis = self.axis_named(letter.upper()) if isinstance(letter, str) else None
        if axis is None:
            known = ", ".join(a.letter for a in self.axes)
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
        self._host_declared.update(params)
        host = self.host_line()
        return {"host": None if host is None else host.describe(), "garbled": self._garbles()}

    def _in_dip(self, params: dict[str, Any], t: float) -> Any:
        for key, value in params.items():
            if key not in self.dip or value not in ("up", "down"):
                raise ControlError(f"dip: expected sw1…sw8 set to 'up' or 'down', got {key}={value!r}")
        self.dip.update(params)
        return dict(self.dip)

    def _in_joystick(self, params: dict[str, Any], t: float) -> Any:
        x = _number(params, "x", 0.0, -1.0, 1.0, "joystick")
        y = _number(params, "y", 0.0, -1.0, 1.0, "joystick")
        self._set_joystick(x, y, t)
        return True

    def _in_wheel(self, params: dict[str, Any], t: float) -> Any:
        self._turn_wheel(_number(params, "counts", None, -1e6, 1e6, "wheel"), t)
        return True

    def _in_button(self, params: dict[str, Any], t: float) -> Any:
        name = params.get("name")
        if name not in BUTTON_NAMES:
            raise ControlError(f"button: name must be one of {', '.join(BUTTON_NAMES)}, got {name!r}")
        ms = _number(params, "ms", 100.0, 0.0, 3_600_000.0, "button")
        self.buttons.press(name, ms, t)
        return True

    def _in_ttl_in0(self, params: dict[str, Any], t: float) -> Any:
        if "pulse_ms" in params:
            self.ttl.pulse_in0(_number(params, "pulse_ms", None, 0.0, 3_600_000.0, "ttl_in0"), t)
        elif "level" in params:
            self.ttl.set_in0(int(_number(params, "level", None, 0, 1, "ttl_in0")), t)
        else:
            raise ControlError("ttl_in0 needs pulse_ms (a pulse) or level (0 or 1)")
        return True

    def _in_ttl_in1(self, params: dict[str, Any], t: float) -> Any:
        self.ttl.set_in1(int(_number(params, "level", None, 0, 1, "ttl_in1")), t)
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
                self.log_error(34 if end == UPPER else 35)
                self.axis_finished(axis, t)
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
            self.axis_finished(axis, t)
        return stalled

    def _in_log_error(self, params: dict[str, Any], t: float) -> Any:
        self.log_error(int(_number(params, "code", None, 0, 65535, "log_error")))
        return list(reversed(self.error_log))

    def _in_az_fail(self, params: dict[str, Any], t: float) -> Any:
        self.az_fail.add(self._axis_param(params).hw_letter)
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
