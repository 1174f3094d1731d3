"""Property tests: arbitrary byte streams and chunkings never break the parser or the model, the model
only sends replies the protocol allows, and the documented recovery always brings back a working
`c` (MP-21 ... MP-24 for stray bytes, §7 for bytes during moves, MP-56 for deafness)."""

from __future__ import annotations

import json

from hypothesis import given
from hypothesis import strategies as st

from emulator.device import LineSettings
from protocols import mp285 as p
from protocols.mp285 import Frame, FrameParser, StatusBlock, Vector
from tests.support.fuzz import fuzz_settings
from tests.unit.mp285.harness import Bench

FUZZ = fuzz_settings(80)

VALID = [
    p.GetPosition().encode(),
    p.GetStatus().encode(),
    p.Move(250, -125, 25).encode(),
    p.Move(2_500, 0, 0).encode(),
    p.Move(-400_000, 13, 0).encode(),
    p.SetVelocity(0x00C8).encode(),
    p.SetVelocity(0x0000).encode(),
    p.SetVelocity(0x851E).encode(),
    p.SetVelocity(0x7FFF).encode(),
    p.SetOrigin().encode(),
    p.Absolute().encode(),
    p.Relative().encode(),
    p.Refresh().encode(),
    p.Reset().encode(),
    p.Download(1, (Vector.move(100, 0, 0), Vector.pause(), Vector.move(0, -100, 0))).encode(),
    p.Download(2, (Vector.pause(),)).encode(),
    p.Execute(1).encode(),
    p.Execute(2).encode(),
    p.Upload(1).encode(),
    p.Continue().encode(),
    b"\x03",
    b"\r",
    b"\n",
]

pieces = st.one_of(st.binary(min_size=1, max_size=6), st.sampled_from(VALID))
chunks = st.lists(st.tuples(st.lists(pieces, min_size=1, max_size=4), st.floats(0, 0.3)), max_size=12)

KNOB_SETS = [
    {},
    {"move_interrupt_reply": "error8_4", "query_interrupts_move": False},
    {"move_interrupt_reply": "error8", "terminators_interrupt_move": True},
    {"k_reply_at_pause": False, "stray_terminator_reply": "ignore", "program_vectors": "follow_mode"},
    {
        "axis_motion": "sequential",
        "accel_um_s2": 500,
        "coarse_step_quantum_usteps": 5,
        "input_buffer_size": 4,
    },
    {"out_of_range": "error4", "velocity_over_limit": "error4", "settle_s": 0},
]


def allowed_reply(data: bytes) -> bool:
    """One emission of a device that is neither crashed nor garbling."""
    if data in (b"\r", b"=", b"\x00\r"):  # `00 0D`: upload of an empty program
        return True
    if len(data) == 2 and data[1] == p.CR:
        return p.is_error_code(data[0])
    if len(data) == p.POSITION_REPLY_LENGTH and data[-1] == p.CR:
        return True
    if len(data) == p.STATUS_REPLY_LENGTH and data[-1] == p.CR:
        StatusBlock.unpack(data)
        return True
    return data[-1] == p.CR and len(data) == 2 + 16 * data[0]


@FUZZ
@given(
    st.binary(max_size=300), st.lists(st.integers(1, 300), max_size=6), st.lists(st.booleans(), max_size=300)
)
def test_parser_is_chunking_invariant(data: bytes, cuts: list[int], framing: list[bool]) -> None:
    whole = FrameParser(16).feed(data)
    parser = FrameParser(16)
    pieces, start = [], 0
    for cut in sorted(cuts):
        pieces.append(data[start:cut])
        start = max(start, cut)
    pieces.append(data[start:])
    assert [item for piece in pieces for item in parser.feed(piece)] == whole
    for item in whole:
        if isinstance(item, Frame):
            assert item.command.encode() == item.raw
    flagged = FrameParser(16)
    for i, byte in enumerate(data):
        flagged.feed_byte(byte, framing_error=framing[i] if i < len(framing) else False)


def feed(bench: Bench, stream: list[tuple[list[bytes], float]]) -> None:
    for parts, gap in stream:
        bench.write(b"".join(parts), at=bench.now + gap)
    bench.run(bench.now + 0.5)


def recover_and_query(bench: Bench, power_cycle_if_stuck: bool = False) -> None:
    """Wait out moves and deafness; CRs until command position (they end DISCARDING or complete a
    frame); ^C to stop a move that never ends. Then `c` answers the position. Without RTS/CTS a
    speed-0 move whose busy period already took its one byte ignores even ^C (MP-7): only a power
    cycle (MP-76) ends it."""
    for _ in range(30):
        bench.settle(1.0)
        snap = bench.snapshot()
        if snap["parser"] != "command":
            bench.write(b"\r" * 1600)  # longer than any frame
        elif snap["state"] in ("IDLE", "PAUSED"):
            break
        else:
            bench.write(b"\x03")
    else:
        assert power_cycle_if_stuck, bench.snapshot()
        bench.control("power_cycle")
        bench.settle(1.5)
    bench.take()
    bench.emissions()
    expected = bench.snapshot()["position"]["usteps"]
    bench.write(b"c\r")
    bench.run(bench.now + 0.1)
    assert bench.take() == p.encode_position(expected["X"], expected["Y"], expected["Z"])


@FUZZ
@given(chunks, st.sampled_from(range(len(KNOB_SETS))), st.booleans())
def test_model_survives_anything_and_recovers(stream: list, knob_set: int, paced: bool) -> None:
    bench = Bench(overrides={"knobs": KNOB_SETS[knob_set]}, paced=paced)
    feed(bench, stream)
    for _, data in bench.emissions():
        assert allowed_reply(bytes.fromhex(data)), data
    json.dumps(bench.snapshot())
    recover_and_query(bench)


@FUZZ
@given(chunks)
def test_usb_host_without_rtscts(stream: list) -> None:
    """MP-7: input may be lost, replies stay well-formed ('0' included) and recovery works."""
    bench = Bench("mp285a", host=LineSettings(9600, None, None, 1, False, False))
    feed(bench, stream)
    for _, data in bench.emissions():
        assert allowed_reply(bytes.fromhex(data)), data
    recover_and_query(bench, power_cycle_if_stuck=True)


@FUZZ
@given(chunks, st.sampled_from([(19200, "none", 1), (4800, "none", 1), (9600, "even", 1), (9600, "none", 2)]))
def test_garbled_hosts_never_break_the_model(stream: list, host: tuple) -> None:
    """MP-6: whatever a mismatched host sends, the model only decodes, reacts and garbles back."""
    baud, parity, stop = host
    bench = Bench(host=LineSettings(baud, 8, parity, stop, False, False))
    feed(bench, stream)
    bench.settle(1.0)
    for _, data in bench.emissions():
        assert len(bytes.fromhex(data)) >= 1
    json.dumps(bench.snapshot())
