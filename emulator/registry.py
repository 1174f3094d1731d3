"""Device families: name -> profile schema and model factory. Device modules register themselves."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, TypeVar

if TYPE_CHECKING:
    from emulator.device import Device, HostServices
    from emulator.profile import Config, Profile

#: a family's profile dataclass (an `emulator.schema.Schema` with a `line` section)
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
    factory: Callable[[str, Profile[C], float, HostServices], Device]
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
        import emulator.devices as package

        for info in pkgutil.iter_modules(package.__path__):
            importlib.import_module(f"{package.__name__}.{info.name}")


def families() -> dict[str, Family[Any]]:
    _load_builtins()
    return dict(_families)


def family(name: str) -> Family[Any] | None:
    _load_builtins()
    return _families.get(name)


def channels_of(profile: Profile[Any]) -> tuple[str, ...]:
    """The channels of a device built from `profile` (`main` first)."""
    found = family(profile.family)
    return main_only(profile.config) if found is None else found.channels(profile.config)
