"""All an axis may use of its controller (`model.Ms2000Device` implements it).

Generic in the axis type, so that this file needs no axis: `axis.Axis` holds an `AxisOwner[Axis]`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, TypeVar

if TYPE_CHECKING:
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.sections import Ms2000Knobs

A = TypeVar("A", contravariant=True)


class AxisOwner(Protocol[A]):
    """All an axis may use of its controller (`model.Ms2000Device` implements it)."""

    @property
    def knobs(self) -> Ms2000Knobs: ...

    @property
    def servo_s(self) -> float: ...

    def at(self, due: float, action: Callable[[float], None]) -> Timer: ...

    def log_error(self, code: int) -> None: ...

    def record_sample(self, axis: A, t: float) -> None:
        """A DUMP trajectory sample at a leg boundary (MS-108)."""

    def path_changed(self, axis: A, t: float) -> None:
        """The axis's planned path changed at `t` (a leg planned, a motion cut short): a `move`
        record for the traffic log (movelog.py)."""

    def positions_changed(self) -> None:
        """The axis came to rest or its coordinates changed: positions are due a save (MS-111)."""

    def axis_finished(self, axis: A, t: float) -> None:
        """A commanded move or home of this axis has ended (its move group may complete)."""

    def resume_manual(self, axis: A, t: float) -> None:
        """The axis is free again: the joystick takes it over if deflected (MS-83)."""

    def disable_motor(self, axis: A, t: float) -> None: ...

    def ensync_toggle(self) -> None:
        """The axis crossed its ENSYNC position (MS-95)."""
