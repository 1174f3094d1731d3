"""The G-code interpreter's parser and arc chording (MS-TRACER-5), without a port: units, distance
modes, polar coordinates, planes, arcs and their 0.5 µm sagitta bound, scale factors, errors."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocols.clients.gcode import (
    SAGITTA_MM,
    Dwell,
    GcodeError,
    Move,
    Output,
    Step,
    chord_count,
    parse_program,
    read_program,
)
from protocols.clients.gcode.plan import PLANES, arc_chords


def moves(steps: list[Step]) -> list[Move]:
    return [s for s in steps if isinstance(s, Move)]


def end_of(steps: list[Step]) -> tuple[float, float, float]:
    return moves(steps)[-1].end


def approx(point: tuple[float, float, float]) -> object:
    return pytest.approx(point, abs=1e-9)


def max_arc_distance_from_chord(
    start: tuple[float, float], end: tuple[float, float], centre: tuple[float, float], samples: int = 64
) -> float:
    """Largest distance between the arc from `start` to `end` (the short way, about `centre`) and the
    chord joining them, found by sampling the arc."""
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    sweep = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
    radius = math.dist(start, centre)
    dx, dy = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dx, dy)
    worst = 0.0
    for i in range(samples + 1):
        angle = a0 + sweep * i / samples
        px, py = centre[0] + radius * math.cos(angle), centre[1] + radius * math.sin(angle)
        worst = max(worst, abs((px - start[0]) * dy - (py - start[1]) * dx) / length)
    return worst


# ---- TV-203 and the basics ----------------------------------------------------------------------


def test_tv_203_line_at_feed_plans_one_move() -> None:
    """TV-203 (MS-TRACER-5): `G21 G90 G01 X1 F60` is one move to X = 1 mm at 1 mm/s, all of it X's."""
    [move] = parse_program("G21 G90 G01 X1 F60")
    assert move == Move((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 1.0, 1)
    assert move.axis_speeds() == {"X": 1.0}


def test_feed_split_into_axis_components() -> None:
    """MS-TRACER-5: per-axis `S` are the components of the feed vector."""
    [move] = parse_program("G01 X3 Y4 F300")
    assert move.axis_speeds() == pytest.approx({"X": 3.0, "Y": 4.0})
    assert move.deltas() == {"X": 3.0, "Y": 4.0}


def test_rapid_has_no_feed_and_ignores_f() -> None:
    [move] = parse_program("G00 X1 Y-2 F60")
    assert move.feed_mm_s is None and move.axis_speeds() == {}


def test_inch_and_mm_g20_g21() -> None:
    """G20: lengths and F in inches; G21 back to mm."""
    steps = parse_program("G20 G01 X1 F60\nG21 X1")
    assert [m.end[0] for m in moves(steps)] == pytest.approx([25.4, 1.0])
    assert moves(steps)[0].feed_mm_s == pytest.approx(25.4)
    # F keeps the speed it was given in: inches per minute stay so after G21
    assert moves(steps)[1].feed_mm_s == pytest.approx(25.4)


def test_absolute_and_incremental_g90_g91() -> None:
    steps = parse_program("G91 G01 X1 F60\nX1 Y-1\nG90 X0.5\nZ2", start=(5.0, 0.0, 0.0))
    assert [m.end for m in moves(steps)] == [
        approx((6.0, 0.0, 0.0)),
        approx((7.0, -1.0, 0.0)),
        approx((0.5, -1.0, 0.0)),
        approx((0.5, -1.0, 2.0)),
    ]


def test_modal_motion_and_mode_only_lines() -> None:
    """A line with only G codes sets modes; later axis words use the last motion mode."""
    steps = parse_program("G01 F120\nX1\nG00\nY1")
    assert [(m.end, m.feed_mm_s) for m in moves(steps)] == [
        (approx((1.0, 0.0, 0.0)), 2.0),
        (approx((1.0, 1.0, 0.0)), None),
    ]


def test_zero_length_moves_are_dropped() -> None:
    assert parse_program("G01 X0 Y0 F60") == []


def test_text_forms_comments_and_ignored_words() -> None:
    """Spaces anywhere (`Z- .1`), lower case, `( )` and `;` comments, `%`, N/O numbers, S."""
    program = "%\nO1000\nN10 g21 (metric) g90\nN20 G1 Z- .1 F 60 ; plunge\nN30 S1000 M3\n%\n"
    steps = parse_program(program)
    assert steps == [Move((0.0, 0.0, 0.0), (0.0, 0.0, -0.1), 1.0, 4), Output(True, 5)]


def test_dwell_and_outputs_in_order() -> None:
    """M03 acts before the move of its line, M05 after it; G04 P is milliseconds."""
    steps = parse_program("G01 F60\nM03 X1\nG04 P250\nX2 M05")
    assert [type(s).__name__ for s in steps] == ["Output", "Move", "Dwell", "Move", "Output"]
    assert steps[2] == Dwell(0.25, 3)
    assert (steps[0], steps[4]) == (Output(True, 2), Output(False, 4))


def test_program_end_stops_reading() -> None:
    """M02/M30 end the program: what follows is not read."""
    assert parse_program("G01 X1 F60\nM30\nthis is not G-code") == [
        Move((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 1.0, 1)
    ]


def test_scale_factors() -> None:
    """XYZ scale multiplies every length (arcs too); speed scale multiplies F but not G00."""
    steps = parse_program("G01 X2 F60\nG02 X6 I2\nG00 X0", xyz_scale=0.5, speed_scale=3.0)
    line, *arc, rapid = moves(steps)
    assert line.end == approx((1.0, 0.0, 0.0)) and line.feed_mm_s == pytest.approx(3.0)
    assert arc[-1].end == approx((3.0, 0.0, 0.0))
    assert all(math.dist(m.end[:2], (2.0, 0.0)) == pytest.approx(1.0) for m in arc)
    assert rapid.feed_mm_s is None


@pytest.mark.parametrize("scale", [0.0, -1.0, math.inf, math.nan])
def test_scale_factors_must_be_positive(scale: float) -> None:
    with pytest.raises(ValueError, match="xyz_scale"):
        parse_program("G00 X1", xyz_scale=scale)


# ---- polar coordinates ---------------------------------------------------------------------------


def test_polar_absolute_about_the_origin() -> None:
    """G16 under G90: X radius, Y angle (G17); an omitted word keeps the current position's."""
    steps = parse_program("G16 G90 G01 X10 Y90 F60\nY180\nX5\nG15 X1 Y1")
    assert [m.end for m in moves(steps)] == [
        approx((0.0, 10.0, 0.0)),
        approx((-10.0, 0.0, 0.0)),
        approx((-5.0, 0.0, 0.0)),
        approx((1.0, 1.0, 0.0)),
    ]


def test_polar_incremental_from_the_current_position() -> None:
    steps = parse_program("G16 G91 G01 X2 Y90 F60", start=(1.0, 1.0, 3.0))
    assert end_of(steps) == approx((1.0, 3.0, 3.0))


def test_polar_in_the_zx_plane() -> None:
    """G18: Z is the radius and X the angle, measured from Z towards X; Y stays Cartesian."""
    steps = parse_program("G18 G16 G90 G01 Z2 X90 Y5 F60")
    assert end_of(steps) == approx((2.0, 5.0, 0.0))


# ---- arcs ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("program", "through"),
    [
        ("G03 X0 Y1 I-1 F60", (math.sqrt(0.5), math.sqrt(0.5))),  # a quarter turn counter-clockwise
        ("G02 X0 Y1 I-1 F60", (-1.0, 0.0)),  # three quarters clockwise
        ("G03 X0 Y1 R1 F60", (math.sqrt(0.5), math.sqrt(0.5))),  # R > 0: the short way
        ("G03 X0 Y1 R-1 F60", (2.0, 1.0)),  # R < 0: the long way round, about (1, 1)
        ("G02 X0 Y1 R1 F60", (1 - math.sqrt(0.5), 1 - math.sqrt(0.5))),  # clockwise about (1, 1)
    ],
)
def test_arc_direction_and_radius_forms(program: str, through: tuple[float, float]) -> None:
    """G02 clockwise, G03 counter-clockwise seen from +Z; the path passes close to `through`."""
    steps = parse_program(program, start=(1.0, 0.0, 0.0))
    points = [m.end[:2] for m in moves(steps)]
    assert points[-1] == pytest.approx((0.0, 1.0), abs=1e-9)
    assert min(math.dist(p, through) for p in points) < 0.05  # chords of r = 1 mm are 63 µm long


def test_full_circle_with_offsets() -> None:
    """Same start and end with I/J is a whole turn, returning exactly to the start."""
    steps = parse_program("G02 I1 F60", start=(0.0, 0.0, 0.0))
    points = [m.end for m in moves(steps)]
    assert points[-1] == (0.0, 0.0, 0.0)
    assert max(p[0] for p in points) == pytest.approx(2.0, abs=1e-5)
    assert all(math.dist(p[:2], (1.0, 0.0)) == pytest.approx(1.0) for p in points)


@pytest.mark.parametrize(("plane", "normal"), [(17, 2), (18, 1), (19, 0)])
def test_arcs_in_each_plane_are_counter_clockwise_about_the_normal(plane: int, normal: int) -> None:
    """G17 XY, G18 ZX, G19 YZ: G03 turns positively about Z, Y, X respectively; the normal axis does
    not move."""
    letters = {17: ("X", "Y", "I", "J"), 18: ("Z", "X", "K", "I"), 19: ("Y", "Z", "J", "K")}[plane]
    first, second, first_offset, _ = letters
    program = f"G{plane} G03 {first}0 {second}1 {first_offset}-1 F60"
    start = [0.0, 0.0, 0.0]
    p = PLANES[plane]
    start[p.first] = 1.0
    points = [m.end for m in moves(parse_program(program, start=(start[0], start[1], start[2])))]
    turn = 0.0
    previous = (1.0, 0.0)
    for point in points:
        here = (point[p.first], point[p.second])
        cross = previous[0] * here[1] - previous[1] * here[0]
        turn += math.atan2(cross, previous[0] * here[0] + previous[1] * here[1])
        previous = here
        assert point[normal] == 0.0
    assert turn == pytest.approx(math.pi / 2)


def test_helix_moves_the_normal_axis_with_the_angle() -> None:
    steps = parse_program("G17 G03 X-1 Y0 Z2 I-1 F60", start=(1.0, 0.0, 0.0))
    for move in moves(steps):
        angle = math.atan2(move.end[1], move.end[0])
        assert move.end[2] == pytest.approx(2 * angle / math.pi, abs=1e-9)


@pytest.mark.parametrize("radius", [0.0002, 0.001, 0.1, 1.0, 10.0, 250.0])
@pytest.mark.parametrize("sweep_deg", [1.0, 45.0, 180.0, 359.0])
def test_chords_stay_within_half_a_micron(radius: float, sweep_deg: float) -> None:
    """MS-TRACER-5: every chord's largest distance from its arc, measured by sampling, is at most
    0.5 µm; and one chord fewer would break the bound or span more than half a turn (the count is
    the least that holds)."""
    sweep = math.radians(sweep_deg)
    start = (radius, 0.0, 0.0)
    end = (radius * math.cos(sweep), radius * math.sin(sweep), 0.0)
    points = [start, *arc_chords(start, end, (0.0, 0.0), PLANES[17], clockwise=False)]
    for a, b in itertools.pairwise(points):
        assert max_arc_distance_from_chord(a[:2], b[:2], (0.0, 0.0)) <= SAGITTA_MM + 1e-12
    count = len(points) - 1
    assert count == chord_count(radius, sweep)
    if count > 1:
        wider = sweep / (count - 1)
        assert wider > math.pi or radius * (1 - math.cos(wider / 2)) > SAGITTA_MM


def test_chord_never_spans_more_than_half_a_turn() -> None:
    """On a radius below the sagitta a chord could cover the arc in one step, but past half a turn
    the far side of the arc strays from it by more than the sagitta."""
    assert chord_count(0.0001, 2 * math.pi) == 2
    assert chord_count(0.0001, math.pi) == 1


def test_arc_radius_blends_within_tolerance() -> None:
    """An end a few µm off the circle (CAM rounding) is accepted; the radius blends to it."""
    steps = parse_program("G03 X-1.003 Y0 I-1 F60", start=(1.0, 0.0, 0.0))
    assert end_of(steps) == approx((-1.003, 0.0, 0.0))


# ---- errors ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("bad_line", "message"),
    [
        ("G01 X1 F0", "feed rate F0 must be above 0"),
        ("X1", "X without G00-G03"),
        ("G05 X1", "G05: unsupported"),
        ("G17.1", "G17.1: unsupported"),
        ("M06", "M06: unsupported"),
        ("M03 M05", "only one M code per line"),
        ("T1", "T1: unsupported"),
        ("G01 G00 X1", "conflicts with another G code"),
        ("G04 G01 P10", "conflicts with another G code"),
        ("G01 X1 X2", "X is given twice"),
        ("G02 X1 Y1", "G02 needs I/J/K (centre) or R (radius)"),
        ("G01 X1 I1", "I belong to G02/G03 arcs, not G01"),
        ("G02 X1 R0.1", "radius R0.1 is too small"),
        ("G02 R1", "R cannot describe a full circle"),
        ("G02 X5 I1", "off the arc's circle"),
        ("G02 X1 I1 R1", "either R or I/J/K"),
        ("G17 G02 X1 K1", "K is not an offset in the G17 plane"),
        ("G02 X1 I0 J0", "radius 0"),
        ("G04", "G04 needs P"),
        ("G04 P-5", "G04 needs P"),
        ("G04 X1", "G04 takes only P (ms), not X"),
        ("P100", "P belongs to G04"),
        ("G01 X(1", "comment '(' is not closed"),
        ("G01 X1e3", "E3: unsupported"),
        ("G01 X", "cannot read 'X'"),
        ("G01 X99999999", "out of range"),
    ],
)
def test_errors_name_the_line(bad_line: str, message: str) -> None:
    program = f"G21 G90 F60\n(fine so far)\n{bad_line}\nG01 X0"
    with pytest.raises(GcodeError) as info:
        parse_program(program, start=(0.0, 0.0, 0.0))
    assert info.value.line == 3
    assert message in info.value.message
    assert str(info.value).startswith("line 3: ")


