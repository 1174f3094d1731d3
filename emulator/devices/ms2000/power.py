"""Power-up, software reset and non-volatile memory of the controller (MS-110…MS-113), mixed into
MS2000. Factory values come from the profile; `SS Z` settings, auto-saved settings and positions
live in the device's flash (flash.py)."""

from __future__ import annotations

from typing import Any

from emulator.device import ControlError
from emulator.devices.ms2000.axis import LOWER, UPPER
from emulator.devices.ms2000.config import baud_of
from emulator.devices.ms2000.settings import (
    AxisAuto,
    AxisSettings,
    CardAuto,
    CardSettings,
    finite_number,
    from_plain,
    to_plain,
)
from emulator.motion import round_half_away
from emulator.nvstore import StorageError

CLOCK_MARK_S = 600.0
CLOCK_MARK_CODE = 255
IDENTITY_MISMATCH_CODE = 55
#: characters of a rejected stored value's repr shown in its warning
REPR_LIMIT = 40


class PowerMixin:
    """Part of MS2000: works on its axes, card settings, modules, flash and scheduler."""

    def _factory_axis(self, letter: str) -> AxisSettings:
        a = self.cfg.axes[letter]
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
        a = self.cfg.axes[letter]
        return AxisAuto(a.soft_lower_mm, a.soft_upper_mm, a.home_mm, a.aa)

    def _factory_card(self) -> CardSettings:
        return CardSettings(stop_bits=int(self.cfg.line.stop_bits))

    def _power_up(self, t: float, cold: bool) -> None:
        same = self.flash.load()
        if self.flash.pending_factory:
            self.flash.data.pop("saved", None)
            self.flash.write(pending_factory=False)
        self.baud = baud_of(self.dip["sw4"], self.dip["sw5"])
        if cold:
            physical = self._section(self.flash.data, "physical") or {}
            for axis in self.axes:
                counts = self._number(physical, axis.hw_letter, "physical")
                if counts is not None:
                    axis.traj = axis.traj.rest(t, counts)
        self._restore_settings()
        positions = self._section(self.flash.data, "positions") or {}  # null after SP X=1
        for axis in self.axes:
            saved = self._number(positions, axis.hw_letter, "positions")
            axis.origin = 0.0
            here = axis.user_mm(t)
            axis.origin = here - saved if saved is not None else here
        self._restart(t)
        if not same:
            self.log_error(IDENTITY_MISMATCH_CODE)

    def _restore_settings(self) -> None:
        saved = self._section(self.flash.data, "saved") or {}
        auto = self._section(self.flash.data, "auto") or {}
        saved_axes = self._section(saved, "axes", "saved") or {}
        auto_axes = self._section(auto, "axes", "auto") or {}
        reject = self._unusable
        for axis in self.axes:
            letter = axis.hw_letter
            axis.s = from_plain(
                self._factory_axis(letter), saved_axes.get(letter), f"saved.axes.{letter}", reject
            )
            axis.auto = from_plain(
                self.factory_auto(letter), auto_axes.get(letter), f"auto.axes.{letter}", reject
            )
            axis.letter = chr(axis.s.rename) if axis.s.rename else letter
        self.card = from_plain(self._factory_card(), saved.get("card"), "saved.card", reject)
        self.card_auto = from_plain(CardAuto(), auto.get("card"), "auto.card", reject)
        saved_modules = self._section(saved, "modules", "saved") or {}
        for name, module in self.modules.items():
            data = self._section(saved_modules, name, "saved.modules")
            module.restore(data)
            # modules check their own values; one that did not take a stored value kept its factory value
            kept = module.save()
            for key, value in (data or {}).items():
                if key in kept and kept[key] is not value and kept[key] != value:
                    reject(f"saved.modules.{name}.{key}", value)

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
        self.log.warning(
            "%s: stored %s = %s cannot be used; keeping the factory value", self.name, path, text
        )

    def _restart(self, t: float) -> None:
        """What power-up and reset share: motion stopped, volatile state cleared, clocks restarted."""
        for axis in self.axes:
            axis.power_off(t)
            axis.enabled = True
            axis.group = None
            axis.switch = {UPPER: False, LOWER: False}
            axis.target = round_half_away(axis.pos(t))
            axis.reset_extremes(t)
            axis.ensync_mm = None
        self.ensync_level = 0
        self.error_log.clear()
        self.trajectory_log.clear()
        self.user_counter = 0
        self.lcd_text = None
        self.low_level = False
        self._line.clear()
        self._overflow = False
        self.last_relative = []
        self.buttons.reset()
        self.low.reset()
        self._booted_at = t
        if self._clock_timer is not None:
            self._clock_timer.cancel()
        self._clock_timer = self.scheduler.at(t + CLOCK_MARK_S, self._clock_mark)
        for module in self.modules.values():
            module.reset(t)
        self.ttl.reset(t)
        self._saved_positions = self._position_key()

    def _clock_mark(self, t: float) -> None:
        if self.knobs.error_log_clock_marks:
            self.log_error(CLOCK_MARK_CODE)
        self._clock_timer = self.scheduler.at(t + CLOCK_MARK_S, self._clock_mark)

    def software_reset(self, t: float) -> None:
        """`~` and 0xFF 'R' (MS-112): saved settings back, positions 0, limits keep their place."""
        self._cancel_pending(t, reply=False)
        for axis in self.axes:
            axis.stop(t)
        self._restore_settings()
        for axis in self.axes:
            axis.origin = 0.0
            axis.origin = axis.user_mm(t)
        self._restart(t)
        # lines that waited behind a blocking command the reset cancelled still run, in order (MS-13)
        self._drain(t)

    def power_cycle(self, t: float) -> None:
        """Power off (positions saved unless `SP X=1`) and on (MS-112)."""
        self._cancel_pending(t, reply=False)
        self._queue.clear()
        for axis in self.axes:
            axis.stop(t)
        self.save_positions(t)
        self._silenced = False
        self._ff = False
        self._power_up(t, cold=False)

    def _position_key(self) -> tuple[int, ...]:
        t = self._now
        return (self.card.inhibit_position_save, *(round_half_away(a.units(t) * 1000) for a in self.axes))

    def save_positions(self, t: float) -> None:
        physical = {a.hw_letter: a.pos(t) for a in self.axes}
        positions = (
            None if self.card.inhibit_position_save else {a.hw_letter: a.user_mm(t) for a in self.axes}
        )
        self.flash.write(physical=physical, positions=positions)
        self._saved_positions = self._position_key()

    def _persist_idle_positions(self, t: float) -> None:
        """With a state directory, positions are written whenever the stage comes to rest, so an
        emulator killed without a power-off still restarts where it was (MS-111)."""
        if not self.flash.store.persistent or any(a.traj.moving(t) for a in self.axes):
            return
        if self._position_key() != self._saved_positions:
            self.save_positions(t)

    def save_settings(self) -> None:
        """SS Z (MS-110, MS-111)."""
        saved = {
            "axes": {a.hw_letter: to_plain(a.s) for a in self.axes},
            "card": to_plain(self.card),
            "modules": {name: m.save() for name, m in self.modules.items()},
        }
        self.flash.write(saved=saved)

    def save_auto(self) -> None:
        """Settings remembered as soon as they change (SL, SU, HM, AA, CCA X, BCA)."""
        auto = {"axes": {a.hw_letter: to_plain(a.auto) for a in self.axes}, "card": to_plain(self.card_auto)}
        self.flash.write(auto=auto)

    def schedule_factory_reset(self, pending: bool) -> None:
        """SS X / SS Y."""
        self.flash.write(pending_factory=pending)

    def forget_nonvolatile(self) -> None:
        """Erase the device's flash (a factory-fresh controller), e.g. for a host's `reset` op."""
        try:
            self.flash.erase()
        except StorageError as failure:
            raise ControlError(
                f"{self.name}: factory reset refused, saved settings kept: {failure}"
            ) from failure

    def storage_result(self, failure: StorageError | None) -> None:
        """The outcome of every flash operation (Flash's `on_result`). The controller works on from
        its in-memory flash and still acks `SS Z`, as a real one does; a failure is flagged
        (`storage_error`, shown by `ctl list`) and pushed as an event, a successful save clears it."""
        if failure is None:
            self.storage_error = None
            return
        self.storage_error = str(failure)
        self.push_event(
            {
                "ev": "storage_error",
                "t": self._now,
                "op": failure.op,
                "path": str(failure.path),
                "error": failure.reason,
            }
        )
