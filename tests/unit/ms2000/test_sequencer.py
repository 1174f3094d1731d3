"""SEQUENCER (§9.10) on the manual clock, on profile `ms2000-seq`: the rest of MS-SEQ-1…MS-SEQ-8
beyond the test vectors, which run in tests/conformance/ms2000 (TV-193…TV-198, TV-220)."""

from __future__ import annotations

from typing import Any

import pytest

from emulator.device import ControlError
from emulator.devices.ms2000.modules.sequencer_program import RESTRICTED, Position, allowed
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def seq() -> Harness:
    return Harness("ms2000-seq")


def transitions(h: Harness) -> list[tuple[Any, ...]]:
    """The block-transition events since the last call, as (block, transition[, repetition])."""
    out: list[tuple[Any, ...]] = []
    for e in h.take_events():
        if e["ev"] == "seq_block":
            out.append((e["block"], e["transition"], *([e["repetition"]] if "repetition" in e else [])))
        elif e["ev"] == "seq_recursion_error":
            out.append(("recursion_error",))
    return out


def test_arm_errors_change_nothing_ms_seq_6(seq: Harness) -> None:
    """MS-SEQ-6, MS-40: `ARM Y` is 0 or 1 (`Y?` reads it); other letters `:N-2`; a rejected line
    changes nothing, even its valid items."""
    assert seq.cmd("ARM Y=0") == ACK
    assert seq.cmd("ARM Y?") == b":A Y=0\r\n"
    assert seq.cmd("ARM Y=2") == b":N-4\r\n"
    assert seq.cmd("ARM Y=1 F") == b":N-2\r\n"
    assert seq.cmd("ARM X?") == b":N-4\r\n"
    assert seq.get("sequencer")["log"] is False
    assert Harness().cmd("ARM") == b":N-1\r\n"  # not in the default build (MS-118)


def test_arm_value_beyond_32_bits_is_out_of_range_ms_26(seq: Harness) -> None:
    """MS-26: `ARM X=99999999999` re-initialised as `ARM X` does and answered `:A` (found by
    test_fuzz_modules); a value beyond the 32-bit variable is `:N-4` and does nothing."""
    seq.input("sequencer", blocks=[{"start": [2], "delay_ms": 1000}])
    assert seq.cmd("ARM") == ACK
    assert seq.cmd("ARM X=99999999999") == b":N-4\r\n"
    assert seq.cmd("ARM Z=-99999999999 Y=0") == b":N-4\r\n"
    assert seq.get("sequencer")["running"] and seq.get("sequencer")["log"] is True


def test_timestamp_and_statestamp_ms_seq_5() -> None:
    """MS-SEQ-5 [choice formats]: `T <ms since ARM>` and `S` with the block states."""
    h = Harness("ms2000-seq", {"knobs": {"sequencer_send_actions": "emit"}})
    h.input(
        "sequencer", blocks=[{"start": [2], "delay_ms": 250, "action": 6}, {"start": [6, 1], "action": 7}]
    )
    h.cmd("ARM")
    h.wait(0.3)
    assert h.output() == b"T 250\r\nS I I I I I I I I\r\n"


@pytest.mark.parametrize("code", range(14))
@pytest.mark.parametrize("position", list(Position))
def test_condition_table_ms_seq_2(seq: Harness, code: int, position: Position) -> None:
    """MS-SEQ-2: each code is accepted exactly where the table allows it."""
    cond = [code, 1, 1] if code == 11 else [code, 1] if 5 <= code <= 10 else [code]
    programs: dict[Position, dict[str, Any]] = {
        Position.BLOCK_START: {"blocks": [{"start": cond}]},
        Position.BLOCK_REPEAT: {"blocks": [{"repeat": cond}]},
        Position.TTL_START: {"outputs": [{"kind": "ttl", "index": 1, "start": cond}]},
        Position.TTL_STOP: {"outputs": [{"kind": "ttl", "index": 1, "stop": cond}]},
        Position.STEP: {"outputs": [{"kind": "avo", "index": 0, "step": cond}]},
        Position.RESET: {"outputs": [{"kind": "stg", "axis": "Z", "reset": cond}]},
    }
    program = programs[position]
    expected = code not in RESTRICTED or position in RESTRICTED[code]
    assert allowed(code, position) is expected
    if expected:
        seq.input("sequencer", **program)
    else:
        with pytest.raises(ControlError, match=f"condition {code} .* not allowed in {position.value}"):
            seq.input("sequencer", **program)


