"""Firmware modules as plug-ins: one file per module in this package (rule 6 of the design).

A module subclasses `Module`, decorates it with `@register`, and declares in its own file what
every module has:

- `name`: the module's name in a profile's `modules` list and on its `BU X` line (`bu_line()`);
- `handlers()`: command key (protocols.ms2000 table) -> handler; a command whose owning modules are
  all absent from the profile replies `:N-1` (MS-118); `query_shapes` adds reply shapes. Handlers
  are installed in the profile's module order after the base ones, so a module may also take over a
  base command; `outranks`: modules whose handlers of a shared word never replace this one's (CRISP
  over TRACKING for `LK`/`LR`/`UL`, §9.0);
- `profile_fields` / `knob_fields`: schema fields merged into the profile (top level / `knobs`);
- `save()`/`restore()`: its part of `SS Z` (MS-111), under `saved.modules.<name>`;
- `channels()`: ports it adds beside `main` (TTL REPORT's `aux`, MS-TTLREP-1), known from the
  profile alone, before any model exists: the daemon creates one port per channel (`channels_of`).

Everything else is opt-in. A module derives from the capability classes it has (capabilities.py):
TTL IN0 and OUT0 modes it serves (`TtlIn`, `TtlOut`, `In0Interrupt`), front-panel presses and
`BE F` functions (`PanelButtons`), an LCD segment (`LcdSegment`) or the whole line (`LcdLine`),
control-channel observables and inputs (`ControlChannel`), settings remembered at once
(`AutoSettings`), vetoes and extra letters on base commands (`CommandVeto`, `ExtraParams`), the
focus wheel and a per-step catch-up (`FocusWheel`, `CatchUp`), and values others read of it (RING
BUFFER's `ReportAxes` and `Playback`, AUTOFOCUS's `FocusScore`, CRISP's `FocusAxisSelect`,
TRACKING's `ReportFields`, ARRAY's `RmXServer`), each asked of the modules that have it.

What happens in the controller (reset, HALT, a completed move, ZERO, IN0 edges, TTL mode changes,
ARRAY's arrivals, RING BUFFER's `RM X`) reaches a module as a typed event it subscribes to with
`@on(EventClass)` (events.py); a module sends one to the others with `controller.emit()`.

A module sees the controller only as a `ModuleOwner` (modules/owner.py), and only the controller's
`ModuleSet` (modules/moduleset.py) calls it, in the order documented there. Adding a module is one
file here, a profile that lists it, its documentation and its tests; a new interaction between two
modules is one event class, an `emit` in one and an `@on` in the other.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

from emulator.device import MAIN
from emulator.devices.ms2000.calls import Handler
from emulator.devices.ms2000.modules.events import Event, subscriptions
from emulator.profiles.schema import Field
from protocols.ms2000 import Shape

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner

#: modules present as plain feature flags, without a plug-in (low-level mode is base code, §8)
FEATURE_FLAGS = ("LL COMMANDS",)


class Module:
    name: ClassVar[str]
    query_shapes: ClassVar[Mapping[str, Shape]] = {}
    profile_fields: ClassVar[tuple[Field, ...]] = ()
    knob_fields: ClassVar[tuple[Field, ...]] = ()
    #: names of modules whose handlers never replace this one's, whatever the profile order (§9.0)
    outranks: ClassVar[frozenset[str]] = frozenset()
    #: event class -> name of the method `@on` subscribed to it (events.py), found once per class
    subscriptions: ClassVar[Mapping[type[Event], str]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.subscriptions = subscriptions(cls)

    def __init__(self, controller: ModuleOwner) -> None:
        self.controller = controller

    @classmethod
    def channels(cls, knobs: Any) -> tuple[str, ...]:
        """Channels (ports) the module adds beside `main` under these profile knobs."""
        return ()

    def handlers(self) -> dict[str, Handler]:
        return {}

    def bu_line(self) -> str:
        return self.name

    def save(self) -> dict[str, Any]:
        return {}

    def restore(self, data: dict[str, Any] | None) -> None:
        """Settings from `SS Z` (None: factory)."""


MODULES: dict[str, type[Module]] = {}


def register(cls: type[Module]) -> type[Module]:
    MODULES[cls.name] = cls
    return cls


def channels_of(config: Any) -> tuple[str, ...]:
    """The channels of a controller built from `config` (an `Ms2000Config`): `main`, then those its
    modules add, in profile order."""
    extra = [c for name in config.modules if name in MODULES for c in MODULES[name].channels(config.knobs)]
    return (MAIN, *dict.fromkeys(extra))


def known_names() -> tuple[str, ...]:
    return (*FEATURE_FLAGS, *MODULES)


def _load() -> None:
    for info in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{info.name}")


_load()
