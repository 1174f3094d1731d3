"""What a module may have beyond what every module has (modules/__init__.py): one plain class per
capability, which the module also derives from. The controller asks a capability only of the
modules that have it (`ModuleSet.all_of`, `ModuleSet.get`); a value one module owns and others read
(the report mask, the playback mode, the focus score) is a query of that module by capability
(`controller.module(Playback)`), not a question put to every module. The base code and other modules thus
name the capability, never the module that has it. Defaults that do nothing are given where a module
may have the capability without each part (an OUT0 mode the base drives, PREPULSE); the rest raise
`NotImplementedError`. (mypy accepts only concrete classes as a query's type, hence no ABCs.)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, ClassVar

if TYPE_CHECKING:
    from emulator.devices.ms2000.calls import Call, Param


class ReportAxes:
    """Selects the axes IN0 mode 5 reports (RING BUFFER's `RM Y`, MS-RB-4)."""

    def report_mask(self) -> int:
        """Bit 0 = first motor axis."""
        raise NotImplementedError


class ReportFields:
    """Appends fields to each IN0 mode 5 report line (TRACKING's PMT sum, MS-TRACK-3)."""

    def report_fields(self, now: float) -> list[str]:
        raise NotImplementedError


class Playback:
    """Keeps the ring-buffer playback mode (RING BUFFER's `RM F`, 1–3, MS-RB-4), which ARRAY
    follows (MS-ARRAY-5)."""

    def playback_mode(self) -> int:
        raise NotImplementedError


class RmXServer:
    """Serves `RM X=` values besides 0 (clear), through the `RmX` event (ARRAY's 1, MS-ARRAY-6)."""

    rm_x_values: ClassVar[frozenset[int]]


class FocusScore:
    """Measures the video focus score `RA Z` reads (AUTOFOCUS, MS-117)."""

    def focus_score(self, now: float) -> int | None:
        """None without a focus axis."""
        raise NotImplementedError


class FocusAxisSelect:
    """Selects the focus axis (CRISP's `UL F`)."""

    def focus_index(self) -> int | None:
        """The hardware index of the focus axis."""
        raise NotImplementedError


class FocusWheel:
    """Offered the focus wheel before the axis (CRISP's lock offset, MS-CRISP-6)."""

    def wheel(self, counts: float, now: float) -> bool:
        """True when the module takes the turn instead of the axis."""
        raise NotImplementedError


class CatchUp:
    """Brings state that follows from time and motion up to `now` at the end of every model step
    (CRISP's lock entering `N` as a focus move starts, MS-CRISP-2), so OUT0 and every observer see
    it as of the same instant. Only modules with this capability cost anything per step."""

    def catch_up(self, now: float) -> None:
        raise NotImplementedError


class LcdLine:
    """Takes LCD line 2 alone, before the uptime, the other modules' segments left out (SEQUENCER,
    §9.0)."""

    def lcd_line(self, now: float, states: Mapping[str, str]) -> str | None:
        """The line (None: the segments show); `states`: each module's `state_char()` by name."""
        raise NotImplementedError


class ExtraParams:
    """Adds letters to base settings commands (NO CHANGE SETTINGS: `VB T`, MS-109)."""

    def extra_params(self, key: str) -> dict[str, Param]:
        raise NotImplementedError


class CommandVeto:
    """Vetoes commands before they run (NO CHANGE SETTINGS' write protection, MS-109)."""

    def refuse(self, call: Call) -> int | None:
        """An error code to answer instead of running `call` (None: run it)."""
        raise NotImplementedError


class AutoSettings:
    """Settings remembered as soon as they change (DLED maxima, MS-111), under
    `auto.modules.<name>`; the module calls `controller.limits_changed()` when they change."""

    def save_auto(self) -> dict[str, Any]:
        raise NotImplementedError

    def restore_auto(self, data: dict[str, Any] | None) -> None:
        """The remembered settings at power-up and reset (None: factory)."""
        raise NotImplementedError


class TtlIn:
    """Serves IN0 modes (`TTL X=`, MS-90): the first module declaring a mode serves it."""

    in0_modes: ClassVar[frozenset[int]]

    def in0_trigger(self, mode: int, now: float) -> None:
        """An IN0 rising edge (or a bare `RM`, MS-RB-5) in one of `in0_modes`."""

    def in0_release(self, mode: int, now: float) -> None:
        """An IN0 falling edge in one of `in0_modes` (CRISP's level-driven mode 9, MS-CRISP-7)."""


class In0Interrupt:
    """The IN0 interrupt service that every IN0 mode but 0 needs (INO_INT, ENC_INT; MS-90)."""


class TtlOut:
    """Serves OUT0 modes (`TTL Y=`, MS-91): the first module declaring a mode serves it."""

    out0_modes: ClassVar[frozenset[int]]

    def out0_level(self) -> int | None:
        """OUT0's level in one of `out0_modes` (None: the base drives it, as for PREPULSE)."""
        return None

    def out0_pwm(self) -> float | None:
        """OUT0's duty cycle in percent, for a mode that dims (None: on or off)."""
        return None


class PanelButtons:
    """Claims front-panel presses (MS-85) and implements `BE F` functions (MS-86)."""

    #: lower claims first (MS-85: SEQUENCER, CRISP, SCAN, ARRAY, AUTOFOCUS, PLANAR, RING BUFFER)
    button_priority: ClassVar[int] = 100

    def button(self, name: str, press: str, now: float) -> bool:
        """A released front-panel button; True when the module claims it."""
        return False

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {}


class LcdSegment:
    """Shows a segment on LCD line 2 (DIP 2 up) and may show its state as one character in another
    module's segment (SEQUENCER's, MS-SEQ-8)."""

    def lcd_segment(self, now: float) -> str | None:
        return None

    def state_char(self) -> str | None:
        """PLANAR CORRECTION's and ARRAY's state, for SEQUENCER's line."""
        return None


class ControlChannel:
    """Adds control-channel vocabulary: observables (`observable` read by `observe()`; a module
    publishing more names, TRACER, extends `observables()`) and inputs."""

    observable: ClassVar[str | None] = None
    inputs: ClassVar[frozenset[str]] = frozenset()

    def observe(self, now: float) -> Any:
        return None

    def observables(self) -> dict[str, Callable[[float], Any]]:
        return {self.observable: self.observe} if self.observable else {}

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """One of `inputs` (asked only for those)."""
        raise NotImplementedError
