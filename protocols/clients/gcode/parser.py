"""G-code text to a plan (MS-TRACER-5): the subset ASI's Tracer Console reads, FANUC style.

Supported: G00 (rapid), G01 (line at F), G02/G03 (clockwise / counter-clockwise arc with I/J/K
centre offsets, always relative to the arc's start, or radius R: positive up to half a turn,
negative beyond; same start and end with I/J/K is a full turn; a word on the normal axis makes a
helix), G04 P (dwell, ms), G15/G16 (polar off/on), G17/G18/G19 (XY/ZX/YZ plane), G20/G21 (inch/mm),
G90/G91 (absolute/incremental), M03/M05 (TTL output on/off), M02/M30 (end of program), F (per
minute, modal). Numbers are decimal ("calculator" input: `X1` is 1 mm, not 1 µm).

Choices where the subset leaves room [choice]:
- the program's origin is the stage's zero; the program starts where the stage is (`start`);
- power-on state G17 G21 G90 G15, no motion mode and no feed: an axis word before G00–G03, or a
  feed move before any F, is an error rather than a guess;
- polar (G16): the plane's first-axis word is the radius and the second-axis word the angle in
  degrees from the first axis (G17: X radius, Y angle). Under G90 the pole is the origin and an
  omitted radius or angle keeps the current position's; under G91 the pole is the current position
  and an omitted word is 0;
- M03 in a line with a move acts before the move, M05 after it (the output spans that move);
- N (sequence) and O (program) numbers and S (spindle speed: there is no spindle) are ignored;
- an I/J/K arc whose end lies off its circle by more than `ARC_RADIUS_TOLERANCE_MM` plus
  `ARC_RADIUS_TOLERANCE_SHARE` of the radius (program mm) is an error; within it the radius blends
  from start to end;
- the XYZ scale multiplies every length (a similarity about the origin); the speed scale multiplies
  F, not G00.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

from protocols.clients.gcode.plan import (
    AXES,
    EPSILON_MM,
    PLANES,
    Dwell,
    Move,
    Output,
    Plane,
    Point,
    Step,
    iter_arc_chords,
)

INCH_MM = 25.4
ARC_RADIUS_TOLERANCE_MM = 0.005
ARC_RADIUS_TOLERANCE_SHARE = 0.001
#: no word may exceed this in size (a 10 km coordinate is a typo, and keeps numbers finite)
MAX_VALUE = 1e6

_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\([^()]*\)")
_GROUPS = {
    0: "motion",
    1: "motion",
    2: "motion",
    3: "motion",
    4: "dwell",
    15: "polar",
    16: "polar",
    17: "plane",
    18: "plane",
    19: "plane",
    20: "units",
    21: "units",
    90: "distance",
    91: "distance",
}
_M_CODES = {3: "output on", 5: "output off", 2: "end", 30: "end"}
END_CODES = (2, 30)
_VALUE_WORDS = set("XYZIJKRFP")
_IGNORED_WORDS = set("NOS")


class GcodeError(ValueError):
    """A line the interpreter cannot run; `line` is 1-based."""

    def __init__(self, line: int, message: str) -> None:
        self.line = line
        self.message = message
        super().__init__(f"line {line}: {message}")


@dataclass
class Block:
    """One line's words: G codes by modal group, its M code, and the valued words."""

    line: int
    g: dict[str, int] = field(default_factory=dict)
    m: int | None = None
    words: dict[str, float] = field(default_factory=dict)


