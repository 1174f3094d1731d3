"""Device families: name -> profile schema and model factory. Device modules register themselves."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from emulator.schema import Struct

if TYPE_CHECKING:
    from emulator.device import Device, HostServices
    from emulator.profile import Profile


@dataclass(frozen=True)
class Family:
    name: str
    summary: str
    schema: Struct
    factory: Callable[[str, Profile, float, HostServices], Device]


_families: dict[str, Family] = {}
_loaded = False


def register(family: Family) -> Family:
    _families[family.name] = family
    return family


def _load_builtins() -> None:
    """Import every module of the `emulator.devices` package; each registers its family."""
    global _loaded
    if not _loaded:
        _loaded = True
        import emulator.devices as package

        for info in pkgutil.iter_modules(package.__path__):
            importlib.import_module(f"{package.__name__}.{info.name}")


def families() -> dict[str, Family]:
    _load_builtins()
    return dict(_families)


def family(name: str) -> Family | None:
    _load_builtins()
    return _families.get(name)
