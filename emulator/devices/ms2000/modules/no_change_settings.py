"""NO CHANGE SETTINGS: write protection of chosen commands with `VB T` (§7, MS-109).

`VB T=1000+n` write-protects command number n, `VB T=n` releases it; an unknown number is `:N-4`.
A protected command still answers queries (every item `L?`); anything else it is asked, bare forms
included, replies `:N-4` and changes nothing [choice]. `VB T?` reads back the last code set (0 at
the factory) [choice]. The protections are saved with `SS Z` like the rest of `VB`; a reset returns
to the saved ones (MS-112). Without this module `VB T` is `:N-2` (a letter `VB` does not define).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.calls import Call, CommandError, Param
from emulator.devices.ms2000.modules import Module, register
from emulator.devices.ms2000.modules.capabilities import CommandVeto, ControlChannel, ExtraParams
from protocols.ms2000 import ErrorCode, Kind

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner

#: MS-109: command number -> command key (the numbers ASI's table shows legibly)
COMMAND_NUMBERS = {
    0: "AA", 1: "AC", 2: "B", 3: "BE", 4: "C", 6: "E", 11: "H", 12: "!", 15: "KI", 18: "M",
    20: "PC", 21: "RM", 24: "SL", 25: "SU", 26: "@", 27: "S", 35: "ES", 40: "MC", 41: "PD",
    42: "AF", 43: "WT", 44: "SS", 45: "SN", 51: "KA", 55: "UL", 60: "MA", 62: "AM", 64: "AL",
    65: "RU", 69: "HM", 71: "CCA", 72: "CCB", 75: "RT", 80: "LCD", 81: "WRDAC", 82: "AR", 83: "AH",
}  # fmt: skip
PROTECT_OFFSET = 1000


@register
class NoChangeSettings(Module, ExtraParams, CommandVeto, ControlChannel):
    name = "NO CHANGE SETTINGS"
    observable = "no_change_settings"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.protected: set[int] = set()
        self.last_code = 0

    def extra_params(self, key: str) -> dict[str, Param]:
        if key != "VB":
            return {}
        return {"T": Param(lambda: self.last_code, self._apply, _known_code)}

    def _apply(self, code: float) -> None:
        self.last_code = int(code)
        number = self.last_code % PROTECT_OFFSET
        if self.last_code >= PROTECT_OFFSET:
            self.protected.add(number)
        else:
            self.protected.discard(number)

    def refuse(self, call: Call) -> int | None:
        if call.key not in self._protected_keys():
            return None
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if items and all(i.kind is Kind.QUERY for i in items):
            return None
        return ErrorCode.OUT_OF_RANGE

    def _protected_keys(self) -> set[str]:
        return {COMMAND_NUMBERS[n] for n in self.protected}

    def observe(self, now: float) -> Any:
        return {"protected": sorted(self._protected_keys())}

    def save(self) -> dict[str, Any]:
        return {"protected": sorted(self.protected), "last_code": self.last_code}

    def restore(self, data: dict[str, Any] | None) -> None:
        data = data or {}
        numbers = data.get("protected", [])
        last = data.get("last_code", 0)
        valid = isinstance(numbers, list) and all(n in COMMAND_NUMBERS for n in numbers)
        self.protected = set(numbers) if valid else set()
        self.last_code = last if isinstance(last, int) and _is_known(last) else 0


def _is_known(code: int) -> bool:
    return 0 <= code < 2 * PROTECT_OFFSET and code % PROTECT_OFFSET in COMMAND_NUMBERS


def _known_code(value: float) -> float:
    """`T=n` or `T=1000+n` for a command number n of the table (MS-109), else `:N-4`."""
    if value != int(value) or not _is_known(int(value)):
        raise CommandError(ErrorCode.OUT_OF_RANGE)
    return value
