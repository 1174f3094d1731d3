"""The G-code executor (MS-TRACER-5) driving the MS-2000 model through the real client, no port:
each exchange is a command line handed to the model after 10 ms of device time."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from protocols.clients.errors import NoReply
from protocols.clients.gcode import (
    ExecutionError,
    GcodeError,
    GcodeExecutor,
    Step,
    iter_program,
    moving_axes,
    parse_program,
    run_program,
)
from protocols.clients.ms2000 import MS2000
from tests.unit.ms2000.conftest import Harness

#: device time that passes before each command line (a host's round trip)
EXCHANGE_S = 0.01


class ModelStage(MS2000):
    """The MS2000 client whose line is the model harness; it keeps every command line it sent."""

    def __init__(self, harness: Harness, fail_on: str | None = None) -> None:
        self._axes = None
        self.harness = harness
        self.sent: list[str] = []
        self._fail_on = fail_on

    def exchange(self, command: str) -> str:
        self.sent.append(command)
        if command == self._fail_on:
            raise NoReply(f"{command!r}: no complete reply within 1.0 s (got b'')")
        self.harness.wait(EXCHANGE_S)
        reply = self.harness.cmd(command)
        assert reply.endswith(b"\r\n"), reply
        return reply[:-2].decode("latin-1")


def executor_on(
    profile: str = "ms2000-tracer", fail_on: str | None = None
) -> tuple[GcodeExecutor, ModelStage]:
    harness = Harness(profile)
    stage = ModelStage(harness, fail_on)
    return GcodeExecutor(stage, poll_s=0.0, sleep=harness.wait, clock=lambda: harness.now), stage


def run(executor: GcodeExecutor, program: str) -> None:
    executor.run(parse_program(program, start=executor.start_position()))


def test_tv_203_feed_move_then_output() -> None:
    """TV-203 (MS-TRACER-5, MS-TRACER-3): `S X=1.000000` and `M X=10000`, `/` polled until `N`
    before the next step; M03 is `TTL Y=1`. The speeds found at the start come back at the end."""
    executor, stage = executor_on()
    run(executor, "G21 G90 G01 X1 F60\nM03")
    sent = stage.sent
    speed, move, output = sent.index("S X=1.000000"), sent.index("M X=10000"), sent.index("TTL Y=1")
    assert speed < move < output
    polls = sent[move + 1 : output]
    assert polls and set(polls) == {"/"}
    assert sent[-1] == "S X=5.145600"
    assert stage.harness.cmd("W X") == b":A 10000\r\n"
    assert stage.harness.get("ttl_out0") == 1
    assert stage.harness.cmd("S X?") == b":A X=5.145600\r\n"


def test_rapid_runs_each_axis_at_its_maximum() -> None:
    """G00: maxima found by setting a huge speed and reading back the clamped value (MS-54)."""
    executor, stage = executor_on()
    run(executor, "G00 X1 Y-1 Z0.1")
    assert stage.sent[stage.sent.index("S X? Y? Z?") :][:3] == [
        "S X? Y? Z?",
        "S X=10000.000000 Y=10000.000000 Z=10000.000000",
        "S X? Y? Z?",
    ]
    assert executor.max_speed == {"X": 7.68, "Y": 7.68, "Z": 1.92}
    assert "M X=10000 Y=-10000 Z=1000" in stage.sent
    assert stage.harness.cmd("W X Y Z") == b":A 10000 -10000 1000\r\n"


def test_feed_beyond_a_maximum_shrinks_the_whole_vector() -> None:
    """The direction of the path is kept: Y at its maximum (left there by the probe, so not sent
    again), X in proportion."""
    executor, stage = executor_on()
    run(executor, "G01 X0.3 Y0.4 F60000")
    move = stage.sent.index("M X=3000 Y=4000")
    assert stage.sent[move - 2 : move] == ["S X? Y?", "S X=5.760000"]


def test_unchanged_speeds_are_not_sent_again() -> None:
    executor, stage = executor_on()
    run(executor, "G01 X1 F60\nX2\nX3")
    assert stage.sent.count("S X=1.000000") == 1
    assert [c for c in stage.sent if c.startswith("M ")] == ["M X=10000", "M X=20000", "M X=30000"]


def test_program_starts_where_the_stage_is() -> None:
    executor, stage = executor_on()
    stage.harness.cmd("M X=5000 Y=-2500")
    stage.harness.idle()
    assert executor.start_position() == (0.5, -0.25, 0.0)
    run(executor, "G91 G01 X1 F600")
    assert stage.harness.cmd("W X Y") == b":A 15000 -2500\r\n"


def test_full_circle_returns_to_its_start_in_chords() -> None:
    executor, stage = executor_on()
    steps = parse_program("G02 I0.01 F600", start=executor.start_position())
    executor.run(steps)
    assert len([c for c in stage.sent if c.startswith("M ")]) == len(steps) > 4
    assert stage.harness.cmd("W X Y") == b":A 0 0\r\n"


def test_dwell_waits_on_the_host_clock() -> None:
    executor, stage = executor_on()
    before = stage.harness.now
    summary = executor.run(parse_program("G04 P250"))
    assert stage.harness.now - before >= 0.25
    assert (summary.dwells, summary.moves) == (1, 0)


def test_axis_the_stage_lacks_is_refused_before_anything_moves() -> None:
    executor, stage = executor_on("ms2000-xy")
    steps = parse_program("G01 X1 F60\nG01 Z1", start=executor.start_position())
    with pytest.raises(GcodeError, match=r"line 2: the stage has no Z axis \(it has X Y\)"):
        executor.run(steps)
    assert not [c for c in stage.sent if c.startswith(("M ", "S "))]


def test_silence_mid_program_halts_and_switches_the_output_off() -> None:
    """A failure names the program line; the stage is halted, the output de-asserted and the speeds
    restored."""
    executor, stage = executor_on(fail_on="M X=20000")
    steps = parse_program("M03\nG01 X1 F60\nX2\nX3", start=executor.start_position())
    with pytest.raises(ExecutionError, match=r"^line 3: 'M X=20000': no complete reply") as info:
        executor.run(steps)
    assert info.value.line == 3
    after = stage.sent[stage.sent.index("M X=20000") + 1 :]
    assert after == ["\\", "TTL Y=0", "S X=5.145600"]
    assert stage.harness.get("ttl_out0") == 0


def test_counts_per_mm_read_out() -> None:
    """MS-TRACER-5: the `C` read-out Tracer Console shows (45396 on the profiles)."""
    executor, _ = executor_on()
    assert executor.counts_per_mm() == {"X": 45396.0, "Y": 45396.0, "Z": 20000.0}


def test_run_program_in_one_call() -> None:
    stage = ModelStage(Harness("ms2000"))
    summary = run_program(stage, "G21 G91 G01 X0.1 Y0.1 F600\nM03\nM05", xyz_scale=2.0)
    assert (summary.moves, summary.outputs) == (1, 2)
    assert stage.harness.cmd("W X Y") == b":A 2000 2000\r\n"


def test_a_plan_from_an_iterator_is_sent_as_it_is_made() -> None:
    """With the axes known beforehand (`moving_axes`), the executor reads the plan once, a step at a
    time: a program of millions of moves is never held whole (before, `run` took a list)."""
    executor, stage = executor_on()
    program = "G21 G90 G01 F600\n" + "".join(f"X{(i % 2) * 0.01:g}\n" for i in range(1, 7))
    start = executor.start_position()
    made: list[int] = []

    def plan() -> Iterator[Step]:
        for step in iter_program(program.splitlines(), start=start):
            made.append(step.line)
            yield step

    heard: list[tuple[int, list[int]]] = []
    axes = moving_axes(iter_program(program.splitlines(), start=start))
    summary = executor.run(plan(), lambda step: heard.append((step.line, list(made))), axes=axes)
    assert axes == {"X": 2} and summary.moves == 6
    assert heard == [(line, list(range(2, line + 1))) for line in range(2, 8)], "one step ahead, never more"
    assert stage.harness.cmd("W X") == b":A 0\r\n"


def test_an_axis_the_stage_lacks_is_refused_from_the_axes_given_before_any_step_is_read() -> None:
    executor, stage = executor_on("ms2000-xy")

    class Unread:
        def __iter__(self) -> Iterator[Step]:
            raise AssertionError("no step may be read")

    with pytest.raises(GcodeError, match=r"line 5: the stage has no Z axis \(it has X Y\)"):
        executor.run(Unread(), axes={"X": 2, "Z": 5})
    assert not [c for c in stage.sent if c.startswith(("M ", "S "))]