def read_block(number: int, text: str) -> Block | None:
    """The words of one line, or None for a line with nothing to do (blank, comment, `%`)."""
    text = _COMMENT.sub("", text.split(";", 1)[0])
    if "(" in text or ")" in text:
        raise GcodeError(number, "a comment '(' is not closed on its line (or ')' has no '(')")
    text = "".join(text.split()).upper()
    if not text or text.startswith("%"):
        return None
    block = Block(number)
    at = 0
    while at < len(text):
        match = _WORD.match(text, at)
        if match is None:
            raise GcodeError(number, f"cannot read {text[at : at + 12]!r}: expected a letter and a number")
        at = match.end()
        letter, digits = match.group(1), match.group(2)
        value = float(digits)
        if abs(value) > MAX_VALUE:
            raise GcodeError(number, f"{letter}{digits} is out of range (at most {MAX_VALUE:g})")
        if letter == "G":
            _add_g(block, value, f"G{digits}")
        elif letter == "M":
            if not value.is_integer() or int(value) not in _M_CODES:
                raise GcodeError(number, f"M{digits}: unsupported (M03, M05, M02, M30 are)")
            if block.m is not None:
                raise GcodeError(number, "only one M code per line")
            block.m = int(value)
        elif letter in _VALUE_WORDS:
            if letter in block.words:
                raise GcodeError(number, f"{letter} is given twice")
            block.words[letter] = value
        elif letter not in _IGNORED_WORDS:
            raise GcodeError(number, f"{letter}{digits}: unsupported")
    return block


def _add_g(block: Block, value: float, text: str) -> None:
    code = int(value) if value.is_integer() else None
    group = _GROUPS.get(code) if code is not None else None
    if code is None or group is None:
        supported = "G00-G04, G15-G21, G90, G91"
        raise GcodeError(block.line, f"{text}: unsupported ({supported} are)")
    if group in block.g or (group in ("motion", "dwell") and {"motion", "dwell"} & set(block.g)):
        raise GcodeError(block.line, f"{text} conflicts with another G code of its kind on the line")
    block.g[group] = code


