"""Device families: name -> profile schema and model factory. Device modules register themselves."""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, TypeVar

if TYPE_CHECKING:
    from emulator.device import Device, DeviceServices
    from emulator.profiles.profile import Config, Profile

#: a family's profile dataclass (an `emulator.profiles.schema.Schema` with a `line` section)
C = TypeVar("C", bound="Config")


def main_only(config: Any) -> tuple[str, ...]:
    return ("main",)


@dataclass(frozen=True)
class Family(Generic[C]):
    """`schema` is the profile's top dataclass; `factory` takes profiles of exactly that type, so
    mypy checks a model against the schema it is registered with. `channels` gives the channels
    (ports) a model built from a profile's config will have (`Device.channels`), known before it
    is built: rigs give each of them a port."""

    name: str
    summary: str
    schema: type[C]
    factory: Callable[[str, Profile[C], float, DeviceServices], Device]
    channels: Callable[[C], tuple[str, ...]] = main_only


_families: dict[str, Family[Any]] = {}
_loaded = False


def register(family: Family[C]) -> Family[C]:
    _families[family.name] = family
    return family


def _load_builtins() -> None:
    """Import every module of the `emulator.devices` package; each registers its family."""
    global _loaded
    if not _loaded:
        _loaded = True
        import pkgutil

        import emulator.devices as package

        for info in pkgutil.iter_modules(package.__path__):
            importlib.import_module(f"{package.__name__}.{info.name}")


def _load_builtin(name: str) -> None:
    """Import the one module of `emulator.devices` named `name`, if there is one: a daemon serving
    only MS2000s never imports the MP-285 model (start-up time)."""
    if not name.isidentifier() or name.startswith("_"):
        return
    module = f"emulator.devices.{name}"
    if importlib.util.find_spec(module) is not None:
        importlib.import_module(module)


def families() -> dict[str, Family[Any]]:
    _load_builtins()
    return dict(_families)


def family(name: str) -> Family[Any] | None:
    if name not in _families and not _loaded:
        _load_builtin(name)
        if name not in _families:  # not a module's name: look in all of them, as families() does
            _load_builtins()
    return _families.get(name)


def channels_of(profile: Profile[Any]) -> tuple[str, ...]:
    """The channels of a device built from `profile` (`main` first)."""
    found = family(profile.family)
    return main_only(profile.config) if found is None else found.channels(profile.config)