@pytest.mark.parametrize(
    ("program", "message"),
    [
        ({"blocks": [{"start": [5]}]}, r"block 1 start: condition 5 .* takes 2"),
        ({"blocks": [{"start": [6, 9]}]}, r"block 1 start block: 9 is not an integer 1…8"),
        ({"blocks": [{}, {"delay_ms": -1}]}, r"block 2 delay_ms"),
        ({"blocks": [{"repetitions": 1.5}]}, r"block 1 repetitions"),
        ({"blocks": [{"action": 2}]}, r"block 1 action: action 2 .* needs module AUTOFOCUS"),
        ({"blocks": [{"action": 8}]}, r"block 1 action"),
        ({"blocks": [{"start": [14]}]}, r"block 1 start code"),
        ({"blocks": [{"begin": [2]}]}, r"block 1 begin: unknown field"),
        ({"blocks": [{}] * 9}, r"at most 8 blocks"),
        ({"outputs": [{"kind": "ttl", "index": 4}]}, r"output 1 index"),
        ({"outputs": [{"kind": "stg", "axis": "Q"}]}, r"output 1 axis"),
        ({"outputs": [{"kind": "avo", "index": 0, "initial": 11}]}, r"output 1 \(avo 0\) initial"),
        ({"outputs": [{"kind": "ttl", "index": 0}, {"kind": "ttl", "index": 0}]}, r"output 2 .* twice"),
        ({"outputs": [{"kind": "lst"}]}, r"output 1 kind"),
        ({"program": []}, r"program program: unknown field"),
    ],
)
def test_bad_programs_are_rejected_whole_ms_seq_8(
    seq: Harness, program: dict[str, Any], message: str
) -> None:
    """MS-SEQ-8, MS-SEQ-5: out-of-range codes and numbers, absent modules, unknown keys: the
    message names the block or output and field; the program stays as it was."""
    before = seq.get("sequencer")
    with pytest.raises(ControlError, match=message):
        seq.input("sequencer", **program)
    assert seq.get("sequencer") == before


def test_lcd_line_is_the_sequencer_segment_ms_seq_8(seq: Harness) -> None:
    """MS-SEQ-8, §9.0, MS-ARRAY-7: planar char, array char, then as many block characters as fit
    before the uptime; the other modules' segments are left out."""
    seq.input("sequencer", blocks=[{"start": [2], "delay_ms": 1000}])
    seq.cmd("ARM")
    seq.cmd("AIJ X=2 Y=1")
    line = seq.get("lcd")[1]
    assert line == "1 M D I I I 00:00:00"  # planar 1, array M(oving), blocks 1–4
    assert len(line) == 20


def test_array_arrival_is_condition_13_ms_array_8(seq: Harness) -> None:
    """MS-ARRAY-8, MS-SEQ-2: every array arrival raises ARRAY_MOVE_DONE; the stage going idle
    raises XYZ_STAGE_NOT_BUSY."""
    seq.input("sequencer", blocks=[{"start": [13]}, {"start": [4]}])
    seq.cmd("AR X=2 Y=1 Z=1 F=1")
    seq.cmd("RT Z=10")
    seq.cmd("AR")
    seq.settle()
    seen = [t for t in transitions(seq) if t[1] == "START"]
    assert seen.count((1, "START")) == 2
    assert (2, "START") in seen


