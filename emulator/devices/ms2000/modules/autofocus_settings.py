"""AUTOFOCUS's settings commands: `AF` parameters, `AFC` parameters, `AFADJ`, `AL`, `AM` and the
`AFINFO` report (MS-AF-1, MS-AF-5…MS-AF-8).

`AF` and `AFADJ` are saved by `SS Z` (the reference says so); `AFC`, `AL` and `AM` settings are
volatile, back at their factory values after a reset or power-up (it says nothing of saving them).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from emulator.devices.ms2000.calls import (
    Call,
    CommandError,
    Param,
    Rendered,
    Reply,
    one_of,
    run_settings,
    within,
)
from emulator.devices.ms2000.modules.autofocus_curve import SATURATED, Adjust
from protocols.ms2000 import ErrorCode, Fmt, format_value

NORMAL_MODE, HILL_MODE = 0, 1  # AF Z (2 and 3 are reserved, MS-AF-1)
MAX_RANGE_MM = 20.0  # [choice] the Z travel of the profiles
#: AL X and Y both this or more are refused (MS-AF-5)
AREA_REFUSED = 90
FACTORY_AF: dict[str, float] = {"speed": 2, "range": 0.1, "mode": NORMAL_MODE, "hill": 50}
FACTORY_AREA: dict[str, float] = {"x": 80, "y": 50, "safety": 1}


def _setter(values: dict[str, float], key: str) -> Callable[[float], None]:
    return lambda v: values.__setitem__(key, v)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


@dataclass
class AfSettings:
    #: PZ builds drive a piezo focus axis (MS-DAC-3): another factory frame offset (MS-AF-6)
    piezo: bool
    af: dict[str, float] = field(default_factory=lambda: dict(FACTORY_AF))
    adjust: Adjust = field(default_factory=Adjust)
    calib: dict[str, float] = field(default_factory=dict)
    area: dict[str, float] = field(default_factory=dict)
    on_move: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.volatile_factory()

    def volatile_factory(self) -> None:
        self.calib = {"contrast": 18, "offset": 3.75 if self.piezo else 3.5, "axis": 0}
        self.area = dict(FACTORY_AREA)
        self.on_move = {"x": 0, "y": 0}

    # ---- SS Z ---------------------------------------------------------------------------------

    def save(self) -> dict[str, Any]:
        return {"af": dict(self.af), "adjust": asdict(self.adjust)}

    def restore(self, data: dict[str, Any] | None) -> None:
        data = data or {}
        self.af = dict(FACTORY_AF)
        saved_af = data.get("af")
        if isinstance(saved_af, dict):
            self.af.update({k: v for k, v in saved_af.items() if k in FACTORY_AF and _is_number(v)})
        fields = asdict(Adjust())
        saved_adjust = data.get("adjust")
        if isinstance(saved_adjust, dict):
            fields.update({k: v for k, v in saved_adjust.items() if k in fields and isinstance(v, int)})
        self.adjust = Adjust(**fields)
        self.volatile_factory()

    # ---- commands -----------------------------------------------------------------------------

    def af_command(self, call: Call, render: Rendered, ack: Reply) -> Reply:
        """AF: X speed % of the axis maximum, Y range mm, Z mode, F hill offset % (MS-AF-1)."""
        af = self.af
        params = {
            "X": Param(lambda: af["speed"], _setter(af, "speed"), within(0, 100, integer=True)),
            "Y": Param(lambda: af["range"], _setter(af, "range"), within(0, MAX_RANGE_MM), Fmt.F6),
            "Z": Param(lambda: af["mode"], _setter(af, "mode"), one_of(NORMAL_MODE, HILL_MODE)),
            "F": Param(lambda: af["hill"], _setter(af, "hill"), within(0, 100, integer=True)),
        }
        return run_settings(call, params, "XYZF", render, ack)

    def calib_command(self, call: Call, render: Rendered, ack: Reply) -> Reply:
        """AFC: X minimum contrast, Y frame offset (stored only), F axis (stored only) (MS-AF-6)."""
        calib = self.calib
        params = {
            "X": Param(
                lambda: calib["contrast"], _setter(calib, "contrast"), within(0, SATURATED, integer=True)
            ),
            "Y": Param(lambda: calib["offset"], _setter(calib, "offset"), within(0, 100), Fmt.F6),
            "F": Param(lambda: calib["axis"], _setter(calib, "axis"), within(0, 3, integer=True)),
        }
        return run_settings(call, params, "XYF", render, ack)

    def adjust_command(self, call: Call, render: Rendered, ack: Reply) -> Reply:
        """AFADJ: X zero, Y amplitude (0–100), Z gain (0–3) (MS-AF-7)."""
        values = asdict(self.adjust)

        def setter(key: str) -> Callable[[float], None]:
            return lambda v: values.__setitem__(key, int(v))

        params = {
            "X": Param(lambda: values["zero"], setter("zero"), within(0, 100, integer=True)),
            "Y": Param(lambda: values["amplitude"], setter("amplitude"), within(0, 100, integer=True)),
            "Z": Param(lambda: values["gain"], setter("gain"), within(0, 3, integer=True)),
        }
        reply = run_settings(call, params, "XYZ", render, ack)
        self.adjust = Adjust(**values)
        return reply

    def area_command(self, call: Call, render: Rendered, ack: Reply) -> Reply:
        """AL: X, Y highlighted area (0–100), Z safety limit on/off (MS-AF-5). X and Y both 90 or
        more are refused with `:N-5`, as ASI's page shows, and change nothing [choice]."""
        staged = dict(self.area)
        params = {
            "X": Param(lambda: staged["x"], _setter(staged, "x"), within(0, 100, integer=True)),
            "Y": Param(lambda: staged["y"], _setter(staged, "y"), within(0, 100, integer=True)),
            "Z": Param(lambda: staged["safety"], _setter(staged, "safety"), one_of(0, 1)),
        }
        reply = run_settings(call, params, "XYZ", render, ack)
        if staged["x"] >= AREA_REFUSED and staged["y"] >= AREA_REFUSED:
            raise CommandError(ErrorCode.FAILED)
        self.area = staged
        return reply

    def move_command(self, call: Call, render: Rendered, ack: Reply) -> Reply:
        """AM: X=1 autofocus after every commanded XY move, Y safe turret (stored) (MS-AF-8)."""
        on_move = self.on_move
        params = {
            "X": Param(lambda: on_move["x"], _setter(on_move, "x"), one_of(0, 1)),
            "Y": Param(lambda: on_move["y"], _setter(on_move, "y"), one_of(0, 1)),
        }
        return run_settings(call, params, "XY", render, ack)

    def info(self, last_max: int, start: str, final: str) -> Reply:
        """AFINFO: the settings and the last run, one bare line each (MS-AF-7)."""
        af, calib = self.af, self.calib
        return Reply.text(
            f"Speed: {format_value(af['speed'], Fmt.I)} %",
            f"Range: {format_value(af['range'], Fmt.F6)} mm",
            f"Mode: {'Hill' if af['mode'] == HILL_MODE else 'Normal'}",
            f"Hill offset: {format_value(af['hill'], Fmt.I)} %",
            f"Min contrast: {format_value(calib['contrast'], Fmt.I)}",
            f"Frame offset: {format_value(calib['offset'], Fmt.F6)}",
            f"Last max focus: {last_max}",
            f"Start pos: {start}",
            f"Final pos: {final}",
        )
