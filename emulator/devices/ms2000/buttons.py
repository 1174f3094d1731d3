"""Front-panel buttons: press classes, the button-flag byte, functions and their assignment (MS-85,
MS-86).

A press is classified on release: normal < 1 s, long 1–3 s, extra-long ≥ 3 s. Modules claim presses
first, in priority order (MS-85); otherwise the function assigned to that press runs. Function
numbers follow Appendix B of the specification: 0 none, 1 zero all axes, 2 move all axes to 0,
3 toggle joystick speed, 4–15 module functions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.moduleset import ModuleSet
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.settings import CardAuto, CardSettings

NAMES = ("at", "home", "joystick", "zero")
NORMAL, LONG, EXTRA = "normal", "long", "extra"
PRESS_CODES = {NORMAL: 1, LONG: 2, EXTRA: 3}
PRESSES = {code: press for press, code in PRESS_CODES.items()}
#: EXTRA M flag byte: two bits per button (MS-86)
FLAG_SHIFT = {"at": 0, "home": 2, "joystick": 4, "zero": 6}
#: BE Z enable bits (MS-86); bit 4 gates the TTL inputs
ENABLE_BIT = {"zero": 1, "home": 2, "at": 4, "joystick": 8}
TTL_ENABLE_BIT = 16
#: which BCA letter assigns which press [choice: the real letter map is not public]
BCA_PRESS = {
    ("at", NORMAL): "X",
    ("at", LONG): "Y",
    ("at", EXTRA): "Z",
    ("home", LONG): "F",
    ("home", EXTRA): "T",
    ("joystick", LONG): "R",
    ("zero", LONG): "M",
    ("zero", EXTRA): "M",
}
TOGGLE_CHAR_S = 1.0


def classify(ms: float) -> str:
    if ms < 1000:
        return NORMAL
    return LONG if ms < 3000 else EXTRA


class ButtonsOwner(Protocol):
    """All the front panel uses of its controller."""

    @property
    def card(self) -> CardSettings:
        """`BE`, `BZ` and `VB` (MS-85, MS-86, MS-96)."""

    @property
    def card_auto(self) -> CardAuto:
        """`BCA` (MS-86)."""

    @property
    def modules(self) -> ModuleSet:
        """Presses and `BE F` functions the modules claim."""

    def at(self, due: float, action: Callable[[float], None]) -> Timer: ...

    def unsolicited(self, text: str, t: float) -> None: ...

    def halt_all(self, t: float) -> bool: ...

    def zero_all(self, t: float) -> None: ...

    def move_all_to_zero(self, t: float) -> None: ...


class Buttons:
    def __init__(self, controller: ButtonsOwner) -> None:
        self.controller = controller
        self.flags = 0
        self.fast = True
        self.toggled_at: float | None = None
        #: how long the press being released was held (ms): modules may need more than its class
        self.held_ms = 0.0

    def reset(self) -> None:
        self.flags = 0
        self.fast = True
        self.toggled_at = None

    def enabled(self, name: str) -> bool:
        return bool(self.controller.card.button_enable & ENABLE_BIT[name])

    def press(self, name: str, ms: float, t: float) -> None:
        if not self.enabled(name):
            return
        if name == "zero" and self.controller.card.button_zero_normal != 0:
            self.controller.halt_all(t)
        self.controller.at(t + ms / 1000, lambda due: self.release(name, ms, due))

    def release(self, name: str, ms: float, t: float) -> None:
        press = classify(ms)
        self.held_ms = ms
        shift = FLAG_SHIFT[name]
        self.flags = (self.flags & ~(3 << shift)) | (PRESS_CODES[press] << shift)
        if self.controller.card.vb_flags & 2 and name == "joystick":
            self.controller.unsolicited("p" if press == NORMAL else "P", t)
        self.run(name, press, t)

    def run(self, name: str, press: str, t: float) -> None:
        """Modules claim a press first, by priority (MS-85); else its assigned function runs."""
        if not self.controller.modules.button(name, press, t):
            self.run_function(self.function_for(name, press), t)

    def function_for(self, name: str, press: str) -> int:
        card = self.controller.card
        if (name, press) == ("zero", NORMAL):
            return card.button_zero_normal
        if (name, press) == ("home", NORMAL):
            return card.button_home_normal
        if (name, press) == ("joystick", NORMAL):
            return 3
        if (name, press) == ("joystick", EXTRA):
            return card.button_joystick_extra
        letter = BCA_PRESS.get((name, press))
        return self.controller.card_auto.bca.get(letter, 0) if letter else 0

    def functions(self) -> dict[int, Callable[[float], None]]:
        table: dict[int, Callable[[float], None]] = {
            0: lambda t: None,
            1: self.controller.zero_all,
            2: self.controller.move_all_to_zero,
            3: self.toggle,
        }
        table.update(self.controller.modules.button_functions())
        return table

    def valid_function(self, number: float) -> bool:
        return number in self.functions()

    def run_function(self, number: int, t: float) -> None:
        action = self.functions().get(number)
        if action is not None:
            action(t)

    def toggle(self, t: float) -> None:
        self.fast = not self.fast
        self.toggled_at = t

    def left_char(self, t: float) -> str | None:
        if self.toggled_at is None or t - self.toggled_at >= TOGGLE_CHAR_S:
            return None
        return "f" if self.fast else "s"

    def take_flags(self) -> int:
        value, self.flags = self.flags, 0
        return value

    def set_flags(self, value: int, t: float) -> None:
        """EXTRA M=n: set the byte and run the presses it encodes, @ first (MS-86)."""
        self.flags = value
        for name in NAMES:
            code = (value >> FLAG_SHIFT[name]) & 3
            if code:
                self.run(name, PRESSES[code], t)
