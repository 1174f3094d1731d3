"""Firmware modules as plug-ins: one file per module in this package (rule 6 of the design).

A module subclasses `Module`, decorates it with `@register`, and declares everything it adds to the
controller in its own file:

- `name`: the module's name in a profile's `modules` list and on its `BU X` line (`bu_line()`);
- `handlers()`: command key (protocols.ms2000 table) -> handler; a command whose owning modules are
  all absent from the profile replies `:N-1` (MS-118); `query_shapes` adds reply shapes. Handlers
  are installed in the profile's module order after the base ones, so a module may also take over a
  base command;
- `profile_fields` / `knob_fields`: schema fields merged into the profile (top level / `knobs`);
- `save()`/`restore()`: its part of `SS Z` (MS-111), under `saved.modules.<name>`;
- `in0_modes`, `out0_modes`: TTL IN0/OUT0 mode numbers it implements (`TTL X=`, `TTL Y=`);
  `provides_in0_interrupt`: it is the IN0 interrupt service (INO_INT) that non-zero modes need;
- `button_priority`, `button()`, `button_functions()`: front-panel presses it claims (MS-85) and
  `BE F` function numbers it implements (MS-86);
- `observable` / `observe()` (more names: `observables()`), `inputs` / `control_input()`:
  control-channel vocabulary;
- `lcd_segment()`, `lcd_line()` (a module that takes LCD line 2 alone: SEQUENCER), `state_char()`
  (the one character another module's segment shows), `reset()`, `halt()`, and the event hooks
  `in0_edge()`, `array_arrival()`, `in0_trigger()`, `in0_mode_changed()`,
  `out0_mode_changed()`, `out0_level()`, `out0_pwm()`, `ttl_trailing_value()`, `move_complete()`,
  `zeroing()`, `report_mask()`, `focus_score()`;
- `extra_params()`: letters added to a base settings command; `refuse()`: a veto on any command.
- `save_auto()`/`restore_auto()`: settings remembered as soon as they change (MS-111), under
  `auto.modules.<name>`; `report_fields()`: fields appended to IN0 mode 5 reports.
- `outranks`: modules whose handlers of a shared command word this one's replace whatever the
  profile order (CRISP over TRACKING for `LK`/`LR`/`UL`, §9.0); `in0_release()`: IN0 falling
  edge; `wheel()`: a claim on the focus wheel; `focus_index()`: the focus axis it selects.
- `rm_x_values` / `rm_x()`: `RM X=` values it serves besides clearing (ARRAY's `RM X=1`,
  MS-ARRAY-6); `playback_mode()`: the ring buffer's `RM F`, for modules that follow it (MS-ARRAY-5).
- `channels()`: ports it adds beside `main` (TTL REPORT's `aux`, MS-TTLREP-1), known from the
  profile alone, before any model exists: the daemon creates one port per channel (`channels_of`).

A module sees the controller only as a `ModuleHost` (modules/host.py), and only the controller's
`ModuleSet` (modules/moduleset.py) calls its hooks, in the order documented there. Adding a module
is one file here, a profile that lists it, its documentation and its tests.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, ClassVar

from emulator.device import MAIN, ControlError
from emulator.devices.ms2000.calls import Call, Param, Pending, Reply
from emulator.schema import Field
from protocols.ms2000 import Shape

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.host import ModuleHost

Handler = Callable[[Call], "Reply | Pending"]

#: modules present as plain feature flags, without a plug-in (low-level mode is base code, §8)
FEATURE_FLAGS = ("LL COMMANDS",)


class Module:
    name: ClassVar[str]
    query_shapes: ClassVar[Mapping[str, Shape]] = {}
    profile_fields: ClassVar[tuple[Field, ...]] = ()
    knob_fields: ClassVar[tuple[Field, ...]] = ()
    in0_modes: ClassVar[frozenset[int]] = frozenset()
    provides_in0_interrupt: ClassVar[bool] = False
    out0_modes: ClassVar[frozenset[int]] = frozenset()
    #: `RM X=` values besides 0 (clear) that the module serves through `rm_x()` (MS-RB-4)
    rm_x_values: ClassVar[frozenset[int]] = frozenset()
    #: lower claims buttons first (MS-85: SEQUENCER, CRISP, SCAN, ARRAY, AUTOFOCUS, PLANAR, RING BUFFER)
    button_priority: ClassVar[int] = 100
    observable: ClassVar[str | None] = None
    inputs: ClassVar[frozenset[str]] = frozenset()
    #: names of modules whose handlers never replace this one's, whatever the profile order (§9.0)
    outranks: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, host: ModuleHost) -> None:
        self.host = host

    @classmethod
    def channels(cls, knobs: Any) -> tuple[str, ...]:
        """Channels (ports) the module adds beside `main` under these profile knobs."""
        return ()

    def handlers(self) -> dict[str, Handler]:
        return {}

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {}

    def bu_line(self) -> str:
        return self.name

    def lcd_segment(self, now: float) -> str | None:
        return None

    def lcd_line(self, now: float, states: Mapping[str, str]) -> str | None:
        """LCD line 2 before the uptime when the module takes the whole line, the other modules'
        segments left out (SEQUENCER, §9.0); `states`: each module's `state_char()` by name."""
        return None

    def state_char(self) -> str | None:
        """The module's state as one character, for a segment that shows it beside others
        (SEQUENCER's, MS-SEQ-8): PLANAR CORRECTION's and ARRAY's."""
        return None

    def observe(self, now: float) -> Any:
        return None

    def observables(self) -> dict[str, Callable[[float], Any]]:
        """Control-channel observables: `observable` read by `observe()`; a module publishing more
        than one name (TRACER: `tracer`, `analog_out_v`) extends this."""
        return {self.observable: self.observe} if self.observable else {}

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        raise ControlError(f"{self.name}: no input {name!r}")

    def save(self) -> dict[str, Any]:
        return {}

    def restore(self, data: dict[str, Any] | None) -> None:
        """Settings from `SS Z` (None: factory)."""

    def save_auto(self) -> dict[str, Any]:
        """Settings remembered as soon as they change (DLED maxima, MS-111), under
        `auto.modules.<name>`; the module calls `host.limits_changed()` when they change."""
        return {}

    def restore_auto(self, data: dict[str, Any] | None) -> None:
        """The remembered settings at power-up and reset (None: factory)."""

    def reset(self, now: float) -> None:
        """Software reset or power-up: state machines back to idle."""

    def halt(self, now: float) -> None:
        """HALT: stop whatever the module is running (MS-76)."""

    def in0_edge(self, now: float) -> None:
        """An IN0 rising edge, whatever the IN0 mode (SEQUENCER's TTL_TRIGGER_RECEIVED, MS-SEQ-2)."""

    def array_arrival(self, now: float) -> None:
        """ARRAY reached a cell (SEQUENCER's ARRAY_MOVE_DONE, MS-ARRAY-8)."""

    def in0_trigger(self, mode: int, now: float) -> None:
        """An IN0 rising edge (or a bare `RM`, MS-RB-5) in one of `in0_modes`."""

    def in0_release(self, mode: int, now: float) -> None:
        """An IN0 falling edge in one of `in0_modes` (CRISP's level-driven mode 9, MS-CRISP-7)."""

    def in0_mode_changed(self, mode: int, now: float) -> None:
        """`TTL X` was set (to any mode)."""

    def out0_mode_changed(self, mode: int, now: float) -> None:
        """`TTL Y` was set (to any mode)."""

    def out0_level(self) -> int | None:
        """Level of OUT0 in one of `out0_modes` (None: not driven by this module)."""
        return None

    def out0_pwm(self) -> float | None:
        return None

    def ttl_trailing_value(self, out_mode: int, value: float, now: float) -> None:
        """A bare number after `TTL Y=<out_mode>` (MS-24, MS-LED-3)."""

    def button(self, name: str, press: str, now: float) -> bool:
        """A released front-panel button; True when the module claims it."""
        return False

    def wheel(self, counts: float, now: float) -> bool:
        """The focus wheel turned by `counts`; True when the module takes the turn instead of the
        axis (CRISP's lock offset, MS-CRISP-6)."""
        return False

    def focus_index(self) -> int | None:
        """The hardware index of the focus axis, if the module selects it (CRISP's `UL F`)."""
        return None

    def move_complete(self, axes: list[str], now: float) -> None:
        """A commanded move completed; `axes` are the letters of the axes it moved to the end."""

    def zeroing(self, now: float) -> None:
        """ZERO or the zero button is about to make every axis read 0 (PLANAR CORRECTION
        re-references its plane here, MS-PC-2)."""

    def report_mask(self) -> int | None:
        """Axes (bit 0 = first motor axis) that IN0 mode 5 reports, if the module selects them."""
        return None

    def focus_score(self, now: float) -> int | None:
        """The video focus score `RA Z` reads, if the module measures one (AUTOFOCUS, MS-117)."""
        return None

    def catch_up(self, now: float) -> None:
        """Bring state that follows from time and motion up to `now`, at the end of every model
        step (CRISP's lock entering `N` as a focus move starts, MS-CRISP-2), so OUT0 and every
        observer see it as of the same instant. Only modules that define it are called."""

    def report_fields(self, now: float) -> list[str]:
        """Fields the module appends to each IN0 mode 5 report line (TRACKING's PMT sum, MS-TRACK-3)."""
        return []

    def rm_x(self, value: int, now: float) -> None:
        """`RM X=value` was accepted: 0 after the ring buffer cleared, or one of `rm_x_values`."""

    def playback_mode(self) -> int | None:
        """The ring-buffer playback mode (`RM F`, 1–3), if the module keeps one (MS-RB-4)."""
        return None

    def extra_params(self, key: str) -> dict[str, Param]:
        """Letters the module adds to the base settings command `key` (NO CHANGE SETTINGS: `VB T`)."""
        return {}

    def refuse(self, call: Call) -> int | None:
        """A command about to run: an error code to answer instead of running it (None: run it).
        NO CHANGE SETTINGS refuses writes to write-protected commands (MS-109)."""
        return None


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
