"""Running a plan on any MS-2000 personality with documented high-level commands (MS-TRACER-5).

Per move: `S` for the moving axes (six decimals; skipped when unchanged), `M` in units, then `/`
polled until `N` before the next step. A rapid (G00) runs each axis at its maximum speed, found
the way hosts find it: set a speed above any maximum, which the controller clamps, and read it
back (MS-54). M03/M05 are `TTL Y=1`/`TTL Y=0` (MS-TRACER-3). A dwell waits on the host's clock.

Around the run [choice]: the speeds found at the start are restored at the end; if the run fails
or is interrupted, motion is halted, the TTL output de-asserted and the speeds restored, as far as
the controller still answers.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import TypeVar

import serial

from protocols.clients.errors import NoReply
from protocols.clients.gcode.parser import GcodeError, parse_program
from protocols.clients.gcode.plan import AXES, Dwell, Move, Output, Point, Step, moving_axes
from protocols.clients.ms2000 import MS2000, MS2000Error

#: above any axis's maximum speed (mm/s): the controller clamps it to the maximum (MS-54)
PROBE_SPEED_MM_S = 10000.0
#: the smallest speed six decimals can say (mm/s)
MIN_SPEED_MM_S = 0.000001
_STAGE_ERRORS = (MS2000Error, NoReply, TimeoutError, serial.SerialException)
_T = TypeVar("_T")


class ExecutionError(Exception):
    """The controller refused or did not answer while running the program line `line` (None:
    while preparing the run)."""

    def __init__(self, line: int | None, message: str) -> None:
        self.line = line
        self.message = message
        super().__init__(message if line is None else f"line {line}: {message}")


@dataclass
class RunSummary:
    moves: int = 0
    dwells: int = 0
    outputs: int = 0
    seconds: float = 0.0


class GcodeExecutor:
    """Sends a plan (`parse_program`) to a controller through the MS2000 client."""

    def __init__(
        self,
        stage: MS2000,
        *,
        poll_s: float = 0.01,
        move_timeout_s: float = 3600.0,
        sleep: Callable[[float], None] = time.sleep,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.stage = stage
        self.poll_s = poll_s
        self.move_timeout_s = move_timeout_s
        self._sleep = sleep
        self._clock = clock
        self.units_per_mm: dict[str, float] = {}
        self.max_speed: dict[str, float] = {}
        self._original_speed: dict[str, float] = {}
        self._speed_sent: dict[str, float] = {}
        self._output_on = False

    # ---- read-outs ----------------------------------------------------------------------------

    def counts_per_mm(self) -> dict[str, float]:
        """`C X? …`: the encoder counts per mm Tracer Console shows (MS-TRACER-5)."""
        return self._ask(None, lambda: self.stage.get("C", *self.stage.axes()))

    def start_position(self) -> Point:
        """Where the stage is (stage mm; 0 for an axis the stage lacks): where a program starts."""
        axes = [a for a in AXES if a in self._ask(None, self.stage.axes)]
        self._learn_units(axes)
        where = self._ask(None, lambda: self.stage.where(*axes))
        x, y, z = (where[a] / self.units_per_mm[a] if a in where else 0.0 for a in AXES)
        return (x, y, z)

    # ---- running ------------------------------------------------------------------------------

    def run(
        self,
        steps: Iterable[Step],
        on_step: Callable[[Step], None] | None = None,
        *,
        axes: Mapping[str, int] | None = None,
    ) -> RunSummary:
        """Run the plan to its end; `on_step` hears of each step before it is sent. `axes` are the
        axes the plan moves, with the line that first moves each (`moving_axes`): given them, the
        plan is read once, as it is sent, so a plan of any length can come from an iterator."""
        if axes is None:
            steps = list(steps)
            axes = moving_axes(steps)
        moving = self._check_axes(axes)
        started = self._clock()
        summary = RunSummary()
        self._prepare(moving)
        try:
            for step in steps:
                if on_step is not None:
                    on_step(step)
                self._ask(step.line, partial(self._step, step, summary))
        except BaseException:
            self._abort()
            raise
        self._ask(None, self._restore_speeds)
        summary.seconds = self._clock() - started
        return summary

    def _check_axes(self, first_use: Mapping[str, int]) -> list[str]:
        """The axes the plan moves (in X Y Z order); each must exist on the stage."""
        present = self._ask(None, self.stage.axes)
        for axis, line in first_use.items():
            if axis not in present:
                raise GcodeError(line, f"the stage has no {axis} axis (it has {' '.join(present)})")
        return [a for a in AXES if a in first_use]

    def _learn_units(self, axes: list[str]) -> None:
        unknown = [a for a in axes if a not in self.units_per_mm]
        if unknown:
            self.units_per_mm.update(self._ask(None, lambda: self.stage.get("UM", *unknown)))
        for axis in axes:
            if not self.units_per_mm.get(axis):
                raise ExecutionError(None, f"axis {axis} reports UM 0: positions cannot be converted")

    def _prepare(self, axes: list[str]) -> None:
        if not axes:
            return
        self._learn_units(axes)
        stage = self.stage

        def probe() -> None:
            self._original_speed = stage.get("S", *axes)
            stage.set_speed(**dict.fromkeys(axes, PROBE_SPEED_MM_S))
            self.max_speed = stage.get("S", *axes)

        self._ask(None, probe)
        self._speed_sent = dict(self.max_speed)

    def _step(self, step: Step, summary: RunSummary) -> None:
        if isinstance(step, Move):
            self._move(step)
            summary.moves += 1
        elif isinstance(step, Dwell):
            self._sleep(step.seconds)
            summary.dwells += 1
        elif isinstance(step, Output):
            self.stage.set("TTL", Y=1 if step.on else 0)
            self._output_on = step.on
            summary.outputs += 1

    def _move(self, move: Move) -> None:
        deltas = move.deltas()
        if move.feed_mm_s is None:
            speeds = {a: self.max_speed[a] for a in deltas}
        else:
            speeds = self._within_maximum(move.axis_speeds())
        changed = {a: v for a, v in speeds.items() if self._speed_sent.get(a) != v}
        if changed:
            self.stage.set_speed(**changed)
            self._speed_sent.update(changed)
        end = dict(zip(AXES, move.end, strict=True))
        self.stage.move(**{a: round(end[a] * self.units_per_mm[a], 6) for a in deltas})
        self.stage.wait_until_idle(
            timeout=self.move_timeout_s, poll=self.poll_s, sleep=self._sleep, clock=self._clock
        )

    def _within_maximum(self, speeds: dict[str, float]) -> dict[str, float]:
        """The feed vector shrunk as a whole until no axis exceeds its maximum, so the path keeps
        its direction; each speed at six decimals, never 0."""
        share = min([1.0, *(self.max_speed[a] / v for a, v in speeds.items() if v > 0)])
        return {a: max(MIN_SPEED_MM_S, round(v * share, 6)) for a, v in speeds.items()}

    def _restore_speeds(self) -> None:
        if self._original_speed:
            self.stage.set_speed(**self._original_speed)

    def _abort(self) -> None:
        """Leave the stage safe after a failure: halted, output off, speeds back."""
        with contextlib.suppress(*_STAGE_ERRORS):
            self.stage.halt()
        if self._output_on:
            with contextlib.suppress(*_STAGE_ERRORS):
                self.stage.set("TTL", Y=0)
        with contextlib.suppress(*_STAGE_ERRORS):
            self._restore_speeds()

    def _ask(self, line: int | None, action: Callable[[], _T]) -> _T:
        """Run `action`, turning a controller's refusal or silence into an `ExecutionError`."""
        try:
            return action()
        except _STAGE_ERRORS as exc:
            raise ExecutionError(line, str(exc)) from exc


def run_program(stage: MS2000, text: str, *, xyz_scale: float = 1.0, speed_scale: float = 1.0) -> RunSummary:
    """Parse `text` from where the stage is and run it: the one-call form of the library."""
    executor = GcodeExecutor(stage)
    steps = parse_program(text, start=executor.start_position(), xyz_scale=xyz_scale, speed_scale=speed_scale)
    return executor.run(steps)
