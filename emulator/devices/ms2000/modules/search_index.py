"""SEARCH INDEX and SEEK LIMITS: the `SI` command, by encoder kind (§9.16, MS-SI-1…MS-SI-3).

An axis with a linear encoder (profile `encoder: linear`) needs SEARCH INDEX: `SI L=p` moves to the
encoder index at the middle of the hardware travel, makes that position read p units, resets the
soft limits to their factory values and replies once the search is over (MS-33). A search fails
(`:N-5`) when it would repeat the last successful one (same p, the axis not moved since), or when
the index is missing (control input `index_missing`; code 100 + axis index is logged).

An axis with a rotary encoder needs SEEK LIMITS: `SI L=1` / `SI L=-1` replies at once and runs the
axis to its upper / lower hardware limit, backs off 3 mm and approaches again, busy throughout
(right status character `B`). Every leg runs at the axis speed `S` [choice: the slower final
approach is not modelled] and each leg is a commanded move of its own (a `move_complete` event).

An axis whose kind's module is absent answers `:N-1`, like the command without either module
(MS-SI-3, MS-118). `SI L?` reads the last value set (volatile, 0 after a reset). The two modules
share one command: when a build lists both, the first listed serves `SI` for both kinds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from emulator.device import ControlError
from emulator.devices.ms2000.activity import Activity
from emulator.devices.ms2000.calls import (
    Call,
    CommandError,
    Pending,
    Reply,
    axis_items,
    first_error,
    number,
)
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel
from emulator.devices.ms2000.modules.events import Halt, MoveComplete, Reset, on
from protocols.ms2000 import ErrorCode, Fmt, Kind, error_reply, format_value
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner

SEARCH_INDEX = "SEARCH INDEX"
SEEK_LIMITS = "SEEK LIMITS"
#: the encoder kind each module serves (MS-SI-3)
KIND_OF = {SEARCH_INDEX: "linear", SEEK_LIMITS: "rotary"}
#: MS-SI-2: the back-off distance before the second approach
BACK_OFF_MM = 3.0
#: MS-SI-1: code logged when the index is missing is this plus the axis index
INDEX_MISSING_CODE = 100
APPROACH, BACK_OFF, FINAL = 1, 2, 3


@dataclass
class Seek:
    """One axis's limit seek: its leg, direction (+1 upper, −1 lower) and the target of that leg."""

    leg: int
    direction: int
    target: int


