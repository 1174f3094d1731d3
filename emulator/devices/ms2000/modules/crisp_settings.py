"""CRISP's settings (MS-CRISP-4, MS-CRISP-5): `LR` (LOCKRG), `UL` (UNLOCK), `AL` (AFLIM), the lock
offset `LK Z`, the AGC value `LK M` and the integral gain `EXTRA Z`, all saved with `SS Z`.

Ranges the reference leaves open are [choice]: cal_gain 0–65535, lock range 0–10 mm, cal range
above 0 up to 1 mm, loop gain 0–100, update period 1–1000 ms, knob sensitivity 0–100, lock offset
±2047 counts (the error's own range), integral gain 0–100.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from typing import Any

from emulator.devices.ms2000.calls import CommandError, Param, within
from emulator.profiles.schema import finite_number
from protocols.ms2000 import ErrorCode, Fmt

#: objective NA 0.65 gives the documented cal range 0.005 mm and in-focus window 0.0001 mm
CAL_RANGE_NA_MM = 0.00325
IN_FOCUS_NA_MM = 0.000065
OFFSET_LIMIT = 2047


@dataclass
class CrispSettings:
    cal_gain: int = 100  # LR X: what calibration measures with the default optics
    na: float = 0.65  # LR Y
    lock_range_mm: float = 1.0  # LR Z
    cal_range_mm: float = 0.005  # LR F
    loop_gain: float = 4.0  # LR T
    led_percent: float = 99.0  # UL X
    update_ms: float = 10.0  # UL Y
    knob_speed: float = 2.0  # UL Z
    focus_index: int = 2  # UL F: hardware index (Z of an XYZ build)
    agc_pot: int = 1  # AL X
    led_pot: int = 1  # AL Y [choice: no documented default]
    in_focus_mm: float = 0.0001  # AL Z
    offset: int = 0  # LK Z
    agc: int = 0  # LK M [choice: log-amp calibration sets it]
    integral_gain: float = 1.0  # EXTRA Z

    def set_na(self, na: float) -> None:
        """`LR Y` also sets `LR F` and `AL Z` (MS-CRISP-5 [choice formulas])."""
        self.na = na
        self.cal_range_mm = CAL_RANGE_NA_MM / na
        self.in_focus_mm = IN_FOCUS_NA_MM / na

    def save(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def restored(cls, data: dict[str, Any] | None, axes: int) -> CrispSettings:
        """Saved values that are numbers of the right kind, factory values for the rest."""
        settings = cls(focus_index=min(2, axes - 1))
        for f in fields(cls):
            value = (data or {}).get(f.name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not finite_number(value):
                continue
            if f.type == "int" and value != int(value):
                continue
            setattr(settings, f.name, int(value) if f.type == "int" else float(value))
        if not 0 <= settings.focus_index < axes:
            settings.focus_index = min(2, axes - 1)
        return settings


def above_zero(high: float) -> Callable[[float], float]:
    def check(value: float) -> float:
        if not 0 < value <= high:
            raise CommandError(ErrorCode.OUT_OF_RANGE)
        return value

    return check


def _param(s: CrispSettings, attr: str, check: Callable[[float], float], integer: bool = False) -> Param:
    def store(value: float) -> None:
        setattr(s, attr, int(value) if integer else value)

    return Param(lambda: getattr(s, attr), store, check, Fmt.F6)


def lockrg_params(s: CrispSettings) -> dict[str, Param]:
    """LR X=cal_gain Y=NA Z=lock_range F=cal_range T=loop_gain (MS-CRISP-5)."""
    return {
        "X": _param(s, "cal_gain", within(0, 65535, integer=True), integer=True),
        "Y": Param(lambda: s.na, s.set_na, within(0.1, 1.65), Fmt.F6),
        "Z": _param(s, "lock_range_mm", within(0, 10)),
        "F": _param(s, "cal_range_mm", above_zero(1)),
        "T": _param(s, "loop_gain", within(0, 100)),
    }


def unlock_params(s: CrispSettings, axes: int) -> dict[str, Param]:
    """UL X=led_percent Y=update_ms Z=knob_speed F=focus_index (MS-CRISP-5)."""
    return {
        "X": _param(s, "led_percent", within(0, 100)),
        "Y": _param(s, "update_ms", within(1, 1000)),
        "Z": _param(s, "knob_speed", within(0, 100)),
        "F": _param(s, "focus_index", within(0, axes - 1, integer=True), integer=True),
    }


def aflim_params(s: CrispSettings) -> dict[str, Param]:
    """AL X=agc Y=led_pot Z=in_focus_mm (MS-CRISP-5)."""
    return {
        "X": _param(s, "agc_pot", within(0, 255, integer=True), integer=True),
        "Y": _param(s, "led_pot", within(0, 255, integer=True), integer=True),
        "Z": _param(s, "in_focus_mm", above_zero(0.1)),
    }