def test_feed_move_before_any_f_is_an_error() -> None:
    with pytest.raises(GcodeError, match=r"line 2: no feed rate: give F before or with G01"):
        parse_program("G21\nG01 X1")


def test_read_program_checks_words_without_running() -> None:
    """Syntax is checked without a start position; what depends on running (feed, arcs) is not."""
    assert len(read_program("G01 X1\n\n(comment)\nG02 X1 R0.01")) == 2
    with pytest.raises(GcodeError, match="line 2"):
        read_program("G01 X1\nG01 Q1")


# ---- properties -----------------------------------------------------------------------------------

_WORD_VALUES = st.floats(-100, 100, allow_nan=False).map(lambda v: round(v, 3))


@st.composite
def linear_programs(draw: st.DrawFn) -> tuple[str, tuple[float, float, float]]:
    """Lines of G00/G01 moves with random units and distance modes, and where they must end."""
    position = [0.0, 0.0, 0.0]
    lines = ["F100"]
    for _ in range(draw(st.integers(1, 8))):
        inch = draw(st.booleans())
        absolute = draw(st.booleans())
        words = draw(st.dictionaries(st.sampled_from("XYZ"), _WORD_VALUES, min_size=1))
        unit = 25.4 if inch else 1.0
        for letter, value in words.items():
            i = "XYZ".index(letter)
            position[i] = value * unit if absolute else position[i] + value * unit
        motion = draw(st.sampled_from(["G00", "G01"]))
        text = " ".join(f"{k}{v}" for k, v in words.items())
        lines.append(f"{'G20' if inch else 'G21'} {'G90' if absolute else 'G91'} {motion} {text}")
    return "\n".join(lines), (position[0], position[1], position[2])