@dataclass
class Interpreter:
    """Runs blocks against the modal state, yielding their steps; positions are stage mm. A block's
    steps are made as they are taken (an arc's chords one at a time), so its state moves with them:
    take them all before the next block."""

    position: Point = (0.0, 0.0, 0.0)
    xyz_scale: float = 1.0
    speed_scale: float = 1.0
    motion: int | None = None
    plane: Plane = PLANES[17]
    unit_mm: float = 1.0
    absolute: bool = True
    polar: bool = False
    feed_mm_s: float | None = None

    def run(self, block: Block) -> Iterator[Step]:
        g = block.g
        if "units" in g:
            self.unit_mm = INCH_MM if g["units"] == 20 else 1.0
        if "distance" in g:
            self.absolute = g["distance"] == 90
        if "plane" in g:
            self.plane = PLANES[g["plane"]]
        if "polar" in g:
            self.polar = g["polar"] == 16
        words = block.words
        if "F" in words:
            if words["F"] <= 0:
                raise GcodeError(block.line, f"feed rate F{words['F']:g} must be above 0")
            self.feed_mm_s = words["F"] * self.unit_mm / 60 * self.speed_scale
        if "motion" in g:
            self.motion = g["motion"]
        if block.m == 3:
            yield Output(True, block.line)
        if "dwell" in g:
            yield self._dwell(block)
        else:
            if "P" in words:
                raise GcodeError(block.line, "P belongs to G04 (dwell)")
            yield from self._motion(block)
        if block.m == 5:
            yield Output(False, block.line)

    # ---- dwell and motion ---------------------------------------------------------------------

    def _dwell(self, block: Block) -> Dwell:
        others = sorted(set(block.words) - {"P", "F"})
        if others:
            raise GcodeError(block.line, f"G04 takes only P (ms), not {', '.join(others)}")
        if "P" not in block.words or block.words["P"] < 0:
            raise GcodeError(block.line, "G04 needs P with the dwell time in ms (0 or more)")
        return Dwell(block.words["P"] / 1000, block.line)

    def _motion(self, block: Block) -> Iterator[Step]:
        words = block.words
        axis_words = [a for a in AXES if a in words]
        arc_words = [w for w in "IJKR" if w in words]
        if not axis_words and not arc_words:
            return
        if self.motion is None:
            raise GcodeError(block.line, f"{axis_words[0] if axis_words else arc_words[0]} without G00-G03")
        if arc_words and self.motion not in (2, 3):
            named = ", ".join(arc_words)
            raise GcodeError(block.line, f"{named} belong to G02/G03 arcs, not G0{self.motion}")
        end = self._target(block)
        if self.motion == 0:
            yield from self._segment(end, None, block.line)
        elif self.motion == 1:
            yield from self._segment(end, self._feed(block), block.line)
        else:
            yield from self._arc(block, end)
        self.position = end

    def _feed(self, block: Block) -> float:
        if self.feed_mm_s is None:
            raise GcodeError(block.line, f"no feed rate: give F before or with G0{self.motion}")
        return self.feed_mm_s

    def _segment(self, end: Point, feed: float | None, line: int) -> Iterator[Move]:
        move = Move(self.position, end, feed, line)
        if move.deltas():
            yield move

    # ---- coordinates --------------------------------------------------------------------------

    @property
    def length_mm(self) -> float:
        """Stage mm per program length unit."""
        return self.unit_mm * self.xyz_scale

    def _target(self, block: Block) -> Point:
        target = list(self.position)
        for i, letter in enumerate(AXES):
            if letter in block.words:
                value = block.words[letter] * self.length_mm
                target[i] = value if self.absolute else target[i] + value
        if self.polar:
            self._polar(block, target)
        return (target[0], target[1], target[2])

    def _polar(self, block: Block, target: list[float]) -> None:
        """G16: the plane's first-axis word is a radius, its second-axis word an angle (degrees)."""
        first, second = self.plane.first, self.plane.second
        radius_word, angle_word = AXES[first], AXES[second]
        here = (self.position[first], self.position[second])
        if self.absolute:
            pole = (0.0, 0.0)
            radius = math.hypot(*here)
            angle = math.degrees(math.atan2(here[1], here[0]))
        else:
            pole, radius, angle = here, 0.0, 0.0
        if radius_word in block.words:
            radius = block.words[radius_word] * self.length_mm
        angle = block.words.get(angle_word, angle)
        target[first] = pole[0] + radius * math.cos(math.radians(angle))
        target[second] = pole[1] + radius * math.sin(math.radians(angle))

    # ---- arcs ---------------------------------------------------------------------------------

    def _arc(self, block: Block, end: Point) -> Iterator[Move]:
        feed = self._feed(block)
        words = block.words
        plane = self.plane
        offsets = {AXES[plane.first]: "IJK"[plane.first], AXES[plane.second]: "IJK"[plane.second]}
        stray = [w for w in "IJK" if w in words and w not in offsets.values()]
        if stray:
            raise GcodeError(block.line, f"{stray[0]} is not an offset in the G{plane.code} plane")
        has_offsets = any(w in words for w in offsets.values())
        if "R" in words and has_offsets:
            raise GcodeError(block.line, "give the arc either R or I/J/K, not both")
        if "R" in words:
            centre = self._centre_from_radius(block, end)
        elif has_offsets:
            centre = self._centre_from_offsets(block, end)
        else:
            raise GcodeError(block.line, f"G0{self.motion} needs I/J/K (centre) or R (radius)")
        for point in iter_arc_chords(self.position, end, centre, plane, clockwise=self.motion == 2):
            yield from self._segment(point, feed, block.line)
            self.position = point

    def _in_plane(self, point: Point) -> tuple[float, float]:
        return point[self.plane.first], point[self.plane.second]

    def _centre_from_offsets(self, block: Block, end: Point) -> tuple[float, float]:
        su, sv = self._in_plane(self.position)
        first, second = "IJK"[self.plane.first], "IJK"[self.plane.second]
        centre = (
            su + block.words.get(first, 0.0) * self.length_mm,
            sv + block.words.get(second, 0.0) * self.length_mm,
        )
        r_start = math.dist((su, sv), centre)
        r_end = math.dist(self._in_plane(end), centre)
        if r_start <= EPSILON_MM:
            raise GcodeError(block.line, "the arc's centre is its start point (radius 0)")
        # compared in program mm: the tolerance is about how CAM rounds, whatever the XYZ scale
        start_mm, end_mm = r_start / self.xyz_scale, r_end / self.xyz_scale
        if abs(end_mm - start_mm) > ARC_RADIUS_TOLERANCE_MM + ARC_RADIUS_TOLERANCE_SHARE * start_mm:
            raise GcodeError(
                block.line,
                f"the end point is {abs(end_mm - start_mm):.4f} mm off the arc's circle "
                f"(radius {start_mm:.4f} mm at the start, {end_mm:.4f} mm at the end)",
            )
        return centre

    def _centre_from_radius(self, block: Block, end: Point) -> tuple[float, float]:
        """R > 0: the shorter arc (at most half a turn), R < 0: the longer one."""
        radius = block.words["R"] * self.length_mm
        (su, sv), (eu, ev) = self._in_plane(self.position), self._in_plane(end)
        chord = math.dist((su, sv), (eu, ev))
        if chord <= EPSILON_MM:
            raise GcodeError(block.line, "R cannot describe a full circle: use I/J/K")
        if abs(radius) <= EPSILON_MM:
            raise GcodeError(block.line, "arc radius R must not be 0")
        half = chord / 2
        shortfall = half - abs(radius)
        if shortfall > ARC_RADIUS_TOLERANCE_MM * self.xyz_scale:
            raise GcodeError(
                block.line,
                f"radius R{block.words['R']:g} is too small to reach the end point "
                f"({chord / self.length_mm:.4f} away)",
            )
        rise = math.sqrt(max(0.0, radius * radius - half * half))
        # the centre lies left of start->end for a short counter-clockwise arc; each of clockwise
        # and a negative R (the long way round) moves it to the other side
        side = 1.0 if self.motion == 3 else -1.0
        if radius < 0:
            side = -side
        du, dv = (eu - su) / chord, (ev - sv) / chord
        return (su + eu) / 2 - side * rise * dv, (sv + ev) / 2 + side * rise * du


