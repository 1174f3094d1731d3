"""PLANAR CORRECTION: a three-point focal plane that Z follows (§9.9, MS-PC-1…MS-PC-5).

`CCB Z=1|2|3` store the current X, Y, Z as points 1–3, `CCB Z=4` fits the plane through them and
enables the correction, `Z=5` disables it, `Z=6` reads the physical Z position (units), `Z=7`
clears everything. The joystick button held 3 s selects the next point (and enables after the
third, or re-enables in state `G`); home held 3 s (6 s beside RING BUFFER) disables, or clears.

While enabled, Z's physical position is its commanded one plus the plane's height c(x, y) at the
current X and Y, however they move: the axis's `follow` adds c to its commanded path, so `W Z`
stays in plane coordinates. Switching the correction on or off never moves Z: the commanded frame
is re-expressed instead (`Axis.reframe`). The plane's tilt comes from the points in machine
coordinates; where its height is 0 is kept in user coordinates of X and Y, so `H X`/`H Y` change
the height at a place but not the tilt, and ZERO (command or button) makes it 0 at the current
place (MS-PC-2). `SS Z` saves the plane and the enabled flag; points are volatile.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.buttons import EXTRA
from emulator.devices.ms2000.calls import Call, CommandError, Reply, first_error, number
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, LcdSegment, PanelButtons
from emulator.devices.ms2000.modules.events import Reset, Zeroing, on
from emulator.profiles.schema import finite_number
from protocols.ms2000 import ErrorCode, Kind, Shape
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner

#: `CCB Z=` operations (MS-PC-1)
FIT_AND_ENABLE, DISABLE, READ_PHYSICAL, CLEAR = 4, 5, 6, 7
#: BE F function numbers (Appendix B)
FN_SELECT, FN_DISABLE = 13, 14
#: how long home must be held (MS-PC-4): longer beside RING BUFFER, whose home press clears it
HOME_MS, HOME_MS_WITH_RING_BUFFER = 3000.0, 6000.0
#: three points closer to a line than this (sine squared of the angle between them) fit no plane
COLLINEAR = 1e-12


@dataclass(frozen=True)
class Plane:
    """z = a·(x − x0) + b·(y − y0): tilt in Z mm per X and Y mm, origin (x0, y0) in user mm."""

    a: float
    b: float
    x0: float
    y0: float


def fit(points: list[tuple[float, float, float]]) -> tuple[float, float] | None:
    """The tilt (a, b) of the plane through three (x, y, z) points, None if collinear in XY."""
    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = points
    dx2, dy2, dz2 = x2 - x1, y2 - y1, z2 - z1
    dx3, dy3, dz3 = x3 - x1, y3 - y1, z3 - z1
    det = dx2 * dy3 - dx3 * dy2
    spread = (dx2 * dx2 + dy2 * dy2) * (dx3 * dx3 + dy3 * dy3)
    if spread == 0 or det * det <= COLLINEAR * spread:
        return None
    return (dz2 * dy3 - dz3 * dy2) / det, (dx2 * dz3 - dx3 * dz2) / det


@register
class PlanarCorrection(Module, PanelButtons, LcdSegment, ControlChannel):
    name = "PLANAR CORRECTION"
    button_priority = 60  # MS-85: after AUTOFOCUS, before RING BUFFER
    observable = "planar"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        #: points 1–3 in machine mm (x, y, physical z)
        self.points: dict[int, tuple[float, float, float]] = {}
        self.plane: Plane | None = None
        self.enabled = False
        #: the plane Z follows now (None: Z is not corrected); differs from the settings only
        #: between a restore and the reset that applies it
        self._active: Plane | None = None

    def _axes(self) -> tuple[Axis, Axis, Axis] | None:
        by_letter = {a.hw_letter: a for a in self.controller.axes}
        x, y, z = (by_letter.get(letter) for letter in "XYZ")
        return (x, y, z) if x is not None and y is not None and z is not None else None

    def _height_counts(self, plane: Plane | None, now: float) -> float:
        """c(x, y) at the current X, Y in Z encoder counts (MS-PC-2)."""
        axes = self._axes()
        if plane is None or axes is None:
            return 0.0
        x, y, z = axes
        dx = x.physical(now) / x.counts_per_mm - x.machine_mm_of_user(plane.x0)
        dy = y.physical(now) / y.counts_per_mm - y.machine_mm_of_user(plane.y0)
        return (plane.a * dx + plane.b * dy) * z.counts_per_mm

    def _follow(self, now: float) -> float:
        return self._height_counts(self._active, now)

    def _apply(self, plane: Plane | None, now: float) -> None:
        """Make Z follow `plane` (None: nothing) without moving: the commanded frame takes the
        difference (enable: commanded = physical − c; disable: commanded = physical)."""
        axes = self._axes()
        if axes is None:
            return
        z = axes[2]
        before = self._height_counts(self._active, now)
        self._active = plane
        z.follow = None if plane is None else self._follow
        z.reframe(now, before - self._height_counts(plane, now))

    def state(self) -> str:
        """LCD state character (MS-PC-3): next point to select, `Z` enabled, `G` defined."""
        if self.enabled:
            return "Z"
        if self.plane is not None or len(self.points) == 3:
            return "G"
        return next(str(n) for n in (1, 2, 3) if n not in self.points)

    # ---- the command --------------------------------------------------------------------------

    def handlers(self) -> dict[str, Handler]:
        return {"CCB": self.ccb}

    def ccb(self, call: Call) -> Reply:
        """CUSTOMB Z=1…7 (MS-PC-1); `CCB Z?` reads the state character [choice]."""
        items = [i for i in call.items if i.kind is not Kind.NUMBER]
        if not items:
            raise CommandError(ErrorCode.MISSING_PARAMETERS)
        first_error(
            ErrorCode.UNDEFINED if i.kind is Kind.MALFORMED else ErrorCode.BAD_AXIS
            for i in items
            if i.kind is Kind.MALFORMED or i.letter != "Z"
        )
        item = items[-1]  # a repeated letter: the last wins (MS-27)
        if item.kind is Kind.QUERY:
            return self.controller.render(call.key).items([("Z", self.state())])
        value = number(item)
        if value not in range(1, 8):
            raise CommandError(ErrorCode.OUT_OF_RANGE)
        if self._axes() is None:
            raise CommandError(ErrorCode.FAILED)  # no X, Y and Z to correct [choice]
        operation = int(value)
        if operation <= 3:
            self.store_point(operation, call.now)
        elif operation == FIT_AND_ENABLE:
            if not self.fit_and_enable(call.now):
                raise CommandError(ErrorCode.FAILED)
        elif operation == DISABLE:
            self.disable(call.now)
        elif operation == READ_PHYSICAL:
            return self.controller.render(call.key, Shape.A_LIST).items(
                [("", str(self.physical_units(call.now)))]
            )
        else:
            self.clear(call.now)
        return self.controller.ack()

    def physical_units(self, now: float) -> int:
        """Z's actual position in units, correction included (MS-PC-1, MS-PC-2)."""
        axes = self._axes()
        assert axes is not None
        z = axes[2]
        return round_half_away(z.user_mm_of(z.physical(now)) * z.s.unit_multiplier)

    # ---- operations, shared by commands and buttons -------------------------------------------

    def store_point(self, n: int, now: float) -> None:
        axes = self._axes()
        assert axes is not None
        x, y, z = axes
        self.points[n] = (
            x.physical(now) / x.counts_per_mm,
            y.physical(now) / y.counts_per_mm,
            z.physical(now) / z.counts_per_mm,
        )

    def fit_and_enable(self, now: float) -> bool:
        """Fit the plane through the three points (or keep a saved one when points are missing)
        and enable it; False with fewer than three points and no plane, or collinear points."""
        axes = self._axes()
        if axes is None:
            return False
        if len(self.points) == 3:
            tilt = fit([self.points[n] for n in (1, 2, 3)])
            if tilt is None:
                return False
            x1, y1, _ = self.points[1]
            x, y, _ = axes
            self.plane = Plane(*tilt, x.user_of_machine_mm(x1), y.user_of_machine_mm(y1))
        elif self.plane is None:
            return False
        self.enabled = True
        self._apply(self.plane, now)
        return True

    def disable(self, now: float) -> None:
        self.enabled = False
        if self._active is not None:
            self._apply(None, now)

    def clear(self, now: float) -> None:
        self.disable(now)
        self.points.clear()
        self.plane = None

    @on(Zeroing)
    def zeroing(self, event: Zeroing) -> None:
        """ZERO makes the plane's height 0 here, and everything here reads 0 (MS-PC-2): Z keeps its
        physical place, its commanded position takes what the correction was."""
        now = event.t
        if self.plane is None:
            return
        rereferenced = replace(self.plane, x0=0.0, y0=0.0)
        axes = self._axes()
        if self._active is not None and axes is not None:
            axes[2].reframe(now, self._height_counts(self._active, now))
            self._active = rereferenced
        self.plane = rereferenced

    # ---- buttons (MS-PC-4) --------------------------------------------------------------------

    def button_functions(self) -> dict[int, Callable[[float], None]]:
        return {FN_SELECT: self.select, FN_DISABLE: self.disable_or_reset}

    def button(self, name: str, press: str, now: float) -> bool:
        if name == "joystick" and press == EXTRA and not self.enabled:
            self.select(now)
            return True
        home_ms = HOME_MS_WITH_RING_BUFFER if "RING BUFFER" in self.controller.cfg.modules else HOME_MS
        if name == "home" and self.controller.button_held_ms >= home_ms:
            self.disable_or_reset(now)
            return True
        return False

    def select(self, now: float) -> None:
        """Select the next point (1 → 2 → 3 → enabled), or re-enable in state `G`."""
        state = self.state()
        if state in "123" and self._axes() is not None:
            self.store_point(int(state), now)
            if state == "3":
                self.fit_and_enable(now)
        elif state == "G":
            self.fit_and_enable(now)

    def disable_or_reset(self, now: float) -> None:
        if self.enabled:
            self.disable(now)
        else:
            self.clear(now)

    # ---- reports, SS Z, reset ------------------------------------------------------------------

    def lcd_segment(self, now: float) -> str | None:
        return self.state()

    def state_char(self) -> str | None:
        return self.state()  # shown in SEQUENCER's segment (MS-SEQ-8)

    def observe(self, now: float) -> Any:
        plane = self.plane
        return {
            "state": self.state(),
            "a": None if plane is None else plane.a,
            "b": None if plane is None else plane.b,
            "enabled": self.enabled,
            "points": sorted(self.points),
            "correction_counts": self._follow(now),
        }

    def save(self) -> dict[str, Any]:
        plane = self.plane
        if plane is None:
            return {"enabled": False}
        return {"a": plane.a, "b": plane.b, "x0": plane.x0, "y0": plane.y0, "enabled": self.enabled}

    def restore(self, data: dict[str, Any] | None) -> None:
        data = data or {}
        keys = ("a", "b", "x0", "y0")
        numbers = [
            float(v) for key in keys if isinstance(v := data.get(key), int | float) and finite_number(v)
        ]
        self.plane = Plane(*numbers) if len(numbers) == len(keys) else None
        self.enabled = data.get("enabled") is True and self.plane is not None

    @on(Reset)
    def reset(self, event: Reset) -> None:
        """Points are volatile; Z follows the restored plane if it is enabled. Positions come back
        in plane coordinates, so attaching it re-expresses nothing. A correction that goes is
        measured in the coordinates the reset has just set (the plane's height is 0 where they
        are 0, as after ZERO): Z ends at its commanded position [choice]."""
        now = event.t
        self.points.clear()
        wanted = self.plane if self.enabled else None
        if wanted is None and self._active is not None:
            self._apply(None, now)
        axes = self._axes()
        if wanted is not None and axes is not None:
            self._active = wanted
            axes[2].follow = self._follow