def test_always_blocks_run_after_arm_x_until_stopped_ms_seq_6(seq: Harness) -> None:
    """MS-SEQ-3, MS-SEQ-6: an ALWAYS block waits for `ARM X`, then restarts whenever idle; `ARM Z`
    leaves it idle. With no delay it restarts within the step: a recursion error."""
    seq.input("sequencer", blocks=[{"start": [12], "delay_ms": 100}])
    seq.wait(0.5)
    assert transitions(seq) == []
    seq.cmd("ARM X")
    seq.wait(0.35)
    assert [t for t in transitions(seq) if t[1] == "START"] == [(1, "START")] * 4
    seq.cmd("ARM Z")
    seq.wait(0.5)
    assert transitions(seq) == [] and not seq.get("sequencer")["running"]
    seq.input("sequencer", blocks=[{"start": [12]}])
    seq.cmd("ARM X")
    assert transitions(seq)[-1] == ("recursion_error",)


def test_repetition_m_and_always_repeat_ms_seq_3(seq: Harness) -> None:
    """MS-SEQ-2, MS-SEQ-3: REPEAT = ALWAYS repeats at once; BLOCK n REPETITION m fires once."""
    seq.input(
        "sequencer",
        blocks=[{"start": [2], "repeat": [12], "repetitions": 3}, {"start": [11, 1, 2]}],
    )
    seq.cmd("ARM")
    repeats = [t for n in (1, 2, 3) for t in ((1, "REPEAT"), (1, "REPETITION", n), (1, "DELAY_COMPLETE"))]
    assert transitions(seq) == [
        (1, "START"),
        (1, "DELAY_COMPLETE"),
        *repeats,
        (1, "COMPLETE"),
        (2, "START"),
        (2, "DELAY_COMPLETE"),
        (2, "COMPLETE"),
    ]


def test_analog_and_stage_outputs_ms_seq_1(seq: Harness) -> None:
    """MS-SEQ-1: AVO steps by volts from its start value, STG moves its axis by units; RESET goes
    back to the start values."""
    seq.input(
        "sequencer",
        outputs=[
            {"kind": "avo", "index": 1, "step": [2], "reset": [3], "step_size": 0.5, "initial": 1.0},
            {"kind": "stg", "axis": "Z", "step": [2], "reset": [1], "step_size": 100, "initial": 0},
        ],
    )
    for _ in range(2):
        seq.cmd("ARM")
        seq.idle()
    state = seq.get("sequencer")
    assert state["avo"] == {"1": 2.0} and state["stage_steps"] == {"Z": 2}
    assert seq.cmd("W Z") == b":A 200\r\n"
    seq.input("ttl_in0", pulse_ms=1)
    seq.idle()
    assert seq.cmd("W Z") == b":A 0\r\n"


def test_at_button_without_and_with_the_condition_ms_seq_7(seq: Harness) -> None:
    """MS-SEQ-7, MS-85: `@` is AT_BUTTON_PRESSED when the program waits for it; otherwise it is
    ARRAY's (self-scan); a long press starts the array self-scan."""
    seq.input("button", name="at", ms=200)
    seq.wait(0.3)
    assert seq.get("array")["running"] == "self_scan"
    seq.cmd("\\")
    seq.input("sequencer", blocks=[{"start": [3], "delay_ms": 1000}])
    seq.input("button", name="at", ms=200)
    seq.wait(0.3)
    assert seq.get("array")["running"] is None
    assert transitions(seq) == [(1, "START")]
    seq.input("button", name="at", ms=1500)
    seq.wait(1.6)
    assert not seq.get("sequencer")["running"]  # block 1 is done: the long press is ARRAY's
    assert seq.get("array")["running"] == "self_scan"


def test_arm_y0_mutes_transitions_and_halt_stops_ms_seq_6(seq: Harness) -> None:
    """MS-SEQ-6 [choice]: with `ARM Y=0` no block-transition events; HALT also stops a sequence."""
    seq.input("sequencer", blocks=[{"start": [2], "delay_ms": 1000}])
    seq.cmd("ARM Y=0")
    seq.cmd("ARM")
    assert transitions(seq) == [] and seq.get("sequencer")["running"]
    assert seq.cmd("\\") == ACK
    assert not seq.get("sequencer")["running"]
