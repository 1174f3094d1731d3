"""What every command group shares: the controller, reply rendering, item collection."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.axis import Axis
from emulator.devices.ms2000.calls import (
    Call,
    Param,
    Pending,
    Reply,
    axis_items,
    run_settings,
)
from protocols.ms2000 import Fmt, Item, Shape

if TYPE_CHECKING:
    from emulator.devices.ms2000.model import Ms2000Device

Handler = Callable[[Call], "Reply | Pending"]


class CommandSet:
    """Helpers of the command handlers; the handlers themselves live in the sibling modules."""

    def __init__(self, ctl: Ms2000Device) -> None:
        self.ctl = ctl

    @property
    def _order(self) -> str:
        return "".join(a.letter for a in self.ctl.axes)

    def _settings(self, call: Call, params: dict[str, Param], order: str | None = None) -> Reply:
        ctl = self.ctl
        return run_settings(call, params, order or self._order, ctl.render(call.key), ctl.ack())

    def _per_axis(
        self,
        get: Callable[[Axis], Any],
        set_: Callable[[Axis, float], None] | None = None,
        check: Callable[[Axis, float], float] | None = None,
        fmt: Fmt = Fmt.F6,
        plus: Callable[[Axis], None] | None = None,
        minus: Callable[[Axis], None] | None = None,
    ) -> dict[str, Param]:
        params = {}
        for a in self.ctl.axes:
            params[a.letter] = Param(
                get=partial(get, a),
                set=partial(set_, a) if set_ else None,
                check=partial(check, a) if check else (lambda v: v),
                fmt=fmt,
                plus=partial(plus, a) if plus else None,
                minus=partial(minus, a) if minus else None,
            )
        return params

    def _axis_items(self, call: Call, require: bool = True) -> list[tuple[Axis, Item]]:
        return axis_items(call, self.ctl.axes, require)

    def _list(self, call: Call, values: list[str]) -> Reply:
        return self.ctl.render(call.key, Shape.A_LIST).items(("", v) for v in values)
