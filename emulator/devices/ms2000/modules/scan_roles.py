"""`SN` (SCAN) axis roles and pattern, shared by SCAN MODULE and ARRAY MODULE (MS-SCAN-1, MS-ARRAY-3).

`SN X=a Y=b Z=c` gives motor axes X, Y, Z a role (1 fast, 2 slow, 0 unused; defaults 1, 2, 0) and
`SN F` the pattern (0 raster, 1 serpentine; raster by default in builds with SCAN MODULE, serpentine
in builds with only ARRAY MODULE). Both modules read the one `ScanRoles` of their controller
(`shared_roles`), so a build with both has a single setting; each saves it with its own `SS Z` part.
Not a module: this file registers nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
from weakref import WeakKeyDictionary

from emulator.devices.ms2000.calls import Param, one_of

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner

SCAN_MODULE = "SCAN MODULE"
ROLE_LETTERS = "XYZ"
UNUSED, FAST, SLOW = 0, 1, 2
RASTER, SERPENTINE = 0, 1
FACTORY_ROLES = {"X": FAST, "Y": SLOW, "Z": UNUSED}


def factory_pattern(controller: ModuleOwner) -> int:
    """MS-SCAN-1: raster in builds with SCAN MODULE, serpentine in ARRAY-only builds."""
    return RASTER if SCAN_MODULE in controller.cfg.modules else SERPENTINE


@dataclass
class ScanRoles:
    pattern: int
    roles: dict[str, int] = field(default_factory=lambda: dict(FACTORY_ROLES))

    def axis_with(self, role: int, controller: ModuleOwner) -> Axis | None:
        """The one motor axis given `role`; None when no axis or several have it."""
        letters = [letter for letter in ROLE_LETTERS if self.roles[letter] == role]
        return controller.axis_named(letters[0]) if len(letters) == 1 else None

    def params(self) -> dict[str, Param]:
        """`SN X/Y/Z` roles and `SN F` pattern: the letters are accepted whatever axes the build has
        (TV-146 queries `Z?` on an XY build)."""
        params = {letter: self._role(letter) for letter in ROLE_LETTERS}
        params["F"] = Param(lambda: self.pattern, self._set_pattern, one_of(RASTER, SERPENTINE))
        return params

    def _role(self, letter: str) -> Param:
        def store(value: float) -> None:
            self.roles[letter] = int(value)

        return Param(lambda: self.roles[letter], store, one_of(UNUSED, FAST, SLOW))

    def _set_pattern(self, value: float) -> None:
        self.pattern = int(value)

    def save(self) -> dict[str, Any]:
        return {"roles": dict(self.roles), "pattern": self.pattern}

    def restore(self, data: dict[str, Any], controller: ModuleOwner) -> None:
        """The saved roles and pattern (factory values for anything missing or unusable)."""
        roles = data.get("roles")
        self.roles = dict(FACTORY_ROLES)
        if isinstance(roles, dict):
            for letter, role in roles.items():
                if letter in self.roles and role in (UNUSED, FAST, SLOW):
                    self.roles[letter] = role
        pattern = data.get("pattern")
        self.pattern = pattern if pattern in (RASTER, SERPENTINE) else factory_pattern(controller)


_SHARED: WeakKeyDictionary[Any, ScanRoles] = WeakKeyDictionary()


def shared_roles(controller: ModuleOwner) -> ScanRoles:
    """The `SN` setting of the controller `host` (created at factory values on first use)."""
    roles = _SHARED.get(controller)
    if roles is None:
        roles = _SHARED[controller] = ScanRoles(factory_pattern(controller))
    return roles
