"""ARRAY MODULE: moves to the cells of a grid of XY positions (§9.1, MS-ARRAY-1…MS-ARRAY-8).

`AR` defines the grid (columns, rows, spacings in mm, tilt in degrees), `AH` its (1,1) cell, `AIJ`
moves to one cell. Bare `AR` (or a normal `@` press) runs a self-scan: every cell in serpentine or
raster order (`SN F`), `RT Z` ms after each arrival, repeating in ring-buffer mode 3. `RM X=1` moves
to (1,1) and arms commanded stepping, where each IN0 pulse in mode 7 (or bare `RM`) moves to the next
cell. Every cell move is a commanded move of the motion model (busy, OUT0 mode 2 pulse) and ends in
an `array_arrival` event. `AR`, `AH` and `SN` are saved by `SS Z`; the last cell is volatile.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.buttons import LONG, NORMAL
from emulator.devices.ms2000.calls import (
    Call,
    Param,
    Reply,
    run_settings,
    whole,
    within,
)
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import (
    ControlChannel,
    LcdSegment,
    PanelButtons,
    Playback,
    RmXServer,
    TtlIn,
)
from emulator.devices.ms2000.modules.events import ArrayArrival, Halt, MoveComplete, Reset, RmX, on
from emulator.devices.ms2000.modules.scan_roles import FAST, SCAN_MODULE, SERPENTINE, SLOW, shared_roles
from emulator.profiles.schema import Bool, Field
from protocols.ms2000 import Fmt, Kind
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

#: MS-ARRAY-1: a 96-well plate
FACTORY_GRID: dict[str, float] = {"columns": 12, "rows": 8, "dx": 9.0, "dy": -9.0, "tilt": 0.0}
MAX_CELLS_PER_SIDE = 1000  # [choice] (MS-ARRAY-1)
MAX_TILT_DEG = 360.0  # [choice]
STEP_MODE = 7  # IN0 mode 7: next cell (MS-ARRAY-6)
START_STEPPING = 1  # RM X=1 (MS-ARRAY-6)
REPEATING = 3  # ring-buffer mode that repeats self-scans (MS-ARRAY-5)
FN_SELF_SCAN = 7  # BE F function: array self-scan start/stop (Appendix B)
SEQUENCER = "SEQUENCER"  # beside it a long `@` press starts a self-scan (MS-SEQ-7)
#: row counts whose row is shown as a letter on the LCD (MS-ARRAY-7)
LETTER_ROWS = (4, 8, 16)
# MS-ARRAY-7 state characters
IDLE, START, MOVING, DELAY, ARRIVED, NEXT, COMPLETE, ERROR = "I", "S", "M", "D", "A", "N", "C", "E"
# what runs: nothing (idle or one AIJ move), a self-scan, commanded stepping
SELF_SCAN, STEPPING = "self_scan", "stepping"

Cell = tuple[int, int]


@dataclass(frozen=True)
class CellOrder:
    """The visiting order of a run, fixed when it starts: row by row, serpentine (alternate rows
    reversed) or raster (MS-ARRAY-5). Computed per step: a 1000 × 1000 grid is no list."""

    columns: int
    rows: int
    serpentine: bool

    @property
    def count(self) -> int:
        return self.columns * self.rows

    def cell(self, step: int) -> Cell:
        row, offset = divmod(step, self.columns)
        j = row + 1
        i = self.columns - offset if self.serpentine and j % 2 == 0 else offset + 1
        return i, j


@register
class ArrayModule(Module, RmXServer, TtlIn, PanelButtons, LcdSegment, ControlChannel):
    name = "ARRAY MODULE"
    knob_fields = (
        Field(
            "array_start_on_rm_x0",
            Bool(),
            False,
            "MS-ARRAY-6",
            "`RM X=0` also starts commanded array stepping while `TTL X=7` (ARRAY MODULE)",
        ),
    )
    in0_modes = frozenset({STEP_MODE})
    rm_x_values = frozenset({START_STEPPING})
    button_priority = 40  # after SEQUENCER, CRISP, SCAN (MS-85)
    observable = "array"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.roles = shared_roles(controller)
        self.grid = dict(FACTORY_GRID)
        self.home = {"X": 0.0, "Y": 0.0}  # AH: the (1,1) cell, user mm
        self.cell: Cell = (1, 1)
        self.state = IDLE
        self.running: str | None = None
        self.order = CellOrder(0, 0, False)
        self.step = 0
        self.goals: list[tuple[Axis, float]] = []
        self._timer: Timer | None = None

    def handlers(self) -> dict[str, Handler]:
        table: dict[str, Handler] = {"AR": self.array, "AH": self.ahome, "AIJ": self.aij}
        if SCAN_MODULE not in self.controller.cfg.modules:  # SCAN MODULE owns SN when present
            table["SN"] = self.scan_settings
        return table

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {FN_SELF_SCAN: self.toggle_self_scan}

    # ---- reports ------------------------------------------------------------------------------

    @property
    def moving(self) -> bool:
        return bool(self.goals)

    def state_char(self) -> str:
        """Lower case while IN0 is ignored until the current stepping move ends (MS-ARRAY-7)."""
        return self.state.lower() if self.running == STEPPING and self.moving else self.state

    def lcd_segment(self, now: float) -> str | None:
        i, j = self.cell
        rows = int(self.grid["rows"])
        row = chr(ord("A") + j - 1) if rows in LETTER_ROWS else str(j)
        return f"{self.state_char()} {i},{row}"

    def observe(self, now: float) -> Any:
        i, j = self.cell
        return {"state": self.state_char(), "i": i, "j": j, "running": self.running}

    # ---- SS Z ---------------------------------------------------------------------------------

    def save(self) -> dict[str, Any]:
        return {"grid": dict(self.grid), "home": dict(self.home), **self.roles.save()}

    def restore(self, data: dict[str, Any] | None) -> None:
        data = data or {}
        self.grid = dict(FACTORY_GRID)
        self.home = {"X": 0.0, "Y": 0.0}
        for stored, own in ((data.get("grid"), self.grid), (data.get("home"), self.home)):
            if isinstance(stored, dict):
                for key, value in stored.items():
                    if key in own and isinstance(value, int | float) and not isinstance(value, bool):
                        own[key] = value
        self.roles.restore(data, self.controller)

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self._stop(IDLE)
        self.cell = (1, 1)

    @on(Halt)
    def halt(self, event: Halt) -> None:
        """HALT stops a self-scan or stepping (MS-ARRAY-5)."""
        self._stop(IDLE)

    # ---- commands -----------------------------------------------------------------------------

    def array(self, call: Call) -> Reply:
        """ARRAY: X columns, Y rows, Z/F spacing (mm), T tilt (°); bare AR starts or stops a self-scan
        (MS-ARRAY-1, MS-ARRAY-5)."""
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            self.toggle_self_scan(call.now)
            return self.controller.ack()
        grid = self.grid

        def setter(key: str) -> Callable[[float], None]:
            return lambda v: grid.__setitem__(key, v)

        params = {
            "X": Param(lambda: grid["columns"], setter("columns"), whole(1, MAX_CELLS_PER_SIDE)),
            "Y": Param(lambda: grid["rows"], setter("rows"), whole(1, MAX_CELLS_PER_SIDE)),
            "Z": Param(lambda: grid["dx"], setter("dx"), fmt=Fmt.F6),
            "F": Param(lambda: grid["dy"], setter("dy"), fmt=Fmt.F6),
            "T": Param(lambda: grid["tilt"], setter("tilt"), within(-MAX_TILT_DEG, MAX_TILT_DEG), Fmt.F6),
        }
        return run_settings(call, params, "XYZFT", self.controller.render(call.key), self.controller.ack())

    def ahome(self, call: Call) -> Reply:
        """AHOME: bare, the current XY position becomes cell (1,1); `AH X=x Y=y` in mm (MS-ARRAY-2)."""
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            for letter in self.home:
                axis = self.controller.axis_named(letter)
                if axis is not None:
                    self.home[letter] = axis.user_mm(call.now)
            return self.controller.ack()
        params = {letter: self._home_param(letter) for letter in self.home}
        return run_settings(call, params, "XY", self.controller.render(call.key), self.controller.ack())

    def _home_param(self, letter: str) -> Param:
        def store(value: float) -> None:
            self.home[letter] = value

        return Param(lambda: self.home[letter], store, fmt=Fmt.F6)

    def aij(self, call: Call) -> Reply:
        """AIJ X=i Y=j: a commanded move to cell (i, j); a missing item keeps the last i or j, so bare
        `AIJ` revisits the last cell [choice]; `AIJ X? Y?` reads the last cell (MS-ARRAY-4)."""
        target = list(self.cell)
        params = {
            "X": Param(
                lambda: self.cell[0],
                lambda v: target.__setitem__(0, int(v)),
                whole(1, int(self.grid["columns"])),
            ),
            "Y": Param(
                lambda: self.cell[1],
                lambda v: target.__setitem__(1, int(v)),
                whole(1, int(self.grid["rows"])),
            ),
        }
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        reply = run_settings(
            call, params, "XY", self.controller.render(call.key), self.controller.ack(), require_items=False
        )
        if not items or any(i.kind is not Kind.QUERY for i in items):
            self._stop(IDLE)
            self._visit((target[0], target[1]), call.now)
        return reply

    def scan_settings(self, call: Call) -> Reply:
        """SCAN in a build without SCAN MODULE: the axis roles and pattern only (MS-SCAN-1); bare `SN`
        has nothing to start: `:N-3` [choice]."""
        return run_settings(
            call, self.roles.params(), "XYZF", self.controller.render(call.key), self.controller.ack()
        )

    # ---- geometry (MS-ARRAY-3) ----------------------------------------------------------------

    def _roles(self) -> tuple[Axis | None, Axis | None]:
        """The axes the columns (fast) and rows (slow) run along: `SN`'s, else X and Y [choice]."""
        fast, slow = self.roles.axis_with(FAST, self.controller), self.roles.axis_with(SLOW, self.controller)
        if fast is None or slow is None or fast is slow:
            return self.controller.axis_named("X"), self.controller.axis_named("Y")
        return fast, slow

    def cell_goals(self, cell: Cell) -> list[tuple[Axis, float]]:
        """Machine counts of cell (i, j): the grid rotated by the tilt about cell (1,1)."""
        i, j = cell
        theta = math.radians(self.grid["tilt"])
        ux, uy = (i - 1) * self.grid["dx"], (j - 1) * self.grid["dy"]
        along = ux * math.cos(theta) - uy * math.sin(theta)
        across = ux * math.sin(theta) + uy * math.cos(theta)
        goals = []
        for axis, offset in zip(self._roles(), (along, across), strict=True):
            if axis is not None:
                origin = self.home.get(axis.letter, 0.0)
                goals.append((axis, float(round_half_away(axis.counts_of(origin + offset)))))
        return goals

    def _cells(self) -> CellOrder:
        return CellOrder(int(self.grid["columns"]), int(self.grid["rows"]), self.roles.pattern == SERPENTINE)

    # ---- running ------------------------------------------------------------------------------

    def toggle_self_scan(self, now: float) -> None:
        """Bare AR, `@`, BE F=7: start a self-scan, or stop the one running (MS-ARRAY-5)."""
        if self.running == SELF_SCAN:
            self._stop(IDLE)
        else:
            self._begin(SELF_SCAN, now)

    @on(RmX)
    def rm_x(self, event: RmX) -> None:
        """`RM X=1` starts commanded stepping; `RM X=0` too with the knob, in IN0 mode 7 (MS-ARRAY-6)."""
        knob = self.controller.knobs.array_start_on_rm_x0 and self.controller.card.ttl_in == STEP_MODE
        if event.value == START_STEPPING or (event.value == 0 and knob):
            self._begin(STEPPING, event.t)

    def in0_trigger(self, mode: int, now: float) -> None:
        """Next cell while stepping; ignored while a move runs or once the last cell is reached."""
        if self.running != STEPPING or self.moving or self.step + 1 >= self.order.count:
            return
        self.step += 1
        self.state = NEXT
        self._visit(self.order.cell(self.step), now)

    def button(self, name: str, press: str, now: float) -> bool:
        """`@` normal: start or stop a self-scan (MS-ARRAY-5); beside SEQUENCER, which takes the
        normal press while it runs or waits for `@`, a long press starts one (MS-SEQ-7)."""
        if (name, press) == ("at", NORMAL):
            self.toggle_self_scan(now)
            return True
        if (name, press) == ("at", LONG) and SEQUENCER in self.controller.cfg.modules:
            if self.running != SELF_SCAN:
                self._begin(SELF_SCAN, now)
            return True
        return False

    def _begin(self, running: str, now: float) -> None:
        self._stop(START)
        self.running = running
        self.order = self._cells()
        self.step = 0
        self._visit(self.order.cell(0), now)

    def _stop(self, state: str) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self.running = None
        self.goals = []
        self.state = state

    def _visit(self, cell: Cell, now: float) -> None:
        self.cell = cell
        self.goals = [(axis, goal) for axis, goal in self.cell_goals(cell) if axis.enabled]
        if not self.goals:
            self._stop(ERROR)  # no axis can move: the move fails at once
            return
        self.state = MOVING
        self.controller.start_moves(self.goals, now)

    @on(MoveComplete)
    def move_complete(self, event: MoveComplete) -> None:
        """An arrival: `array_arrival`, then what the run does next; a cell not reached (limit,
        stall) is state E and ends the run (MS-ARRAY-7, MS-ARRAY-8)."""
        axes = event.axes
        now = event.t
        letters = {axis.letter for axis, _ in self.goals}
        if not letters & set(axes):
            return
        reached = all(abs(axis.pos(now) - goal) < 0.5 for axis, goal in self.goals)
        self.goals = []
        if not reached:
            self._stop(ERROR)
            return
        i, j = self.cell
        self.controller.push_event({"ev": "array_arrival", "i": i, "j": j, "t": now})
        self.controller.emit(ArrayArrival(now))  # SEQUENCER's condition 13 (MS-ARRAY-8)
        self.state = ARRIVED
        last = self.step + 1 >= self.order.count
        if self.running == SELF_SCAN:
            repeat = self._playback() == REPEATING
            self.state = COMPLETE if last and not repeat else DELAY
            self._after_delay(now, self._next_self_scan_cell)
        elif self.running == STEPPING and last:
            self.state = COMPLETE
            self._after_delay(now, self._complete)

    def _playback(self) -> int | None:
        """RING BUFFER's playback mode, which self-scanning follows (MS-ARRAY-5)."""
        ring = self.controller.module(Playback)
        return ring.playback_mode() if ring is not None else None

    def _after_delay(self, now: float, action: Callable[[float], None]) -> None:
        self._timer = self.controller.at(now + self.controller.card.rt_delay_ms / 1000, action)

    def _next_self_scan_cell(self, now: float) -> None:
        self._timer = None
        if self.step + 1 >= self.order.count:
            if self._playback() != REPEATING:
                self._complete(now)
                return
            self.order = self._cells()
            self.step = -1
        self.step += 1
        self.state = NEXT
        self._visit(self.order.cell(self.step), now)

    def _complete(self, now: float) -> None:
        """After the last cell: C for one `RT Z` delay, then idle [choice] (TV-133 passes C)."""
        self._stop(IDLE)
