"""SOL_LK and U_SERVO_LK: plate-lock inserts driven from TTL OUT0 (§9.17, MS-SECURE-1).

SOL_LK (solenoid): `SECURE X=0` locks, `X=1` unlocks; `Y` pull-in power and `Z` hold power (0–99 %),
`F` auto-lock time in minutes (0–255, 0: never), `T` pull-in time in ms (0–65000). After an unlock
the auto-lock timer locks again F minutes later. Queries reply value first (`X=1 :A`).

U_SERVO_LK (micro servo): `SECURE X=p` sets the lever position 0.0–1.0 (0.0 is locked [choice]);
it has no other letter and no query (`:N-2`).

Either drives OUT0 in mode 9 (`TTL Y=9`, MS-91): the solenoid is energised (level 1) while unlocked,
at the pull-in power for `T` ms and at the hold power after [choice]; the servo gets its position
as the PWM duty [choice]. The commanded state is kept whatever the OUT0 mode. The settings are
volatile (§9.17 does not mark them `SS Z`); the insert is locked at power-up. LCD segment
`LCK`/`OPN`; observable `secure {locked, position}`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.calls import (
    Call,
    CommandError,
    Param,
    Reply,
    one_of,
    run_settings,
    within,
)
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, LcdSegment, TtlOut
from emulator.devices.ms2000.modules.events import Reset, on
from protocols.ms2000 import ErrorCode, Fmt, Kind

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

LOCK_OUT_MODE = 9
#: SOL_LK factory values: locked, F 5 minutes [doc]; powers and pull-in time [choice]
SOLENOID_FACTORY = {"X": 0, "Y": 99, "Z": 30, "F": 5, "T": 250}
UNLOCKED = 1


class _Secure(Module, TtlOut, LcdSegment, ControlChannel):
    """What both inserts share: the OUT0 mode, the LCD segment and the observable. `position` is
    the lever (servo) or 0/1 (solenoid): 0.0 is locked."""

    out0_modes = frozenset({LOCK_OUT_MODE})
    observable = "secure"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.position = 0.0

    @property
    def locked(self) -> bool:
        return self.position == 0.0

    def lcd_segment(self, now: float) -> str | None:
        return "LCK" if self.locked else "OPN"

    def observe(self, now: float) -> Any:
        return {"locked": self.locked, "position": self.position}


@register
class SolenoidLock(_Secure):
    name = "SOL_LK"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.values = dict(SOLENOID_FACTORY)
        self.pulling_in = False
        self._timers: list[Timer] = []

    def handlers(self) -> dict[str, Handler]:
        return {"SECURE": self.secure}

    def secure(self, call: Call) -> Reply:
        """SECURE X=0 lock / 1 unlock, Y pull-in %, Z hold %, F auto-lock min, T pull-in ms."""
        values = self.values
        now = call.now

        def setter(letter: str) -> Any:
            def store(value: float) -> None:
                values[letter] = int(value)

            return store

        params = {
            "X": Param(lambda: values["X"], lambda v: self._set_lock(int(v), now), one_of(0, 1)),
            "Y": Param(lambda: values["Y"], setter("Y"), within(0, 99, integer=True)),
            "Z": Param(lambda: values["Z"], setter("Z"), within(0, 99, integer=True)),
            "F": Param(lambda: values["F"], setter("F"), within(0, 255, integer=True)),
            "T": Param(lambda: values["T"], setter("T"), within(0, 65000, integer=True)),
        }
        return run_settings(call, params, "XYZFT", self.controller.render(call.key), self.controller.ack())

    def _set_lock(self, x: int, now: float) -> None:
        self._cancel_timers()
        self.values["X"] = x
        self.position = float(x == UNLOCKED)
        self.pulling_in = x == UNLOCKED and self.values["T"] > 0
        if self.pulling_in:
            self._timers.append(self.controller.at(now + self.values["T"] / 1000, self._hold))
        if x == UNLOCKED and self.values["F"]:
            self._timers.append(self.controller.at(now + self.values["F"] * 60, self._auto_lock))
        self.controller.refresh_out0(now)

    def _hold(self, t: float) -> None:
        self.pulling_in = False
        self.controller.refresh_out0(t)

    def _auto_lock(self, t: float) -> None:
        self._set_lock(0, t)

    def _cancel_timers(self) -> None:
        for timer in self._timers:
            timer.cancel()
        self._timers.clear()

    def out0_level(self) -> int | None:
        return 0 if self.locked else 1

    def out0_pwm(self) -> float | None:
        if self.locked:
            return 0.0
        return float(self.values["Y"] if self.pulling_in else self.values["Z"])

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self._cancel_timers()
        self.values = dict(SOLENOID_FACTORY)
        self.position = 0.0
        self.pulling_in = False


@register
class ServoLock(_Secure):
    name = "U_SERVO_LK"

    def handlers(self) -> dict[str, Handler]:
        return {"SECURE": self.secure}

    def secure(self, call: Call) -> Reply:
        """SECURE X=p, the lever position 0.0–1.0; no other letter, no query (MS-SECURE-1)."""
        if any(i.kind is Kind.QUERY for i in call.items):
            raise CommandError(ErrorCode.BAD_AXIS)
        now = call.now

        def store(value: float) -> None:
            self.position = value
            self.controller.refresh_out0(now)

        params = {"X": Param(lambda: self.position, store, within(0.0, 1.0), Fmt.F6)}
        return run_settings(call, params, "X", self.controller.render(call.key), self.controller.ack())

    def out0_level(self) -> int | None:
        return 1 if self.position > 0 else 0

    def out0_pwm(self) -> float | None:
        return self.position * 100

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self.position = 0.0