class _IndexSeek(Module, ControlChannel):
    inputs = frozenset({"index_missing"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        modules = list(controller.cfg.modules)
        first = next(n for n in modules if n in KIND_OF)
        #: only the first of the two modules listed serves `SI`, so one state serves both kinds
        self.serves = first == self.name
        self.kinds = {KIND_OF[n] for n in modules if n in KIND_OF}
        self.last: dict[str, float] = {}
        #: hw letter -> (p, machine count) of the last successful search
        self.found: dict[str, tuple[float, int]] = {}
        self.missing: set[str] = set()
        self.seeks: dict[str, Seek] = {}
        #: the search the pending `SI` waits for: (axis, p, index count) per axis
        self.search: list[tuple[Axis, float, int]] = []

    def handlers(self) -> dict[str, Handler]:
        return {"SI": self.si} if self.serves else {}

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self.last.clear()
        self.found.clear()
        self.seeks.clear()
        self.search = []

    @on(Halt)
    def halt(self, event: Halt) -> None:
        self.seeks.clear()
        self.search = []

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """`index_missing {axis, missing}`: the axis's index mark cannot be found (MS-SI-1)."""
        letter = params.get("axis")
        axis = self.controller.axis_named(letter.upper()) if isinstance(letter, str) else None
        if axis is None:
            raise ControlError(f"index_missing: axis must be a motor axis letter, got {letter!r}")
        missing = params.get("missing", True)
        if not isinstance(missing, bool):
            raise ControlError("index_missing: missing must be true or false")
        if missing:
            self.missing.add(axis.hw_letter)
        else:
            self.missing.discard(axis.hw_letter)
        return sorted(self.missing)

    # ---- the command --------------------------------------------------------------------------

    def si(self, call: Call) -> Reply | Pending:
        """SI: search index (linear axes) or seek limit (rotary axes) (MS-SI-1…MS-SI-3)."""
        controller = self.controller
        picked = axis_items(call, controller.axes)
        if any(axis.cfg.encoder not in self.kinds for axis, _ in picked):
            raise CommandError(ErrorCode.UNKNOWN_COMMAND)
        queries = [axis for axis, item in picked if item.kind is Kind.QUERY]
        sets = [(axis, number(item)) for axis, item in picked if item.kind is not Kind.QUERY]
        codes = [code for axis, value in sets if (code := self._invalid(axis, value, call.now))]
        first_error(codes)
        searches = []
        for axis, value in sets:
            self.last[axis.hw_letter] = value
            if axis.cfg.encoder == "rotary":
                self._seek_leg(axis, Seek(APPROACH, int(value), 0), call.now)
            else:
                searches.append((axis, value))

        def answer() -> Reply:
            if not queries:
                return controller.ack()
            pairs = [(a.letter, format_value(self.last.get(a.hw_letter, 0), Fmt.I)) for a in queries]
            return controller.render(call.key).items(pairs)

        if not searches:
            return answer()
        return self._start_search(searches, call.now, answer)

    def _invalid(self, axis: Axis, value: float, now: float) -> int | None:
        if axis.cfg.encoder == "rotary":
            return None if value in (1, -1) else ErrorCode.OUT_OF_RANGE
        previous = self.found.get(axis.hw_letter)
        if previous == (value, round_half_away(axis.pos(now))) and not axis.busy(now):
            return ErrorCode.FAILED  # the same search again, from where the last one ended
        return None

    # ---- SEARCH INDEX (MS-SI-1) ---------------------------------------------------------------

    def _start_search(
        self, searches: list[tuple[Axis, float]], now: float, answer: Callable[[], Reply]
    ) -> Pending:
        """Move to each index (the middle of the hardware travel [choice]); reply on arrival."""
        controller = self.controller
        self.search = [(axis, p, _index_count(axis)) for axis, p in searches]
        controller.start_moves([(axis, float(count)) for axis, _, count in self.search], now, Activity.HOME)
        due = max([now, *(axis.traj.end for axis, _, _ in self.search)])

        def finish(t: float) -> Reply:
            search, self.search = self.search, []
            ok = [self._found(axis, p, count, t) for axis, p, count in search]
            return answer() if all(ok) else Reply.text(error_reply(ErrorCode.FAILED))

        return Pending(due, finish, cancel=lambda t: self.halt(Halt(t)))

    def _found(self, axis: Axis, p: float, count: int, t: float) -> bool:
        """At the end of the search: set p at the index and the factory soft limits, if found."""
        if axis.hw_letter in self.missing:
            self.controller.log_error(INDEX_MISSING_CODE + axis.index)
            return False
        if not axis.enabled or round_half_away(axis.pos(t)) != count:
            return False  # stopped on the way (limit switch, stall) or a disabled motor
        axis.sample(t)
        axis.origin = axis.s.polarity * axis.pos(t) / axis.counts_per_mm - p / axis.s.unit_multiplier
        axis.auto.soft_lower = axis.cfg.soft_lower_mm
        axis.auto.soft_upper = axis.cfg.soft_upper_mm
        self.found[axis.hw_letter] = (p, count)
        self.controller.positions_changed()
        self.controller.limits_changed()
        return True

    # ---- SEEK LIMITS (MS-SI-2) ----------------------------------------------------------------

    def _seek_leg(self, axis: Axis, seek: Seek, now: float) -> None:
        low, high = axis.cfg.travel_mm
        limit = round_half_away((high if seek.direction > 0 else low) * axis.counts_per_mm)
        goal = limit
        if seek.leg == BACK_OFF:
            goal = round_half_away(axis.pos(now) - seek.direction * BACK_OFF_MM * axis.counts_per_mm)
        self.controller.start_moves([(axis, float(goal))], now, Activity.HOME)
        seek.target = axis.target  # after clamping to the limits
        self.seeks[axis.hw_letter] = seek

    @on(MoveComplete)
    def move_complete(self, event: MoveComplete) -> None:
        axes = event.axes
        now = event.t
        for axis in self.controller.axes:
            seek = self.seeks.get(axis.hw_letter)
            if seek is None or axis.letter not in axes:
                continue
            if axis.target != seek.target or seek.leg == FINAL:
                del self.seeks[axis.hw_letter]  # done, or another command took the axis over
            else:
                self._seek_leg(axis, Seek(seek.leg + 1, seek.direction, 0), now)


def _index_count(axis: Axis) -> int:
    low, high = axis.cfg.travel_mm
    return round_half_away((low + high) / 2 * axis.counts_per_mm)


@register
class SearchIndex(_IndexSeek):
    name = SEARCH_INDEX


@register
class SeekLimits(_IndexSeek):
    name = SEEK_LIMITS
