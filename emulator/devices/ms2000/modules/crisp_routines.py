"""CRISP's timed routines: log-amp and gain calibration, the focus curve and the offset reset
(MS-CRISP-2, MS-CRISP-3, MS-CRISP-8).

- Log-amp calibration: `H` for 0.5 s, then `G` (`D` if the signal is too weak); it sets the AGC
  value `LK M` from the sum signal [choice: sum / 16, at most 255].
- Gain calibration: `C`, then `1`…`5`, 0.2 s each [choice]: in `1` the focus axis goes to
  z0 − `LR F`/2, in `2` the error is read, in `3` it goes to z0 + `LR F`/2, in `4` the error is read
  again, in `5` it returns to z0; then `LR X` = the slope in error counts per µm and state `R`. No
  slope (the error saturated) ends in `E`, a weak signal in `D`, both keeping `LR X`.
- Focus curve: `a` to z0 − `LR F` (0.1 s), `b` and `c` scan to z0 + `LR F` in 350 steps of 5 ms
  [choice] sending `<z units> <error>` at each, `d` back to z0 (0.1 s), `e` one step, then the line
  `end` at the moment the previous state comes back. Anything that ends it early still sends `end`,
  so a host reading to `end` never hangs [choice].
- Offset reset: `o` for one update period (`UL Y`), `LK Z` := 0, `l` for one more, then the
  previous state.

The focus axis moves by the non-busy relative moves the wheel uses (MS-84): calibration moves are
no commanded moves (no `move_complete`, no OUT0 pulse, `/` stays `N`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from emulator.devices.ms2000.modules import crisp_states as st

if TYPE_CHECKING:
    from emulator.devices.ms2000.modules.crisp import Crisp
    from emulator.devices.ms2000.scheduler import Timer

LOGAMP_S = 0.5
GAIN_STEP_S = 0.2
CURVE_MOVE_S = 0.1
CURVE_STEP_S = 0.005
CURVE_STEPS = 350
AGC_PER_SUM = 1 / 16


@dataclass
class Curve:
    start_um: float
    step_um: float
    index: int = 0


class Routines:
    def __init__(self, crisp: Crisp) -> None:
        self.crisp = crisp
        self.timer: Timer | None = None
        self.curve: Curve | None = None
        #: gain calibration: where it started (user µm) and the error read low
        self._z0_um = 0.0
        self._low_error = 0
        self._slope = 0.0
        self.resume_to = st.READY

    def _after(self, seconds: float, action: Callable[[float], None], now: float) -> None:
        self.timer = self.crisp.controller.at(now + seconds, self._run(action))

    def _run(self, action: Callable[[float], None]) -> Callable[[float], None]:
        def run(due: float) -> None:
            self.timer = None
            action(due)

        return run

    def stop(self, now: float, quiet: bool = False) -> str:
        """End whatever runs (a new state was commanded, HALT): a focus curve still sends `end`
        unless `quiet` (reset). Returns the state to go back to: the one before a focus curve or
        an offset reset, `R` after a calibration."""
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None
        if self.curve is not None:
            self.curve = None
            if not quiet:
                self.crisp.controller.unsolicited("end", now)
        return self.resume_to

    # ---- log-amp calibration ------------------------------------------------------------------

    def logamp(self, now: float) -> None:
        self.resume_to = st.READY
        self.crisp.enter(st.LOGAMP_CAL, now)
        self._after(LOGAMP_S, self._logamp_done, now)

    def _logamp_done(self, now: float) -> None:
        crisp = self.crisp
        if crisp.dim():
            crisp.enter(st.DIM, now)
            return
        crisp.settings.agc = min(255, round(crisp.optics.sum * AGC_PER_SUM))
        crisp.enter(st.LOGAMP_DONE, now)

    # ---- gain calibration ---------------------------------------------------------------------

    def gain(self, now: float) -> None:
        self.resume_to = st.READY
        self.crisp.enter(st.GAIN_CAL, now)
        self._z0_um = self.crisp.focus_um(now)
        self._after(GAIN_STEP_S, lambda t: self._gain_step(0, t), now)

    def _gain_step(self, step: int, now: float) -> None:
        crisp = self.crisp
        half_um = crisp.settings.cal_range_mm * 1000 / 2
        if step == len(st.GAIN_STEPS):
            self._gain_done(now)
            return
        crisp.enter(st.GAIN_STEPS[step], now)
        if step == 0:
            crisp.move_focus_to(self._z0_um - half_um, now)
        elif step == 1:
            self._low_error = crisp.error(now)
        elif step == 2:
            crisp.move_focus_to(self._z0_um + half_um, now)
        elif step == 3:
            self._slope = abs(self._low_error - crisp.error(now)) / (2 * half_um)
        else:
            crisp.move_focus_to(self._z0_um, now)
        self._after(GAIN_STEP_S, lambda t: self._gain_step(step + 1, t), now)

    def _gain_done(self, now: float) -> None:
        crisp = self.crisp
        if crisp.dim():
            crisp.enter(st.DIM, now)
        elif round(self._slope) == 0:
            crisp.enter(st.ERROR, now)
        else:
            crisp.settings.cal_gain = round(self._slope)
            crisp.enter(st.READY, now)

    # ---- focus curve (MS-CRISP-8) -------------------------------------------------------------

    def focus_curve(self, previous: str, now: float) -> None:
        crisp = self.crisp
        range_um = crisp.settings.cal_range_mm * 1000
        z0 = crisp.focus_um(now)
        self.curve = Curve(z0 - range_um, 2 * range_um / CURVE_STEPS)
        self.resume_to = previous
        crisp.enter(st.CURVE_START, now)
        crisp.move_focus_to(z0 - range_um, now)
        self._after(CURVE_MOVE_S, self._curve_sample, now)

    def _curve_sample(self, now: float) -> None:
        crisp = self.crisp
        curve = self.curve
        if curve is None:
            return
        crisp.enter(st.CURVE_LOW if curve.index < CURVE_STEPS // 2 else st.CURVE_HIGH, now)
        crisp.controller.unsolicited(
            f"{crisp.controller.where(crisp.focus_units(now))} {crisp.error(now)}", now
        )
        curve.index += 1
        if curve.index > CURVE_STEPS:
            crisp.enter(st.CURVE_BACK, now)
            crisp.move_focus_to(curve.start_um + CURVE_STEPS * curve.step_um / 2, now)
            self._after(CURVE_MOVE_S, self._curve_ending, now)
            return
        crisp.move_focus_to(curve.start_um + curve.index * curve.step_um, now)
        self._after(CURVE_STEP_S, self._curve_sample, now)

    def _curve_ending(self, now: float) -> None:
        self.crisp.enter(st.CURVE_END, now)
        self._after(CURVE_STEP_S, self._curve_done, now)

    def _curve_done(self, now: float) -> None:
        curve = self.curve
        if curve is None:
            return
        self.curve = None
        self.crisp.controller.unsolicited("end", now)
        self.crisp.resume(self.resume_to, now)

    # ---- offset reset -------------------------------------------------------------------------

    def offset_reset(self, previous: str, now: float) -> None:
        crisp = self.crisp
        period = crisp.settings.update_ms / 1000
        self.resume_to = previous
        crisp.enter(st.OFFSET_RESET, now)

        def cleared(t: float) -> None:
            crisp.settings.offset = 0
            crisp.enter(st.OFFSET_RESET_END, t)
            self._after(period, lambda due: crisp.resume(previous, due), t)

        self._after(period, cleared, now)
