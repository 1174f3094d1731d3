"""What a capture learns and what it sends: `Query` (a read-only command as sent), `Reading` (one
profile field and the value a reply gave it), `Transcript` (what was sent and the notes a profile
keeps as comments), and the errors that end a capture.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from emulator.profiles.describe import plain
from emulator.profiles.profile import Profile

#: a profile field's place: ("axes", "X", "speed_mm_s"), ("knobs", "reply_shape_overrides", "OS")
FieldPath = tuple[str, ...]
#: the longest reply text a note quotes
NOTE_QUOTE = 100


class CaptureError(Exception):
    """The capture cannot go on (the port, the first reply, the output file): one line, exit 1."""


class CaptureBug(Exception):
    """What was read gives a profile that does not validate: a bug of the capture (exit 2)."""


@dataclass(frozen=True)
class Query:
    """One read-only command: `label` names it in notes and in `--dry-run`, `wire` is every byte
    sent, `reply_chars` the longest reply expected (a read waits its wire time on top of the
    timeout: an INFO report takes over a second at 9600 baud)."""

    label: str
    wire: bytes
    reply_chars: int = 80


def _at_path(profile: Profile[Any], path: FieldPath) -> Any:
    """The value at `path` in `profile` as `describe` shows it (None where there is no such key)."""
    value: Any = plain(profile.config)
    for part in path:
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


def _differs(actual: Any, observed: Any) -> int:
    return 0 if actual == observed else 1


@dataclass(frozen=True)
class Reading:
    """A profile field learnt from a reply. `value` is what the profile file gets when the closest
    bundled profile differs; a loaded profile matches the reading when `actual(profile)` equals
    `observed` (by default the value at `path` and `value` itself; a field the device reports in
    another form, like the MP-285 status template or the MS2000 overshoot in whole counts, gives
    both). `weight` × `distance` ranks the bundled profiles (build, modules and axes weigh most);
    `captured` is False for what the capture sets itself (`device_id`)."""

    path: FieldPath
    value: Any
    source: str
    observed: Any = None
    actual: Callable[[Profile[Any]], Any] | None = None
    weight: int = 1
    distance: Callable[[Any, Any], int] = _differs
    captured: bool = True

    @property
    def dotted(self) -> str:
        return ".".join(self.path)

    def seen(self) -> Any:
        return self.value if self.actual is None else self.observed

    def actual_in(self, profile: Profile[Any]) -> Any:
        return _at_path(profile, self.path) if self.actual is None else self.actual(profile)

    def matches(self, profile: Profile[Any]) -> bool:
        return self.actual_in(profile) == self.seen()

    def cost(self, profile: Profile[Any]) -> int:
        return self.weight * self.distance(self.actual_in(profile), self.seen())


def quoted(reply: bytes | str) -> str:
    """A reply as a note shows it: one line, ASCII, escapes for control bytes, clipped."""
    text = reply.decode("latin-1") if isinstance(reply, bytes) else reply
    shown = ascii(text)
    return shown if len(shown) <= NOTE_QUOTE else shown[: NOTE_QUOTE - 2] + "…'"


@dataclass
class Transcript:
    """Every query sent, in order, and the notes the profile keeps as comments. `allowed` is the
    family's read-only check: a query it refuses is never sent."""

    allowed: Callable[[Query], bool]
    sent: list[Query] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def check(self, query: Query) -> None:
        if not self.allowed(query):
            raise CaptureBug(f"refusing to send {query.label!r}: not a read-only command")
        self.sent.append(query)

    def note(self, text: str) -> None:
        self.notes.append(text)

    def not_understood(self, query: Query, reply: bytes | str) -> None:
        self.note(f"{query.label} replied {quoted(reply)} — not understood")

    def no_reply(self, query: Query, timeout: float, partial: bytes = b"") -> None:
        got = f" (only {quoted(partial)})" if partial else ""
        self.note(f"{query.label}: no reply within {timeout:.3g} s{got}")
