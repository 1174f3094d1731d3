"""SEQUENCER module (§9.10): TV-193…TV-198 and TV-220, on profile `ms2000-seq`.

Programs are loaded through the control input `sequencer` (MS-SEQ-8); block transitions are read
as `seq_block` events. Event times are exact device times.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from emulator.control_client import ControlFailure
from tests.conformance.ms2000.conftest import ACK, EXACT_S, IDLE, Host

#: block 1 starts on ARM, block k on block k−1's COMPLETE, all delays 0 (TV-196, TV-220)
CHAIN = [{"start": [2]}] + [{"start": [6, k - 1]} for k in range(2, 8)]


@pytest.fixture
def seq(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-seq")


def events(host: Host, timeout: float = 0.5) -> Iterator[dict[str, Any]]:
    return host.target.ctl().events(timeout=timeout)


def transitions(host: Host, until: str, timeout: float = 1.0) -> list[tuple[Any, ...]]:
    """Block transitions (block, transition[, repetition]) and recursion errors, up to and
    including the first whose event or transition is `until` (or `timeout` s of silence)."""
    seen: list[tuple[Any, ...]] = []
    for event in events(host, timeout):
        if event["ev"] == "seq_recursion_error":
            seen.append(("recursion_error",))
        elif event["ev"] == "seq_block":
            extra = (event["repetition"],) if "repetition" in event else ()
            seen.append((event["block"], event["transition"], *extra))
        else:
            continue
        if until in (event["ev"], event.get("transition")):
            break
    return seen


@pytest.mark.smoke
def test_tv_193_arm_forms(seq: Host) -> None:
    """TV-193 (MS-SEQ-6, MS-SEQ-1): `ARM`, `ARM X`, `ARM Y=1`, `ARM Z` acknowledge; sequencer
    programming commands are not emulated."""
    seq.run(
        [
            (b"ARM\r", ACK),
            (b"ARM X\r", ACK),
            (b"ARM Y=1\r", ACK),
            (b"ARM Z\r", ACK),
            (b"SEQ X=1\r", b":N-1\r\n"),
        ]
    )


@pytest.mark.smoke
@pytest.mark.control
def test_tv_194_ttl0_rises_after_the_delay(seq: Host) -> None:
    """TV-194 (MS-SEQ-8, MS-SEQ-1, MS-SEQ-2, MS-SEQ-3): TTL0 starts on block 1's DELAY_COMPLETE:
    OUT0 rises 100 ms after ARM (event times are exact device times); re-initialising (`ARM X`)
    puts the outputs at rest."""
    seq.input(
        "sequencer",
        blocks=[{"start": [2], "delay_ms": 100, "repetitions": 0, "action": 0}],
        outputs=[{"kind": "ttl", "index": 0, "start": [5, 1], "stop": [0]}],
    )
    seq.target.ctl().subscribe("dut")
    seq.ask(b"ARM\r", ACK)
    start = rise = None
    for event in events(seq, timeout=1.0):
        if event["ev"] == "seq_block" and event["transition"] == "START":
            start = event["t"]
        elif event["ev"] == "ttl_out0" and event["level"] == 1:
            rise = event["t"]
            break
    assert start is not None and rise is not None
    assert rise - start == pytest.approx(0.100, abs=EXACT_S)
    assert seq.get("ttl_out0") == 1
    seq.ask(b"ARM X\r", ACK)
    assert seq.get("ttl_out0") == 0


@pytest.mark.control
def test_tv_195_two_repetitions_on_in0_pulses(seq: Host) -> None:
    """TV-195 (MS-SEQ-3): START, DELAY_COMPLETE, then, the block waiting (`W`), per IN0 pulse REPEAT,
    REPETITION m, DELAY_COMPLETE, then COMPLETE; the block is idle again."""
    seq.input("sequencer", blocks=[{"start": [2], "repeat": [1], "delay_ms": 50, "repetitions": 2}])
    seq.target.ctl().subscribe("dut")
    seq.ask(b"ARM\r", ACK)
    seen = transitions(seq, "DELAY_COMPLETE")
    assert seq.get("sequencer")["blocks"][0]["state"] == "W"
    for _ in range(2):
        seq.input("ttl_in0", pulse_ms=1)
        seen += transitions(seq, "DELAY_COMPLETE")
    seen += transitions(seq, "COMPLETE")
    assert [t[1:] for t in seen] == [
        ("START",),
        ("DELAY_COMPLETE",),
        ("REPEAT",),
        ("REPETITION", 1),
        ("DELAY_COMPLETE",),
        ("REPEAT",),
        ("REPETITION", 2),
        ("DELAY_COMPLETE",),
        ("COMPLETE",),
    ]
    assert seq.get("sequencer")["blocks"][0]["state"] == "I"


@pytest.mark.control
def test_tv_196_seventh_start_is_a_recursion_error(seq: Host) -> None:
    """TV-196 (MS-SEQ-4): seven blocks chained with no delay: the seventh START in one step is a
    recursion error, and the sequencer stops."""
    seq.input("sequencer", blocks=CHAIN)
    seq.target.ctl().subscribe("dut")
    seq.ask(b"ARM\r", ACK)
    seen = transitions(seq, "seq_recursion_error")
    assert seen[-1] == ("recursion_error",)
    assert (7, "START") not in seen
    assert {b["state"] for b in seq.get("sequencer")["blocks"]} == {"I"}


@pytest.mark.control
def test_tv_197_ring_buffer_next_and_send_where(connect: Callable[..., Host]) -> None:
    """TV-197 (MS-SEQ-5, MS-18): action 1 moves to ring-buffer slot 0; with
    `sequencer_send_actions: emit`, action 5 follows ARM's reply with the positions of X, Y, Z; by
    default it sends nothing (the next exchange would show a stray byte)."""
    host = connect("ms2000-seq")
    host.run([(b"LD X=1000 Y=2000\r", ACK), (b"LD X=3000 Y=4000\r", ACK)])
    host.input("sequencer", blocks=[{"start": [2], "action": 1}])
    host.run([(b"ARM\r", ACK), IDLE, (b"W X Y\r", b":A 1000 2000\r\n")])
    emit = connect("ms2000-seq", {"knobs": {"sequencer_send_actions": "emit"}})
    emit.input("sequencer", blocks=[{"start": [2], "action": 5}])
    emit.ask(b"ARM\r", ACK + b":A 0 0 0\r\n")
    quiet = connect("ms2000-seq")
    quiet.input("sequencer", blocks=[{"start": [2], "action": 5}])
    quiet.run([(b"ARM\r", ACK), (b"/\r", b"N\r\n")])


@pytest.mark.control
def test_tv_198_at_stops_and_always_is_refused_for_ttl(seq: Host) -> None:
    """TV-198 (MS-SEQ-7, MS-SEQ-2): `@` while the sequencer runs idles every block (block 1 never
    completes its 1 s delay) and halts the stage; a TTL output starting on ALWAYS is refused by the
    control channel, naming output and field, and the program loaded before stays."""
    seq.input("sequencer", blocks=[{"start": [2], "delay_ms": 1000}])
    seq.target.ctl().subscribe("dut")
    seq.run([(b"ARM\r", ACK), (b"M X=500000\r", ACK), (b"/\r", b"B\r\n")])
    assert seq.get("sequencer")["running"]
    seq.advance(0.2, ("button", {"name": "at", "ms": 200}))
    assert {b["state"] for b in seq.get("sequencer")["blocks"]} == {"I"}
    assert not seq.get("sequencer")["running"]
    seq.ask(b"/\r", b"N\r\n")
    assert transitions(seq, "never", timeout=1.5) == [(1, "START")]
    with pytest.raises(ControlFailure, match=r"output 1 \(ttl 0\) start: condition 12 \(ALWAYS\)"):
        seq.input("sequencer", outputs=[{"kind": "ttl", "index": 0, "start": [12]}])
    assert seq.get("sequencer")["program"]["blocks"][0]["delay_ms"] == 1000


@pytest.mark.control
def test_tv_220_six_chained_starts_are_processed(seq: Host) -> None:
    """TV-220 (MS-SEQ-4): six blocks chained with no delay all START and COMPLETE; no recursion
    error."""
    seq.input("sequencer", blocks=CHAIN[:6])
    seq.target.ctl().subscribe("dut")
    seq.ask(b"ARM\r", ACK)
    seen = transitions(seq, "never", timeout=0.5)
    assert [t for t in seen if t[1] in ("START", "COMPLETE")] == [
        (k, what) for k in range(1, 7) for what in ("START", "COMPLETE")
    ]
    assert ("recursion_error",) not in seen
