"""CRISP (also built as CRIFF): continuous focus lock on the focus axis (§9.5, MS-CRISP-1…MS-CRISP-9).

A state machine (crisp_states.py) driven by `LK`, the `@` button, IN0 mode 9 and its own timed
routines (crisp_routines.py), reading a simulated reflection (crisp_optics.py) and settings
(crisp_settings.py). While the lock is engaged (`K`, `F`, `N`) a loop runs every `UL Y` ms: it
re-evaluates the state (MS-CRISP-2) and, in `K` and `F`, moves the focus axis towards the surface by
(e/G) × min(1, `LR T`/10) µm through the motion model, less what its earlier steps still have to
travel, so the lock converges without overshoot and follows drift. Those steps are the non-busy
relative moves the wheel makes: the host sees `/` = `N` and the axis position follow the surface.

- `K`→`F` inside the in-focus window (`AL Z` × 1000 × G counts), `F`→`K` outside it; `E` when the
  axis has gone more than `LR Z` from where the lock began or the sum is below the dim threshold;
  `N` while a commanded move of the focus axis runs, `K` again when it ends (a directly commanded
  `N`, `LK F=78`, stays). Queries see the state as of the instant they are asked.
- HALT ends a calibration (state `R`), a focus curve or an offset reset (the previous state), and
  leaves an engaged lock alone: hosts halt the XY stage while focus stays locked [choice].
- The wheel, while the lock is engaged, changes `LK Z` by counts × `UL Z` instead of moving the axis.
- `@`: a normal press advances like bare `LK`; held more than 10 s it resets the offset [choice];
  `BE F=11` advances, `BE F=12` resets the offset (Appendix B).
- OUT0 mode 12 is high exactly in `F`; mode 11 pulses `RT Y` ms once the lock is in `F` after each
  commanded move completed with the lock engaged, and `/` answers `B` while that pulse waits
  (MS-CRISP-7). A move that completes with the lock not engaged, or a release of the lock, drops it.
- Beside TRACKING, CRISP keeps `LK`, `LR`, `UL` (§9.0); `AL` is shared with AUTOFOCUS as the profile
  orders them. `EXTRA M` stays the base command.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar

from emulator.device import CRISP_SAMPLE
from emulator.devices.ms2000.buttons import NORMAL
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules import crisp_states as st
from emulator.devices.ms2000.modules.capabilities import (
    CatchUp,
    ControlChannel,
    FocusAxisSelect,
    FocusWheel,
    LcdSegment,
    PanelButtons,
    TtlIn,
    TtlOut,
)
from emulator.devices.ms2000.modules.crisp_commands import CrispCommands
from emulator.devices.ms2000.modules.crisp_optics import Optics
from emulator.devices.ms2000.modules.crisp_routines import Routines
from emulator.devices.ms2000.modules.crisp_settings import (
    OFFSET_LIMIT,
    CrispSettings,
)
from emulator.devices.ms2000.modules.events import Halt, MoveComplete, Out0ModeChanged, Reset, on
from emulator.profiles.schema import Choice, Field, Float
from protocols.ms2000 import Shape

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

LOCK_MODE = 9  # IN0 (MS-90)
PULSE_MODE, IN_FOCUS_MODE = 11, 12  # OUT0 (MS-91)
FN_ADVANCE, FN_RESET_OFFSET = 11, 12  # BE F (Appendix B)
#: `@` held longer than this resets the offset (MS-85: CRISP's own press class)
OFFSET_PRESS_MS = 10_000.0
#: the event pushed on each state change (docs/ms2000.md §12)
FOCUS_EVENT = "crisp"


@register
class Crisp(
    Module, FocusAxisSelect, FocusWheel, CatchUp, TtlIn, TtlOut, PanelButtons, LcdSegment, ControlChannel
):
    name = "CRISP"
    knob_fields = (
        Field("crisp_directive_name", Choice(("CRISP", "CRIFF")), "CRISP", "MS-102", "CRISP's `BU X` line"),
        Field(
            "crisp_counts_per_um",
            Float(0, 10000, exclusive_minimum=True),
            100,
            "MS-CRISP-6",
            "CRISP focus-error counts per µm of defocus (G)",
        ),
        Field(
            "crisp_dim_threshold", Float(0, 1e6), 100, "MS-CRISP-2", "CRISP sum signal below which it is dim"
        ),
    )
    query_shapes: ClassVar[Mapping[str, Shape]] = MappingProxyType({"LK": Shape.A_LIST})
    in0_modes = frozenset({LOCK_MODE})
    out0_modes = frozenset({PULSE_MODE, IN_FOCUS_MODE})
    button_priority = 20  # MS-85: after SEQUENCER, before SCAN
    observable = "crisp"
    inputs = frozenset({"crisp"})
    outranks = frozenset({"TRACKING"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.state = st.IDLE
        self.settings = CrispSettings.restored(None, len(controller.axes))
        #: `UL F` takes effect at reset (MS-CRISP-5)
        self.active_index = self.settings.focus_index
        self.optics = Optics()
        self.routines = Routines(self)
        self._tick: Timer | None = None
        self._lock_start_mm = 0.0
        self._inhibited_by_move = False
        self._pulse_waiting = False
        self._pulse: Timer | None = None

    # ---- the signal (MS-CRISP-6) --------------------------------------------------------------

    def focus_index(self) -> int | None:
        return self.active_index

    def _axis(self) -> Axis | None:
        return self.controller.focus_axis()

    @property
    def gain(self) -> float:
        return float(self.controller.knobs.crisp_counts_per_um)

    def dim(self) -> bool:
        return self.optics.sum < self.controller.knobs.crisp_dim_threshold

    def signal_sum(self) -> int:
        """0 with the LED off (`I`), else the sum input."""
        return 0 if self.state == st.IDLE else round(self.optics.sum)

    def error(self, now: float) -> int:
        axis = self._axis()
        if self.state == st.IDLE or axis is None:
            return 0
        return self.optics.error(axis, self.settings.offset, self.gain, now)

    def snr(self) -> float:
        return 0.0 if self.state == st.IDLE else self.optics.snr

    def focus_um(self, now: float) -> float:
        axis = self._axis()
        return 0.0 if axis is None else axis.user_mm_of(axis.physical(now)) * 1000

    def focus_units(self, now: float) -> float:
        axis = self._axis()
        return 0.0 if axis is None else self.focus_um(now) / 1000 * axis.s.unit_multiplier

    def move_focus_to(self, user_um: float, now: float) -> None:
        """Send the focus axis to a physical place in user µm, by a non-busy relative move."""
        axis = self._axis()
        if axis is None:
            return
        follow = axis.physical(now) - axis.pos(now)
        base = axis.wheel_goal if axis.wheel_goal is not None else axis.pos(now)
        axis.nudge(now, axis.counts_of(user_um / 1000) - follow - base)

    def extra_line(self, now: float) -> str:
        """`EXTRA X?` and the LCD segment (MS-CRISP-4, MS-CRISP-9)."""
        return f"{self.state}{self.signal_sum():5d}{self.error(now):5d} "

    # ---- states -------------------------------------------------------------------------------

    def enter(self, state: str, now: float) -> None:
        old, self.state = self.state, state
        if state in st.ENGAGED:
            if self._tick is None:
                self._tick = self.controller.at(now + self.settings.update_ms / 1000, self._on_tick)
        else:
            if self._tick is not None:
                self._tick.cancel()
                self._tick = None
            self._inhibited_by_move = False
            self._pulse_waiting = False
        if state == st.IN_FOCUS and self._pulse_waiting:
            self._fire_pulse(now)
        if old != state:
            self.controller.refresh_out0(now)
            self._push_state(old, now)

    def engage(self, state: str, now: float) -> None:
        """Lock here: the lock range counts from the focus axis's place now."""
        self._lock_start_mm = self.focus_um(now) / 1000
        self._inhibited_by_move = False
        self.enter(state, now)
        self.sync(now)

    def resume(self, previous: str, now: float) -> None:
        """Back to the state before a routine: an engaged lock re-engages in `K`, keeping its start."""
        if previous in st.ROUTINES:
            previous = st.READY
        self.enter(st.LOCK if previous in st.ENGAGED else previous, now)
        self.sync(now)

    def catch_up(self, now: float) -> None:
        self.sync(now)

    def sync(self, now: float) -> None:
        """The lock's transitions as of `now` (MS-CRISP-2)."""
        axis = self._axis()
        if self.state not in st.ENGAGED or axis is None:
            return
        if axis.busy(now):
            if self.state != st.INHIBITED:
                self._inhibited_by_move = True
                self.enter(st.INHIBITED, now)
            return
        if self.state == st.INHIBITED:
            if not self._inhibited_by_move:
                return
            self._inhibited_by_move = False
            self.enter(st.LOCK, now)
        if self.dim() or abs(self.focus_um(now) / 1000 - self._lock_start_mm) > self.settings.lock_range_mm:
            self.enter(st.ERROR, now)
            return
        window = self.settings.in_focus_mm * 1000 * self.gain
        off = abs(self.error(now)) > window
        if self.state == st.LOCK and not off:
            self.enter(st.IN_FOCUS, now)
        elif self.state == st.IN_FOCUS and off:
            self.enter(st.LOCK, now)

    def _on_tick(self, now: float) -> None:
        self._tick = None
        self.sync(now)
        if self.controller.explain:
            self._push_sample(now)
        if self.state in (st.LOCK, st.IN_FOCUS):
            self._correct(now)
        if self.state in st.ENGAGED and self._tick is None:
            self._tick = self.controller.at(now + self.settings.update_ms / 1000, self._on_tick)

    def _correct(self, now: float) -> None:
        axis = self._axis()
        if axis is None:
            return
        to_go = 0.0 if axis.wheel_goal is None else axis.wheel_goal - axis.pos(now)
        to_go_um = axis.s.polarity * to_go / axis.counts_per_mm * 1000
        step_um = (self.error(now) / self.gain - to_go_um) * min(1.0, self.settings.loop_gain / 10)
        if step_um:
            axis.nudge(now, axis.s.polarity * step_um / 1000 * axis.counts_per_mm)

    def _push_state(self, previous: str, now: float) -> None:
        """A `crisp` event per state change: few enough for control-channel subscribers too."""
        axis = self._axis()
        event: dict[str, Any] = {"ev": FOCUS_EVENT, "t": now, "previous": previous}
        event["axis"] = None if axis is None else axis.letter
        event["in_focus_counts"] = round(self.settings.in_focus_mm * 1000 * self.gain, 4)
        self.controller.push_event(event | self._reading(now))

    def _push_sample(self, now: float) -> None:
        """The error the lock loop acts on, per update: for the traffic log only (`LOG_ONLY`)."""
        surface_um = self.optics.describe(self._axis(), now)["surface_um"]
        sample = {"ev": CRISP_SAMPLE, "t": now, "error": self.error(now), "surface_um": round(surface_um, 4)}
        self.controller.push_event(sample)

    def advance(self, now: float) -> None:
        """Bare `LK`, a normal `@` press, `BE F=11`: the panel button's cycle (MS-CRISP-2)."""
        state = self.state
        if state in st.ROUTINES:
            return
        if state in (st.IDLE, st.DIM):
            self.enter(st.DIM if self.dim() else st.READY, now)
        elif state == st.READY:
            self.engage(st.LOCK, now)
        elif state == st.LOGAMP_DONE:
            self.enter(st.DITHER, now)
        elif state == st.DITHER:
            self.routines.gain(now)
        else:
            self.enter(st.READY, now)

    def apply_code(self, code: int, now: float) -> None:
        """`LK F=code` (MS-CRISP-3): graceful codes start their action, state characters are entered."""
        previous = self.state
        self.routines.stop(now)
        if code == st.TO_IDLE:
            self.enter(st.IDLE, now)
        elif code == st.TO_UNLOCK:
            self.enter(st.READY, now)
        elif code == st.TO_LOCK:
            self.engage(st.LOCK, now)
        elif code == st.TO_LOGAMP_CAL:
            self.routines.logamp(now)
        elif code == st.TO_GAIN_CAL:
            self.routines.gain(now)
        elif code == st.TO_DITHER:
            self.enter(st.DITHER, now)
        elif code == st.TO_OFFSET_RESET:
            self.routines.offset_reset(previous, now)
        elif code == st.TO_CURVE:
            self.routines.focus_curve(previous, now)
        elif chr(code) in st.ENGAGED:
            self.engage(chr(code), now)
        else:
            self.enter(chr(code), now)

    def reset_offset(self, now: float) -> None:
        self.apply_code(st.TO_OFFSET_RESET, now)

    def move_pulse_waiting(self) -> bool:
        """OUT0 mode 11: a move's pulse waits for `F`, and `/` answers `B` (MS-CRISP-7)."""
        return self._pulse_waiting and self.controller.card.ttl_out == PULSE_MODE

    # ---- commands -----------------------------------------------------------------------------

    def handlers(self) -> dict[str, Handler]:
        return CrispCommands(self).table()

    # ---- TTL (MS-CRISP-7) ---------------------------------------------------------------------

    def in0_trigger(self, mode: int, now: float) -> None:
        if self.state == st.READY:
            self.engage(st.LOCK, now)

    def in0_release(self, mode: int, now: float) -> None:
        if self.state in st.ENGAGED:
            self.enter(st.READY, now)

    @on(Out0ModeChanged)
    def out0_mode_changed(self, event: Out0ModeChanged) -> None:
        self._pulse_waiting = False
        self._end_pulse(event.t)

    def out0_level(self) -> int | None:
        if self.controller.card.ttl_out == IN_FOCUS_MODE:
            return int(self.state == st.IN_FOCUS)
        return int(self._pulse is not None)

    @on(MoveComplete)
    def move_complete(self, event: MoveComplete) -> None:
        now = event.t
        self.sync(now)
        if self.controller.card.ttl_out != PULSE_MODE or self.state not in st.ENGAGED:
            return
        if self.state == st.IN_FOCUS:
            self._fire_pulse(now)
        else:
            self._pulse_waiting = True

    def _fire_pulse(self, now: float) -> None:
        self._pulse_waiting = False
        if self._pulse is not None:
            self._pulse.cancel()
        self._pulse = self.controller.at(now + self.controller.card.rt_pulse_ms / 1000, self._end_pulse)
        self.controller.refresh_out0(now)

    def _end_pulse(self, now: float) -> None:
        if self._pulse is not None:
            self._pulse.cancel()
            self._pulse = None
            self.controller.refresh_out0(now)

    # ---- buttons and the wheel ----------------------------------------------------------------

    def button(self, name: str, press: str, now: float) -> bool:
        if name != "at":
            return False
        if self.controller.button_held_ms > OFFSET_PRESS_MS:
            self.reset_offset(now)
            return True
        if press == NORMAL:
            self.advance(now)
            return True
        return False

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {FN_ADVANCE: self.advance, FN_RESET_OFFSET: self.reset_offset}

    def wheel(self, counts: float, now: float) -> bool:
        """While locked the wheel moves the lock point: `LK Z` += counts × `UL Z` (MS-CRISP-6)."""
        if self.state not in st.ENGAGED:
            return False
        offset = round(self.settings.offset + counts * self.settings.knob_speed)
        self.settings.offset = max(-OFFSET_LIMIT, min(OFFSET_LIMIT, offset))
        self.sync(now)
        return True

    # ---- reports, control channel, SS Z, reset, HALT -------------------------------------------

    def bu_line(self) -> str:
        return str(self.controller.knobs.crisp_directive_name)  # MS-102

    def lcd_segment(self, now: float) -> str | None:
        self.sync(now)
        return self.extra_line(now).rstrip()

    def observe(self, now: float) -> Any:
        self.sync(now)
        return self._reading(now)

    def _reading(self, now: float) -> dict[str, Any]:
        return {
            "state": self.state,
            "error": self.error(now),
            "offset": self.settings.offset,
            "sum": self.signal_sum(),
            "snr": self.snr(),
            "surface_um": self.optics.describe(self._axis(), now)["surface_um"],
        }

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        result = self.optics.apply(params, self._axis(), now)
        self.sync(now)
        return result

    def save(self) -> dict[str, Any]:
        return self.settings.save()

    def restore(self, data: dict[str, Any] | None) -> None:
        self.settings = CrispSettings.restored(data, len(self.controller.axes))

    @on(Reset)
    def reset(self, event: Reset) -> None:
        now = event.t
        self.routines.stop(now, quiet=True)
        self.active_index = self.settings.focus_index
        self._pulse_waiting = False
        self._end_pulse(now)
        self.enter(st.IDLE, now)

    @on(Halt)
    def halt(self, event: Halt) -> None:
        now = event.t
        if self.state in st.ROUTINES:
            self.resume(self.routines.stop(now), now)
