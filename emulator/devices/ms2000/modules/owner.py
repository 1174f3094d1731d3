"""A module's owner: all a firmware module may use of its controller (rule 6 of the design).

A module is constructed with an object satisfying `ModuleOwner` and nothing else; mypy holds it to
these members. `model.Ms2000Device` implements it (as it implements `axis_owner.AxisOwner` for the
axes). A module that needs more adds it here and to the controller, on purpose and in review,
rather than reaching into controller state; what one module offers another travels as an event
(events.py) or a capability (capabilities.py), not as a member here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

if TYPE_CHECKING:
    from emulator.devices.ms2000.activity import Activity
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.calls import Handler, Rendered, Reply
    from emulator.devices.ms2000.modules.events import Event
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.settings import CardSettings
    from protocols.ms2000 import Shape

T = TypeVar("T")


class ModuleOwner(Protocol):
    # ---- configuration and settings (read; a module keeps its own state itself) ---------------

    @property
    def cfg(self) -> Any:
        """The validated profile (a module's own `profile_fields` included)."""

    @property
    def knobs(self) -> Any:
        """The profile's behaviour knobs (a module's own `knob_fields` included)."""

    @property
    def card(self) -> CardSettings:
        """Card-wide settings: `TTL` modes, `RT` times and the like."""

    @property
    def axes(self) -> Sequence[Axis]:
        """Motor axes in hardware order (bit `axis.index` of an axis mask)."""

    @property
    def servo_s(self) -> float:
        """The servo period: the shortest interval anything is timed to."""

    @property
    def baud(self) -> int:
        """The main port's baud rate, read from DIP switches 4 and 5 at power-up (MS-2)."""

    @property
    def last_relative(self) -> list[tuple[str, float | None]]:
        """The last `R` command's (axis letter, units) items (IN0 mode 2 repeats them, MS-90)."""

    @property
    def joystick_fast(self) -> bool:
        """The joystick button's speed toggle is on fast (MS-85); the side knobs follow it (MS-KNOB-1)."""

    @property
    def button_held_ms(self) -> float:
        """How long the front-panel button now being released was held (ms): the press classes end
        at 3 s, PLANAR CORRECTION's home press needs 6 s beside RING BUFFER (MS-PC-4)."""

    # ---- time ---------------------------------------------------------------------------------

    def at(self, due: float, action: Callable[[float], None]) -> Timer:
        """Run `action(due)` at device time `due` (cancel through the returned timer)."""

    # ---- replies and output -------------------------------------------------------------------

    def ack(self) -> Reply: ...

    def base_handler(self, key: str) -> Handler:
        """The base controller's handler of command `key`, for a module that extends a base command
        (CRISP's letters of `EXTRA`, its `/` in OUT0 mode 11)."""

    def render(self, key: str, shape: Shape | None = None) -> Rendered:
        """How to print a reply of command `key` (its query shape after the profile's overrides)."""

    def where(self, units: float) -> str:
        """A position as `W` prints it (current `VB Z` decimals)."""

    def unsolicited(self, text: str, t: float) -> None:
        """Send a line nobody asked for, with the current terminator (MS-18)."""

    def send_raw(self, data: bytes, t: float, to: str | None = None, channel: str = ...) -> None:
        """Send bytes at `t` on a channel (`main` by default; TTL REPORT's `aux`, MS-TTLREP-1),
        unsolicited when `to` is None."""

    def log_error(self, code: int) -> None: ...

    def finish_pending(self, t: float) -> None:
        """The operation of a module's `Pending` without a due time has ended: its reply goes now
        (an autofocus run, MS-33)."""

    def push_event(self, event: dict[str, Any]) -> None:
        """A control-channel event (`{"ev": name, ...}`)."""

    @property
    def explain(self) -> bool:
        """A traffic log is kept: only then does a module build its log-only events (per-update
        samples, emulator/hosting/trafficlog.py `LOG_ONLY`), so without a log they cost nothing."""

    # ---- motion -------------------------------------------------------------------------------

    def axis_named(self, letter: str) -> Axis | None: ...

    def focus_axis(self) -> Axis | None: ...

    def relative_goal(self, axis: Axis, delta_mm: float, t: float) -> float:
        """The machine count an `R` of `delta_mm` would go to (MS-45, MS-51)."""

    def start_moves(self, goals: list[tuple[Axis, float]], t: float, activity: Activity = ...) -> None:
        """A commanded move of several axes to machine counts, completing together (MS-51)."""

    def start_scan_move(self, axis: Axis, goal: float, t: float, speed_mm_s: float | None = None) -> None:
        """A SCAN leg (MS-SCAN-4): one axis to machine count `goal` in a single leg at `speed_mm_s`
        (default its `S`), without backlash or overshoot legs or the OUT0 pulse of a commanded
        move; busy with right status character `B`, and completes like a commanded move."""

    def halt_all(self, t: float) -> bool:
        """HALT (MS-76): stop every motion and module activity; True if a commanded move ran.
        SEQUENCER's `ARM Z` and its `@` stop halt the stage this way (MS-SEQ-6, MS-SEQ-7)."""

    def positions_changed(self) -> None:
        """An axis origin moved (SI sets a position): positions are due a save (MS-111)."""

    def limits_changed(self) -> None:
        """Soft limits (SI resets them) or a module's remembered limits (`save_auto`: DLED maxima)
        changed: they are remembered at once (MS-65, MS-111)."""

    # ---- TTL ----------------------------------------------------------------------------------

    def in0_function(self, mode: int, t: float) -> None:
        """Do what an IN0 rising edge does in `mode` (MS-90)."""

    def refresh_out0(self, t: float) -> None:
        """Re-read OUT0's level after a module changed what it drives (MS-91)."""

    def toggle_out0(self, t: float) -> None: ...

    def report_axes(self) -> list[Axis]:
        """The axes IN0 mode 5 reports: a module's selection (`ReportAxes`) or all."""

    # ---- the other modules (events.py, capabilities.py) ----------------------------------------

    def emit(self, event: Event) -> None:
        """Offer `event` to the modules subscribed to its class, in profile order."""

    def module(self, kind: type[T]) -> T | None:
        """The module with capability `kind` (the one that owns the value), if the profile has one."""

    def modules_of(self, kind: type[T]) -> tuple[T, ...]:
        """Every module with capability `kind`, in profile order."""
