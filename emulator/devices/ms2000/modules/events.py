"""What happens in the controller that modules may follow: typed, frozen events, one class each.

A module subscribes by decorating a method with `@on(EventClass)`; the method takes the event. The
controller's `ModuleSet` builds its table (event class -> handlers, in the profile's module order)
once, at construction, and `emit()` calls exactly the handlers of the event's class. A module sends
an event to the others through `ModuleOwner.emit()`: a new interaction between two modules is one
class here, an `emit` in one and an `@on` in the other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar


@dataclass(frozen=True)
class Event:
    #: device time of the event
    t: float


@dataclass(frozen=True)
class Reset(Event):
    """Software reset or power-up (MS-112): state machines back to idle. Sent after every module's
    `restore()` and once axes, buttons and low-level mode are idle; OUT0 is re-applied after it."""


@dataclass(frozen=True)
class Halt(Event):
    """HALT (MS-76), after every axis stopped: stop whatever the module is running."""


@dataclass(frozen=True)
class MoveComplete(Event):
    """A commanded move completed, after the base effects (control event, `VB X` lines, OUT0 pulse)."""

    #: letters of the axes it moved to the end, in landing order
    axes: tuple[str, ...]


@dataclass(frozen=True)
class Zeroing(Event):
    """ZERO or the zero button is about to make every axis read 0 (PLANAR CORRECTION re-references
    its plane here, MS-PC-2)."""


@dataclass(frozen=True)
class In0Edge(Event):
    """An IN0 rising edge with the TTL inputs enabled, whatever the IN0 mode, after the mode's own
    function (SEQUENCER's TTL_TRIGGER_RECEIVED, MS-SEQ-2)."""


@dataclass(frozen=True)
class In0ModeChanged(Event):
    """`TTL X` was set (to any mode, the same one included)."""

    mode: int


@dataclass(frozen=True)
class Out0ModeChanged(Event):
    """`TTL Y` was set (to any mode); OUT0 is re-applied after every handler ran."""

    mode: int


@dataclass(frozen=True)
class TtlTrailingValue(Event):
    """A bare number after `TTL Y=<out_mode>` (MS-24, MS-LED-3)."""

    out_mode: int
    value: float


@dataclass(frozen=True)
class ArrayArrival(Event):
    """ARRAY reached a cell (SEQUENCER's ARRAY_MOVE_DONE, MS-ARRAY-8)."""


@dataclass(frozen=True)
class RmX(Event):
    """`RM X=value` was accepted (after RING BUFFER cleared itself for 0), or SEQUENCER starts
    ARRAY's stepping the same way (MS-RB-4, MS-ARRAY-6)."""

    value: int


Method = TypeVar("Method", bound=Callable[..., None])

#: the attribute `on` marks a method with
MARK = "__ms2000_event__"


def on(kind: type[Event]) -> Callable[[Method], Method]:
    """Subscribe the decorated method (`def handler(self, event: kind) -> None`) to `kind`."""

    def mark(method: Method) -> Method:
        setattr(method, MARK, kind)
        return method

    return mark


def subscriptions(cls: type) -> dict[type[Event], str]:
    """Event class -> name of the method of `cls` subscribed to it, inherited subscriptions included:
    a subclass's `@on` method for an event class replaces its base's, and a method that overrides a
    subscribed one without `@on` stays subscribed (by name)."""
    table: dict[type[Event], str] = {}
    for klass in reversed(cls.__mro__):
        own: dict[type[Event], str] = {}
        for name, member in vars(klass).items():
            kind: Any = getattr(member, MARK, None)
            if kind is None:
                continue
            if kind in own:
                raise TypeError(f"{klass.__name__}: two handlers of {kind.__name__}")
            own[kind] = name
        table.update(own)
    return table
