"""Power-up, software reset and non-volatile memory of the controller (MS-110…MS-113).

Factory values come from the profile; `SS Z` settings, auto-saved settings and positions live in the
device's flash (flash.py), a store the host hands in. Positions are saved whenever the stage comes
to rest (an axis reports each rest, commands that move the origin report theirs), checked once at the
end of the model call that caused it: a command that moves nothing costs nothing here.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from emulator.device import ControlError, DeviceServices
from emulator.devices.ms2000.activity import LOWER, UPPER
from emulator.devices.ms2000.calls import Pending, Reply
from emulator.devices.ms2000.flash import Flash
from emulator.devices.ms2000.modules.events import Reset
from emulator.devices.ms2000.sections import baud_of
from emulator.devices.ms2000.settings import (
    AxisAuto,
    AxisSettings,
    CardAuto,
    CardSettings,
    from_plain,
    to_plain,
)
from emulator.profiles.schema import finite_number
from emulator.storage.nvstore import StorageError
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.buttons import Buttons
    from emulator.devices.ms2000.interpreter import Interpreter
    from emulator.devices.ms2000.lowlevel import LowLevel
    from emulator.devices.ms2000.modules.moduleset import ModuleSet
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.schema import Ms2000Config
    from emulator.devices.ms2000.sections import Ms2000Knobs
    from emulator.devices.ms2000.ttl import Ttl

CLOCK_MARK_S = 600.0
#: positions are saved once the stage has rested this long (device seconds): a host moving in
#: a loop then costs no disk write per move, and a kill -9 loses at most this much rest
POSITION_SAVE_DELAY_S = 0.05
CLOCK_MARK_CODE = 255
IDENTITY_MISMATCH_CODE = 55
#: characters of a rejected stored value's repr shown in its warning
REPR_LIMIT = 40


class PowerOwner(Protocol):
    """All power, reset and flash use of their controller: the parts they bring back to idle, and the
    controller state they restore or clear (the attributes)."""

    baud: int
    card: CardSettings
    card_auto: CardAuto
    ensync_level: int
    user_counter: int
    lcd_text: str | None
    last_relative: list[tuple[str, float | None]]
    booted_at: float
    storage_error: str | None

    @property
    def name(self) -> str: ...

    @property
    def now(self) -> float: ...

    @property
    def log(self) -> logging.Logger: ...

    @property
    def services(self) -> DeviceServices:
        """The flash store."""

    @property
    def cfg(self) -> Ms2000Config: ...

    @property
    def knobs(self) -> Ms2000Knobs: ...

    @property
    def dip(self) -> dict[str, str]: ...

    @property
    def axes(self) -> Sequence[Axis]: ...

    @property
    def modules(self) -> ModuleSet: ...

    @property
    def interpreter(self) -> Interpreter: ...

    @property
    def ttl(self) -> Ttl: ...

    @property
    def low(self) -> LowLevel: ...

    @property
    def buttons(self) -> Buttons: ...

    @property
    def error_log(self) -> deque[int]: ...

    @property
    def trajectory_log(self) -> deque[str]: ...

    def at(self, due: float, action: Callable[[float], None]) -> Timer: ...

    def ack(self) -> Reply: ...

    def log_error(self, code: int) -> None: ...

    def push_event(self, event: dict[str, Any]) -> None: ...


class Power:
    """The controller's power states and its flash; works on the controller's axes and settings."""

    def __init__(self, controller: PowerOwner) -> None:
        self.controller = controller
        cfg = controller.cfg
        identity = {"build": cfg.build_name, "version": cfg.version, "axes": list(cfg.motor_axes)}
        self.flash = Flash(controller.services, cfg.device_id, identity, self.storage_result)
        #: positions may differ from the flash's: checked at the end of the current model call
        self.positions_dirty = False
        self._saved_positions: tuple[int, ...] | None = None
        self._clock_timer: Timer | None = None
        #: the pending check that saves positions at rest, and when they last changed
        self._position_timer: Timer | None = None
        self._flagged_at = 0.0
        #: an `SS` waits for the store to settle: only then does a settled store release a reply
        self._ack_waits = False

    # ---- factory values -----------------------------------------------------------------------

    def factory_axis(self, letter: str) -> AxisSettings:
        a = self.controller.cfg.axes[letter]
        return AxisSettings(
            speed=a.speed_mm_s,
            accel_ms=a.accel_ms,
            wait_ms=a.wait_ms,
            backlash=a.backlash_mm,
            overshoot_counts=int(a.overshoot_mm * a.counts_per_mm),
            drift_error=a.drift_error_mm,
            finish_error=a.finish_error_mm,
            maintain=a.maintain,
            runaway=a.runaway_mm,
            kp=a.kp,
            ki=a.ki,
            kd=a.kd,
            kv=a.kv,
            ka=a.ka,
            dac=a.dac_mm_s,
            counts_per_mm=a.counts_per_mm,
            polarity=1,
            unit_multiplier=a.unit_multiplier,
            input_device=a.input_device,
            manual_enabled=True,
            ll_id=a.ll_id,
            rename=None,
        )

    def factory_auto(self, letter: str) -> AxisAuto:
        a = self.controller.cfg.axes[letter]
        return AxisAuto(a.soft_lower_mm, a.soft_upper_mm, a.home_mm, a.aa)

    def factory_card(self) -> CardSettings:
        return CardSettings(stop_bits=int(self.controller.cfg.line.stop_bits))

    # ---- power-up and reset (MS-112) ----------------------------------------------------------

    def power_up(self, t: float, cold: bool) -> None:
        controller = self.controller
        flash = self.flash
        same = flash.load()
        if flash.pending_factory:
            flash.data.pop("saved", None)
            flash.write(pending_factory=False)
        controller.baud = baud_of(controller.dip["sw4"], controller.dip["sw5"])
        if cold:
            physical = self._section(flash.data, "physical") or {}
            for axis in controller.axes:
                counts = self._number(physical, axis.hw_letter, "physical")
                if counts is not None:
                    axis.traj = axis.traj.rest(t, counts)
        self._restore_settings()
        positions = self._section(flash.data, "positions") or {}  # null after SP X=1
        for axis in controller.axes:
            saved = self._number(positions, axis.hw_letter, "positions")
            axis.origin = 0.0
            here = axis.user_mm(t)
            axis.origin = here - saved if saved is not None else here
        self._restart(t)
        if not same:
            controller.log_error(IDENTITY_MISMATCH_CODE)

    def _restore_settings(self) -> None:
        controller = self.controller
        saved = self._section(self.flash.data, "saved") or {}
        auto = self._section(self.flash.data, "auto") or {}
        saved_axes = self._section(saved, "axes", "saved") or {}
        auto_axes = self._section(auto, "axes", "auto") or {}
        reject = self._unusable
        for axis in controller.axes:
            letter = axis.hw_letter
            axis.s = from_plain(
                self.factory_axis(letter), saved_axes.get(letter), f"saved.axes.{letter}", reject
            )
            axis.auto = from_plain(
                self.factory_auto(letter), auto_axes.get(letter), f"auto.axes.{letter}", reject
            )
            axis.letter = chr(axis.s.rename) if axis.s.rename else letter
        controller.card = from_plain(self.factory_card(), saved.get("card"), "saved.card", reject)
        controller.card_auto = from_plain(CardAuto(), auto.get("card"), "auto.card", reject)
        controller.modules.restore(self._section(saved, "modules", "saved") or {}, reject)
        controller.modules.restore_auto(self._section(auto, "modules", "auto") or {}, reject)

    def _section(self, mapping: dict[str, Any], key: str, within: str = "") -> dict[str, Any] | None:
        """The stored mapping `mapping[key]`; None when absent or (reported) not a mapping."""
        value = mapping.get(key)
        if value is None or isinstance(value, dict):
            return value
        self._unusable(f"{within}.{key}" if within else key, value)
        return None

    def _number(self, mapping: dict[str, Any], key: str, within: str) -> float | None:
        """The stored finite number `mapping[key]`; None when absent or (reported) anything else."""
        if key not in mapping:
            return None
        value = mapping[key]
        if finite_number(value):
            return float(value)
        self._unusable(f"{within}.{key}", value)
        return None

    def _unusable(self, path: str, value: Any) -> None:
        """A stored value the model cannot use keeps its factory value, silently for the host as
        on a real controller, but said in the log: once per key per load (not again at `~`)."""
        if path in self.flash.reported:
            return
        self.flash.reported.add(path)
        text = repr(value)
        if len(text) > REPR_LIMIT:
            text = text[: REPR_LIMIT - 3] + "..."
        self.controller.log.warning(
            "%s: stored %s = %s cannot be used; keeping the factory value", self.controller.name, path, text
        )

    def _restart(self, t: float) -> None:
        """What power-up and reset share: motion stopped, volatile state cleared, clocks restarted."""
        controller = self.controller
        for axis in controller.axes:
            axis.power_off(t)
            axis.enabled = True
            axis.group = None
            axis.switch = {UPPER: False, LOWER: False}
            axis.target = round_half_away(axis.pos(t))
            axis.reset_extremes(t)
            axis.ensync_mm = None
        controller.ensync_level = 0
        controller.error_log.clear()
        controller.trajectory_log.clear()
        controller.user_counter = 0
        controller.lcd_text = None
        controller.interpreter.restart()
        controller.last_relative = []
        controller.buttons.reset()
        controller.low.reset()
        controller.booted_at = t
        if self._clock_timer is not None:
            self._clock_timer.cancel()
        self._clock_timer = controller.at(t + CLOCK_MARK_S, self._clock_mark)
        controller.modules.emit(Reset(t))
        controller.ttl.reset(t)
        # what the flash holds counts as saved: a reset alone writes nothing (MS-112)
        self._saved_positions = self._position_key()
        self.positions_dirty = False

    def _clock_mark(self, t: float) -> None:
        if self.controller.knobs.error_log_clock_marks:
            self.controller.log_error(CLOCK_MARK_CODE)
        self._clock_timer = self.controller.at(t + CLOCK_MARK_S, self._clock_mark)

    def software_reset(self, t: float) -> None:
        """`~` and 0xFF 'R' (MS-112): saved settings back, positions 0, limits keep their place."""
        controller = self.controller
        controller.interpreter.cancel_pending(t, reply=False)
        for axis in controller.axes:
            axis.stop(t)
        self._restore_settings()
        for axis in controller.axes:
            axis.origin = 0.0
            axis.origin = axis.user_mm(t)
        self._restart(t)
        # lines that waited behind a blocking command the reset cancelled still run, in order (MS-13)
        controller.interpreter.drain(t)

    def power_cycle(self, t: float) -> None:
        """Power off (positions saved unless `SP X=1`) and on (MS-112)."""
        controller = self.controller
        controller.interpreter.cancel_pending(t, reply=False)
        controller.interpreter.power_off()
        for axis in controller.axes:
            axis.stop(t)
        self.save_positions(t)
        self.power_up(t, cold=False)

    # ---- non-volatile memory (MS-110, MS-111) -------------------------------------------------

    def _position_key(self) -> tuple[int, ...]:
        t = self.controller.now
        axes = self.controller.axes
        return (
            self.controller.card.inhibit_position_save,
            *(round_half_away(a.units(t) * 1000) for a in axes),
        )

    def save_positions(self, t: float) -> None:
        axes = self.controller.axes
        physical = {a.hw_letter: a.pos(t) for a in axes}
        inhibit = self.controller.card.inhibit_position_save
        positions = None if inhibit else {a.hw_letter: a.user_mm(t) for a in axes}
        self.flash.write(physical=physical, positions=positions)
        self._saved_positions = self._position_key()

    def persist_idle_positions(self, t: float) -> None:
        """With a persistent store, positions are written once the stage has rested for
        `POSITION_SAVE_DELAY_S`, so an emulator killed without a power-off still restarts where it
        was (MS-111). Called at the end of a model call that flagged `positions_dirty`; while
        something moves, the rest to come flags it again. One timer serves a burst of moves."""
        self.positions_dirty = False
        if not self.flash.persistent:
            return
        self._flagged_at = t
        if self._position_timer is None:
            self._position_timer = self.controller.at(t + POSITION_SAVE_DELAY_S, self._save_if_rested)

    def save_resting_positions(self, t: float) -> None:
        """At shutdown: what the waiting check would save, saved now (a moving stage is not)."""
        if self._position_timer is not None:
            self._position_timer.cancel()
            self._position_timer = None
            self._save_at_rest(t)

    def _save_if_rested(self, t: float) -> None:
        self._position_timer = None
        rested_until = self._flagged_at + POSITION_SAVE_DELAY_S
        if t < rested_until and not self._moving(t):
            self._position_timer = self.controller.at(rested_until, self._save_if_rested)
        else:
            self._save_at_rest(t)

    def _save_at_rest(self, t: float) -> None:
        # while something moves, the rest to come flags the positions again
        if not self._moving(t) and self._position_key() != self._saved_positions:
            self.save_positions(t)

    def _moving(self, t: float) -> bool:
        return any(a.traj.moving(t) for a in self.controller.axes)

    def save_settings(self) -> None:
        """SS Z (MS-110, MS-111)."""
        controller = self.controller
        saved = {
            "axes": {a.hw_letter: to_plain(a.s) for a in controller.axes},
            "card": to_plain(controller.card),
            "modules": controller.modules.save(),
        }
        self.flash.write(saved=saved)

    def schedule_factory_reset(self, pending: bool) -> None:
        """SS X / SS Y."""
        self.flash.write(pending_factory=pending)

    def settled_ack(self) -> Reply | Pending:
        """`SS` acknowledges once its save is on disk, as the firmware does once its flash is
        written, so a host that saw `:A` may kill the emulator (MS-111). A store writing in the
        background makes it wait; HALT cannot cut a save short, lines behind it wait (MS-13)."""
        if self.flash.settled:
            return self.controller.ack()
        self._ack_waits = True
        return Pending(None, self._settled_ack, cancel=self._stop_waiting, haltable=False)

    def _settled_ack(self, t: float) -> Reply:
        self._stop_waiting(t)
        return self.controller.ack()

    def _stop_waiting(self, t: float) -> None:
        self._ack_waits = False

    def save_auto(self) -> None:
        """Settings remembered as soon as they change (SL, SU, HM, AA, CCA X, BCA, DLED maxima)."""
        controller = self.controller
        axes = {a.hw_letter: to_plain(a.auto) for a in controller.axes}
        modules = controller.modules.save_auto()
        self.flash.write(auto={"axes": axes, "card": to_plain(controller.card_auto), "modules": modules})

    def forget(self) -> None:
        """Erase the device's flash (a factory-fresh controller), e.g. for a host's `reset` op."""
        try:
            self.flash.erase()
        except StorageError as failure:
            raise ControlError(
                f"{self.controller.name}: factory reset refused, saved settings kept: {failure}"
            ) from failure

    def storage_result(self, failure: StorageError | None) -> None:
        """The outcome of every flash operation (Flash's `on_result`). The controller works on from
        its in-memory flash and still acks `SS`, as a real one does; a failure is flagged
        (`storage_error`, shown by `ctl list`) and pushed as an event, a successful save clears it.
        A settled store releases an `SS` waiting for it."""
        controller = self.controller
        if failure is None:
            controller.storage_error = None
        else:
            controller.storage_error = str(failure)
            controller.push_event(
                {
                    "ev": "storage_error",
                    "t": controller.now,
                    "op": failure.op,
                    "path": str(failure.path),
                    "error": failure.reason,
                }
            )
        if self.flash.settled and self._ack_waits:  # not another command's pending reply
            controller.interpreter.release(controller.now)
