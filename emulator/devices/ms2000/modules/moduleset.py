"""The modules of one controller: the only caller of their methods and the dispatcher of their events."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

from emulator.device import ControlError
from emulator.devices.ms2000.calls import Call, CommandError, Param, Pending, Reply
from emulator.devices.ms2000.modules import MODULES, Handler, Module
from emulator.devices.ms2000.modules.capabilities import (
    AutoSettings,
    CatchUp,
    CommandVeto,
    ControlChannel,
    ExtraParams,
    FocusWheel,
    In0Interrupt,
    LcdLine,
    LcdSegment,
    PanelButtons,
    TtlIn,
    TtlOut,
)
from emulator.devices.ms2000.modules.events import Event

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from protocols.ms2000 import Shape

T = TypeVar("T")


class ModuleSet:
    """The modules a profile lists, built on one host; the controller reaches them only through here.

    Order among modules: everything runs on the modules in the profile's `modules` order (the order
    `BU X` prints, MS-102), event handlers included, except that a front-panel press is offered by
    `button_priority` first (MS-85; ties in profile order) and a TTL mode is served by the first
    module declaring it. A capability query (`get`) answers with the first module that has it.

    Order in the controller's life:
    1. construction: modules built in profile order, the event table (class -> handlers) built once;
       `handlers()` installed after the base commands (a module may take over a base command),
       `query_shapes` merged; every handler of the table then runs only after each `CommandVeto`
       let the command through;
    2. power-up and software reset (MS-112): `restore()` (and `AutoSettings.restore_auto()`) after
       the base settings are restored, then, once axes, buttons and low-level mode are back to idle,
       the `Reset` event; TTL OUT0 is re-applied after it, so `out0_level()` sees restored state;
    3. while running, each when it happens: for a `TTL` command `In0ModeChanged` (X set),
       `Out0ModeChanged` (Y set), OUT0 re-applied, then `TtlTrailingValue` (`TTL Y=n v`, MS-24) and
       OUT0 re-read; `in0_trigger()` on an IN0 edge or a bare `RM`, then, for an edge, `In0Edge`;
       `ArrayArrival` when ARRAY reaches a cell; `RmX` after an accepted `RM X=`; `button()` on a
       release, before any base function; `in0_release()` on an IN0 falling edge; `FocusWheel` on a
       wheel turn, before the axis moves; `MoveComplete` after the base effects of a completed move
       (event, `VB X` lines, OUT0 pulse); `Halt` after every axis stopped; `Zeroing` before ZERO
       (command or button) zeroes the axes; `save()` at `SS Z`; `save_auto()` whenever any
       remembered setting changes; `CatchUp` at the end of every model step;
    4. whenever asked: `bu_line()`, `lcd_segment()`, `LcdLine`, `state_char()`, `observe()`,
       `control_input()`, `out0_level()`, `out0_pwm()`, `button_functions()`, `ExtraParams` (by a
       base settings command as it runs), and any capability through `get()`/`all_of()`.
    """

    def __init__(self, controller: ModuleOwner, names: Sequence[str]) -> None:
        #: the profile's list, feature flags (LL COMMANDS) included
        self.names = tuple(names)
        self._modules = [MODULES[n](controller) for n in self.names if n in MODULES]
        self._found: dict[type, tuple[Any, ...]] = {}
        self._by_priority = sorted(self.all_of(PanelButtons), key=lambda m: m.button_priority)
        table: dict[type[Event], list[Callable[[Any], None]]] = {}
        for module in self._modules:
            for kind, method in module.subscriptions.items():
                table.setdefault(kind, []).append(getattr(module, method))
        #: event class -> its handlers in profile order, built once (events.py)
        self._subscribers = {kind: tuple(handlers) for kind, handlers in table.items()}

    def _named(self, name: str) -> Module | None:
        return next((m for m in self._modules if m.name == name), None)

    # ---- events and capabilities ----------------------------------------------------------------

    def emit(self, event: Event) -> None:
        """Call the handlers of `event`'s class, in profile order."""
        for handler in self._subscribers.get(type(event), ()):
            handler(event)

    def all_of(self, kind: type[T]) -> tuple[T, ...]:
        """The modules with capability `kind` (capabilities.py), in profile order."""
        found = self._found.get(kind)
        if found is None:
            found = self._found[kind] = tuple(m for m in self._modules if isinstance(m, kind))
        return found

    def get(self, kind: type[T]) -> T | None:
        """The first module with capability `kind` (the one that owns the value), if any."""
        found = self.all_of(kind)
        return found[0] if found else None

    # ---- construction -------------------------------------------------------------------------

    def handlers(self) -> dict[str, Handler]:
        """Later modules replace earlier ones' handlers of a shared word, unless the earlier one
        `outranks` the later (CRISP keeps `LK`/`LR`/`UL` beside TRACKING, §9.0)."""
        table: dict[str, Handler] = {}
        owner: dict[str, Module] = {}
        for module in self._modules:
            for key, handler in module.handlers().items():
                holder = owner.get(key)
                if holder is not None and module.name in holder.outranks:
                    continue
                table[key] = handler
                owner[key] = module
        return table

    def query_shapes(self) -> dict[str, Shape]:
        return {key: shape for m in self._modules for key, shape in m.query_shapes.items()}

    def guarded(self, table: dict[str, Handler]) -> dict[str, Handler]:
        """The whole command table, each handler behind the modules' `refuse()` vetoes (MS-109).
        Only modules with `CommandVeto` are asked, and without one the table is left as it is:
        every command passes here."""
        refusers = self.all_of(CommandVeto)
        if not refusers:
            return table

        def guard(handler: Handler) -> Handler:
            def run(call: Call) -> Reply | Pending:
                for module in refusers:
                    code = module.refuse(call)
                    if code is not None:
                        raise CommandError(code)
                return handler(call)

            return run

        return {key: guard(handler) for key, handler in table.items()}

    def extra_params(self, key: str) -> dict[str, Param]:
        """Letters the modules add to the base settings command `key` (`VB T`, MS-109)."""
        return {letter: p for m in self.all_of(ExtraParams) for letter, p in m.extra_params(key).items()}

    # ---- reports and the control channel --------------------------------------------------------

    def bu_lines(self) -> list[str]:
        """One `BU X` line per listed module; a feature flag prints its name (MS-102)."""
        lines = []
        for name in self.names:
            module = self._named(name)
            lines.append(module.bu_line() if module is not None else name)
        return lines

    def lcd_segments(self, t: float) -> list[str]:
        """The segments of LCD line 2, or the line of a module that takes it alone (§9.0)."""
        states = self.state_chars()
        for module in self.all_of(LcdLine):
            line = module.lcd_line(t, states)
            if line is not None:
                return [line] if line else []
        return [s for m in self.all_of(LcdSegment) if (s := m.lcd_segment(t))]

    def state_chars(self) -> dict[str, str]:
        """Module name -> its one-character state, for modules that have one (MS-SEQ-8)."""
        return {
            m.name: c
            for m in self._modules
            if isinstance(m, LcdSegment) and (c := m.state_char()) is not None
        }

    def observables(self) -> dict[str, Callable[[float], Any]]:
        return {name: get for m in self.all_of(ControlChannel) for name, get in m.observables().items()}

    def inputs(self) -> set[str]:
        return {name for m in self.all_of(ControlChannel) for name in m.inputs}

    def control_input(self, name: str, params: dict[str, Any], t: float) -> Any:
        module = next((m for m in self.all_of(ControlChannel) if name in m.inputs), None)
        if module is None:
            raise ControlError(f"no module takes input {name!r}")
        return module.control_input(name, params, t)

    # ---- SS Z and the power cycle -------------------------------------------------------------

    def save(self) -> dict[str, dict[str, Any]]:
        return {m.name: m.save() for m in self._modules}

    def restore(self, saved: dict[str, Any], reject: Callable[[str, Any], None]) -> None:
        """Each module's `saved.modules.<name>` section, or its factory values (None). A stored
        value the module did not take (it kept its own) is passed to `reject` (MS-111)."""
        for module in self._modules:
            path = f"saved.modules.{module.name}"
            _restore_section(module.restore, module.save, saved.get(module.name), path, reject)

    def save_auto(self) -> dict[str, dict[str, Any]]:
        """The settings modules remember as soon as they change (DLED maxima, MS-111)."""
        return {
            m.name: section
            for m in self._modules
            if isinstance(m, AutoSettings) and (section := m.save_auto())
        }

    def restore_auto(self, saved: dict[str, Any], reject: Callable[[str, Any], None]) -> None:
        """Each module's `auto.modules.<name>` section, as `restore` does for `SS Z`."""
        for module in self._modules:
            path = f"auto.modules.{module.name}"
            data = saved.get(module.name)
            if isinstance(module, AutoSettings):
                _restore_section(module.restore_auto, module.save_auto, data, path, reject)
            else:  # nothing to restore, but a section that is not a mapping is still reported
                _restore_section(lambda _: None, dict, data, path, reject)

    # ---- motion -------------------------------------------------------------------------------

    def wheel(self, counts: float, t: float) -> bool:
        """Offer a wheel turn to the modules; True when one took it (the axis does not move)."""
        return any(m.wheel(counts, t) for m in self.all_of(FocusWheel))

    def catch_up_hooks(self) -> list[Callable[[float], None]]:
        """The `catch_up` of each module that has the capability (most have not: nothing per step)."""
        return [m.catch_up for m in self.all_of(CatchUp)]

    # ---- TTL (§6.7) ---------------------------------------------------------------------------

    def _in0_module(self, mode: int) -> TtlIn | None:
        return next((m for m in self.all_of(TtlIn) if mode in m.in0_modes), None)

    def _out0_module(self, mode: int) -> TtlOut | None:
        return next((m for m in self.all_of(TtlOut) if mode in m.out0_modes), None)

    def in0_available(self, mode: int) -> bool:
        """Mode 0 always; others need a module serving the mode and the IN0 interrupt (MS-90)."""
        if mode == 0:
            return True
        return bool(self.all_of(In0Interrupt)) and self._in0_module(mode) is not None

    def in0_trigger(self, mode: int, t: float) -> None:
        module = self._in0_module(mode) if mode else None
        if module is not None:
            module.in0_trigger(mode, t)

    def in0_release(self, mode: int, t: float) -> None:
        module = self._in0_module(mode) if mode else None
        if module is not None:
            module.in0_release(mode, t)

    def out0_modes(self) -> set[int]:
        return {mode for m in self.all_of(TtlOut) for mode in m.out0_modes}

    def out0_level(self, mode: int) -> int | None:
        """OUT0's level in `mode` when a module drives it, else None (MS-91)."""
        module = self._out0_module(mode)
        return None if module is None else module.out0_level()

    def out0_pwm(self, mode: int) -> float | None:
        module = self._out0_module(mode)
        return None if module is None else module.out0_pwm()

    # ---- buttons (MS-85, MS-86) ---------------------------------------------------------------

    def button(self, name: str, press: str, t: float) -> bool:
        """Offer a released press to the modules by priority; True when one claimed it."""
        return any(m.button(name, press, t) for m in self._by_priority)

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        table: dict[int, Callable[[float], None]] = {}
        for module in self.all_of(PanelButtons):
            table.update(module.button_functions())
        return table


def _restore_section(
    restore: Callable[[dict[str, Any] | None], None],
    save: Callable[[], dict[str, Any]],
    data: Any,
    path: str,
    reject: Callable[[str, Any], None],
) -> None:
    """Restore one module's stored section; a value it did not take goes to `reject` (MS-111)."""
    if data is not None and not isinstance(data, dict):
        reject(path, data)
        data = None
    restore(data)
    kept = save()
    for key, value in (data or {}).items():
        if key in kept and kept[key] is not value and kept[key] != value:
            reject(f"{path}.{key}", value)