def parse_program(
    text: str, *, start: Point = (0.0, 0.0, 0.0), xyz_scale: float = 1.0, speed_scale: float = 1.0
) -> list[Step]:
    """The plan of a whole program starting at `start` (stage mm); raises `GcodeError` naming the
    first line it cannot run. Lines after M02/M30 are not read."""
    return list(iter_program(text.splitlines(), start=start, xyz_scale=xyz_scale, speed_scale=speed_scale))


def iter_program(
    lines: Iterable[str], *, start: Point = (0.0, 0.0, 0.0), xyz_scale: float = 1.0, speed_scale: float = 1.0
) -> Iterator[Step]:
    """`parse_program` of the program's lines (numbered from 1), a step at a time as the lines are
    read: a program of any length is planned in constant memory."""
    for name, value in (("xyz_scale", xyz_scale), ("speed_scale", speed_scale)):
        if not math.isfinite(value) or value <= 0:
            raise ValueError(f"{name} must be a finite number above 0, got {value!r}")
    interpreter = Interpreter(start, xyz_scale, speed_scale)
    for block in iter_blocks(lines):
        yield from interpreter.run(block)


def read_program(text: str) -> list[Block]:
    """Every line's words up to M02/M30, checked for what can be checked without running them (a
    program can be refused before a port is opened)."""
    return list(iter_blocks(text.splitlines()))


def iter_blocks(lines: Iterable[str]) -> Iterator[Block]:
    """`read_program` of the program's lines (numbered from 1), a block at a time."""
    for number, line in enumerate(lines, start=1):
        block = read_block(number, line)
        if block is not None:
            yield block
            if block.m in END_CODES:
                return
