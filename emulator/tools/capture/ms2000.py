"""Capturing an ASI MS2000: identity, build, axes and settings read with query commands only.

Every line sent is in `plan` (for a build's own axes): `V`, `BU X`, `CD`, `N`, `SB X?`, one query
per axis setting naming every motor axis (`S X? Y? Z?`), `I` of the first axis and of a letter
that is not an axis, `RB` of the first axis, `JS F?` (builds without XY KNOBS) and an empty line.
`is_read_only` admits nothing else: query items (`L?`) of the commands in `QUERY_KEYS` only (never
`Z X?`, whose ZERO ignores its items, nor `EX M?`, which clears the button flags), and the bare
reports `V`, `CD`, `N`, `BU X`, `I L`, `RB L`.

Values are those in force when read: the saved settings (`SS Z`) after a power-up, or whatever a
host set since. They map to the profile's factory fields (docs/capture.md has the table); how
each reply is read is emulator/tools/capture/ms2000_replies.py.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from emulator.devices.ms2000.schema import BAUDS, MAX_SPEED_PER_MM_PITCH, Ms2000Axis
from emulator.profiles.profile import Profile
from emulator.profiles.schema import default_of, schema_fields
from emulator.tools.capture.readings import Query, Reading, Transcript
from emulator.tools.capture.wire import LineOptions
from protocols.ms2000 import CR, Kind, parse_items, split_command

NAME = "ms2000"
DEFAULT_AXES = ("X", "Y", "Z")
#: MS-2: the baud rate is the DIP switches SW4 and SW5
SWITCHES = {baud: switches for switches, baud in BAUDS.items()}
RING_BUFFER = "RING BUFFER"
CRISP_NAMES = ("CRISP", "CRIFF")  # MS-102: the CRISP module's line, by knob crisp_directive_name
#: letters tried for an INFO of a letter that is not a motor axis (MS-107)
NOT_AXIS_LETTERS = "FTRZYX"
#: the longest replies: BU X (a dozen module lines), INFO (21 rows of about 50 characters)
BUILD_CHARS = 400
INFO_CHARS = 1200


@dataclass(frozen=True)
class AxisSetting:
    """A per-axis setting: its command, the `axes.<L>` field it gives, integer or not."""

    key: str
    field: str
    integer: bool = False


#: in this order: C first, the overshoot is read in whole counts of it (MS-58)
AXIS_SETTINGS = (
    AxisSetting("C", "counts_per_mm"),
    AxisSetting("S", "speed_mm_s"),
    AxisSetting("AC", "accel_ms", True),
    AxisSetting("WT", "wait_ms", True),
    AxisSetting("B", "backlash_mm"),
    AxisSetting("OS", "overshoot_mm"),
    AxisSetting("E", "drift_error_mm"),
    AxisSetting("PC", "finish_error_mm"),
    AxisSetting("MA", "maintain", True),
    AxisSetting("RU", "runaway_mm"),
    AxisSetting("KP", "kp", True),
    AxisSetting("KI", "ki", True),
    AxisSetting("KD", "kd", True),
    AxisSetting("KV", "kv", True),
    AxisSetting("KA", "ka", True),
    AxisSetting("AA", "aa", True),
    AxisSetting("D", "dac_mm_s"),
    AxisSetting("UM", "unit_multiplier"),
    AxisSetting("SL", "soft_lower_mm"),
    AxisSetting("SU", "soft_upper_mm"),
    AxisSetting("HM", "home_mm"),
    AxisSetting("J", "input_device", True),
    AxisSetting("LL", "ll_id", True),
)
#: commands whose query form only reads
QUERY_KEYS = frozenset({s.key for s in AXIS_SETTINGS} | {"SB", "JS"})
#: reports with their own bare form: `V`, `CD`, `N` take no items; `BU X`; `I L`, `RB L`
BARE_REPORTS = frozenset({"V", "CD", "N"})


def line_problem(line: LineOptions) -> str | None:
    """Why the MS2000 cannot be opened at `line` (MS-1, MS-2), or None."""
    if line.baud not in SWITCHES:
        return f"--baud {line.baud}: the MS2000 runs at {', '.join(map(str, sorted(SWITCHES)))} (MS-2)"
    if line.parity != "none":
        return "--parity: the MS2000 runs without parity (MS-1)"
    if line.stop_bits not in (1, 2):
        return "--stop-bits: the MS2000 uses 1 or 2 stop bits (MS-3)"
    if line.rtscts:
        return "--rtscts: the MS2000 has no flow control (MS-1)"
    return None


def _query(line: str, reply_chars: int = 80) -> Query:
    return Query(line or "(empty line)", line.encode("ascii") + CR, reply_chars)


VERSION = _query("V")
BUILD = _query("BU X", BUILD_CHARS)
EMPTY = _query("")
FIRST = (VERSION, BUILD)


def not_an_axis(axes: Sequence[str]) -> str:
    return next(letter for letter in NOT_AXIS_LETTERS if letter not in axes)


def rest(axes: Sequence[str], modules: Sequence[str]) -> list[Query]:
    """What follows `FIRST` for a build with these motor axes and modules."""
    letters = " ".join(f"{a}?" for a in axes)
    queries = [_query("CD"), _query("N"), _query("SB X?")]
    if axes:
        queries += [_query(f"{s.key} {letters}") for s in AXIS_SETTINGS]
        queries += [_query(f"I {axes[0]}", INFO_CHARS), _query(f"RB {axes[0]}")]
    if "XY KNOBS" not in modules:
        queries.append(_query("JS F?"))
    return [*queries, _query(f"I {not_an_axis(axes)}"), EMPTY]


def plan() -> list[Query]:
    """Every query, in order, for an XYZ build without XY KNOBS (`--dry-run`)."""
    return [*FIRST, *rest(DEFAULT_AXES, ())]


DRY_RUN_NOTES = (
    "each line ends with CR; the per-axis queries name every motor axis BU X lists (here X Y Z)",
    "I and RB name the first motor axis, `I F` a letter that is not a motor axis",
    "JS F? is sent only to builds without XY KNOBS",
)


def is_read_only(query: Query) -> bool:
    """Only the reads `rest` and `FIRST` make: never a move, a set, a save or a reset."""
    body = query.wire[:-1]
    if not query.wire.endswith(CR) or any(not 0x20 <= byte <= 0x7E for byte in body):
        return False
    line = body.decode("ascii")
    if not line.strip(" "):
        return True
    command = split_command(line)
    if command.spec is None:
        return False
    key = command.spec.key
    items = parse_items(command.args)
    kinds = {item.kind for item in items}
    letters = [item.letter for item in items]
    if key in QUERY_KEYS:
        return kinds == {Kind.QUERY}
    if key in BARE_REPORTS:
        return not items
    if key == "BU":
        return kinds == {Kind.BARE} and letters == ["X"]
    return key in ("I", "RB") and kinds == {Kind.BARE} and len(items) == 1


def _default_max_speed() -> float:
    """An axis entry's `max_speed_mm_s` when the profile names no pitch (MS-54)."""
    fields = {f.name: f for f in schema_fields(Ms2000Axis)}
    return float(round(default_of(fields["pitch_mm"]) * MAX_SPEED_PER_MM_PITCH, 6))


def caveats(parent: Profile[Any]) -> list[str]:
    """What the header says of values read as they are now, not as saved."""
    return [
        "Settings are those in force when read: saved ones (SS Z) after a power-up, else as a host",
        "left them; SL, SU and HM are read from the current origin (MS-49), moved by HERE and ZERO.",
    ]


def amend(parent: Profile[Any], readings: list[Reading], transcript: Transcript) -> list[Reading]:
    """MS-54: a speed above the closest profile's maximum for that axis raises the maximum to it:
    the real maximum is read back only after setting a huge speed, which a capture never does."""
    extra = []
    for reading in readings:
        if reading.path[0] != "axes" or reading.path[2] != "speed_mm_s":
            continue
        axis = reading.path[1]
        entry = parent.config.axes.get(axis)
        highest = entry.max_speed_mm_s if entry is not None else _default_max_speed()
        if reading.value > highest:
            path = ("axes", axis, "max_speed_mm_s")
            extra.append(Reading(path, reading.value, reading.source, captured=False))
            transcript.note(
                f"{reading.source}: {axis} runs at {reading.value:g} mm/s, above {parent.name}'s "
                f"maximum {highest:g}: max_speed_mm_s raised to it (the real maximum is not readable)"
            )
    return readings + extra