@given(linear_programs())
def test_property_linear_moves_end_where_the_words_say(case: tuple[str, tuple[float, float, float]]) -> None:
    """Whatever mix of G20/G21 and G90/G91, the plan is continuous and ends at the position the
    words describe."""
    program, expected = case
    steps = moves(parse_program(program))
    here = (0.0, 0.0, 0.0)
    for move in steps:
        assert move.start == here
        here = move.end
    assert here == pytest.approx(expected, abs=1e-6)


@given(
    radius=st.floats(0.0005, 50),
    start_deg=st.floats(-180, 180),
    sweep_deg=st.floats(0.5, 359.5),
    clockwise=st.booleans(),
)
@settings(max_examples=60, deadline=None)
def test_property_arc_chords_lie_on_the_circle_within_the_sagitta(
    radius: float, start_deg: float, sweep_deg: float, clockwise: bool
) -> None:
    """Any I/J arc: every chord end lies on the circle and every chord is within 0.5 µm of it."""
    a0 = math.radians(start_deg)
    a1 = a0 + math.radians(-sweep_deg if clockwise else sweep_deg)
    start = (radius * math.cos(a0), radius * math.sin(a0), 0.0)
    end_x, end_y = round(radius * math.cos(a1), 9), round(radius * math.sin(a1), 9)
    program = (
        f"G{'02' if clockwise else '03'} X{end_x:.9f} Y{end_y:.9f} I{-start[0]:.9f} J{-start[1]:.9f} F60"
    )
    steps = moves(parse_program(program, start=start))
    for move in steps:
        assert math.hypot(*move.end[:2]) == pytest.approx(radius, abs=2e-6)
        assert max_arc_distance_from_chord(move.start[:2], move.end[:2], (0.0, 0.0)) <= SAGITTA_MM + 1e-6


@given(st.text(alphabet="GMXYZIJKRFPNT0123456789.-+ ()%;\n", max_size=60))
@settings(max_examples=300, deadline=None)
def test_property_any_text_is_planned_or_refused_with_a_line(text: str) -> None:
    """No input makes the parser fail other than with a `GcodeError` naming a line of the text."""
    try:
        parse_program(text)
    except GcodeError as exc:
        assert 1 <= exc.line <= max(1, len(text.splitlines()))
