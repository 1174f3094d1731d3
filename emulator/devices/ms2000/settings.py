"""The controller's settings, in the three groups that differ in how they persist (MS-111).

- `AxisSettings`, `CardSettings`: saved by `SS Z`, restored at reset and power-up (factory values
  from the profile when nothing is saved);
- `AxisAuto`, `CardAuto`: remembered automatically as soon as they change (soft limits, home, AA,
  CCA X, button assignments);
- everything else (positions aside, which are saved at power-off) is volatile.

Positions of limits and home are machine millimetres (fixed hardware locations, MS-49).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from emulator.profiles.schema import finite_number

T = TypeVar("T")


@dataclass
class AxisSettings:
    speed: float  # S, mm/s (MS-54)
    accel_ms: int  # AC (MS-55)
    wait_ms: int  # WT (MS-56)
    backlash: float  # B, mm (MS-57)
    overshoot_counts: int  # OS, whole encoder counts (MS-58)
    drift_error: float  # E, mm (MS-59)
    finish_error: float  # PC, mm (MS-60)
    maintain: int  # MA (MS-61)
    runaway: float  # RU, mm (MS-62)
    kp: int
    ki: int
    kd: int
    kv: int
    ka: int
    dac: float  # D, mm/s per DAC count (MS-71, MS-97)
    counts_per_mm: float  # C (MS-45)
    polarity: int  # EP (MS-97)
    unit_multiplier: float  # UM (MS-44)
    input_device: int  # J L=n (MS-73)
    manual_enabled: bool  # J L+/L- (MS-73)
    ll_id: int  # LL (MS-114)
    rename: int | None  # Z2B L=code, applied at the next reset (MS-115)


@dataclass
class AxisAuto:
    soft_lower: float  # SL, machine mm (MS-65)
    soft_upper: float  # SU, machine mm
    home: float  # HM, machine mm (MS-68)
    aa: int  # AA (MS-97)


@dataclass
class CardSettings:
    js_fast: float = 100.0  # JS X (MS-74)
    js_slow: float = 5.0  # JS Y
    js_wheel: float = 100.0  # JS Z
    knob_slow: float = 1.0  # JS F (MS-KNOB-1)
    knob_mult: int = 4  # JS T
    ttl_in: int = 0  # TTL X (MS-89, MS-90)
    ttl_out: int = 0  # TTL Y (MS-91)
    ttl_aux: int = 0  # TTL Z
    ttl_polarity: int = 1  # TTL F
    rt_report_ms: float = 200.0  # RT X (MS-93)
    rt_pulse_ms: float = 10.0  # RT Y
    rt_delay_ms: float = 100.0  # RT Z
    rt_averages: float = 1.0  # RT F
    vb_flags: int = 0  # VB X (MS-96)
    vb_decimals: int = 0  # VB Z (MS-47, MS-109)
    stop_bits: int = 1  # SB X (MS-3)
    button_enable: int = 31  # BE Z (MS-86)
    button_home_normal: int = 2  # BE R
    button_joystick_extra: int = 0  # BE T
    button_zero_normal: int = 1  # BE M
    user_string: str = ""  # BU Y (MS-103)
    inhibit_position_save: int = 0  # SP X (MS-113)
    cca_y: int = 0  # CCA Y (MS-97)
    cca_z: int = 0  # CCA Z


#: BCA letters and the press they assign (MS-86, our numbering; see docs/ms2000.md)
BCA_LETTERS = "XYZFTRM"


@dataclass
class CardAuto:
    cca_x: int = 0  # CCA X, saved immediately (MS-97)
    bca: dict[str, int] = field(default_factory=lambda: dict.fromkeys(BCA_LETTERS, 0))


def to_plain(value: Any) -> dict[str, Any]:
    return dataclasses.asdict(value)


#: values the model divides by, loops on or prints as they are; only a hand-edited or foreign store
#: holds others, and they keep the factory value
_USABLE: dict[str, Callable[[Any], bool]] = {
    "speed": lambda v: v > 0,
    "accel_ms": lambda v: v >= 1,
    "counts_per_mm": lambda v: v > 0,
    "unit_multiplier": lambda v: v != 0,
    "polarity": lambda v: v in (1, -1),
    "rename": lambda v: v is None or 65 <= v <= 90,
    "js_fast": lambda v: v != 0,
    "vb_decimals": lambda v: 0 <= v <= 6,
    "rt_report_ms": lambda v: v > 0,
    "stop_bits": lambda v: v in (1, 2),
    "user_string": lambda v: len(v) <= 20 and all(" " <= ch <= "~" for ch in v),
}


#: told the key path (`saved.axes.X.speed`) and value of a stored value that keeps its factory value
Reject = Callable[[str, Any], None]


def from_plain(factory: T, data: Any, path: str, reject: Reject) -> T:
    """`factory` updated with the known keys of `data` (the stored mapping at `path`; None when
    nothing is stored). Values of another type, not finite or unusable (`_USABLE`) keep the factory
    value and go to `reject`; unknown keys are ignored, so a store written by another version or
    edited by hand still loads."""
    if data is None:
        return dataclasses.replace(factory)  # type: ignore[type-var]
    if not isinstance(data, dict):
        reject(path, data)
        return dataclasses.replace(factory)  # type: ignore[type-var]
    current = to_plain(factory)
    updates = {}
    for key, value in data.items():
        if key not in current:
            continue
        if _same_kind(current[key], value) and _usable(key, value):
            updates[key] = _merged(current[key], value, f"{path}.{key}", reject)
        else:
            reject(f"{path}.{key}", value)
    return dataclasses.replace(factory, **updates)  # type: ignore[type-var]


def _usable(key: str, value: Any) -> bool:
    return key not in _USABLE or _USABLE[key](value)


def _same_kind(old: Any, new: Any) -> bool:
    if old is None:  # the only optional setting, Z2B's pending rename, is an int when set
        return new is None or (isinstance(new, int) and not isinstance(new, bool))
    if isinstance(old, bool) or isinstance(new, bool):
        return isinstance(old, bool) and isinstance(new, bool)
    if isinstance(old, int | float):
        return finite_number(new)
    return isinstance(new, type(old))


def _merged(old: Any, new: Any, path: str, reject: Reject) -> Any:
    """A stored mapping (BCA assignments) keeps the factory keys, each updated by a value of its kind."""
    if not isinstance(old, dict):
        return new
    merged = dict(old)
    for key, value in new.items():
        if key not in old:
            continue
        if _same_kind(old[key], value):
            merged[key] = value
        else:
            reject(f"{path}.{key}", value)
    return merged
