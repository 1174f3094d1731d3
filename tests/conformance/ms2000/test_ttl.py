"""TTL input and output, position reports and unsolicited output (§6.7): TV-76…TV-91."""

from __future__ import annotations

from collections.abc import Sequence

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host, Step

VECTORS = [
    pytest.param(
        [(b"TTL X=7\r", b":N-4\r\n"), (b"TTL X=11\r", b":N-4\r\n"), (b"TTL X=3\r", b":N-4\r\n")],
        id="tv077_in0_modes_of_absent_modules",
    ),
    pytest.param(
        [
            (b"RT Y?\r", b":A Y=10.000000\r\n"),
            (b"RT X=10\r", b":N-4\r\n"),
            (b"RT X?\r", b":A X=200.000000\r\n"),
        ],
        id="tv081_rtime",
    ),
    pytest.param([(b"VB X=1\r", ACK), (b"M X=100\r", ACK + b"N\r\n")], id="tv087_n_after_each_move"),
    pytest.param(
        [(b"VB X=16\r", ACK), (b"M X=1000 Y=-505\r", b":A 1000 -505\r\n")], id="tv088_move_echoes_targets"
    ),
    pytest.param(
        [
            (b"VB X=8\r", ACK),
            (b"/\r", b"N\r"),
            (b"BU\r", b"STD_XYZ\r"),
            (b"VB X=0\r", b":A\r"),
            (b"/\r", b"N\r\n"),
        ],
        id="tv090_cr_only_terminators",
        marks=pytest.mark.smoke,
    ),
    pytest.param(
        [(b"VB Y?\r", b":A Y=0\r\n"), (b"VB Y=1\r", b":N-4\r\n"), (b"VB T=1027\r", b":N-2\r\n")],
        id="tv091_vb_y_and_t",
    ),
]


@pytest.mark.parametrize("steps", VECTORS)
def test_tv_exchanges(ms: Host, steps: Sequence[Step]) -> None:
    """Each case is one test vector on the default profile, every reply byte for byte (MS-16,
    MS-18, MS-90, MS-93, MS-96, MS-109, MS-118)."""
    ms.run(steps)


@pytest.mark.control
def test_tv_076_ttl_settings_and_out0_toggle(ms: Host) -> None:
    """TV-76 (MS-89, MS-90): factory TTL settings; IN0 mode 10 toggles OUT0 at each pulse."""
    ms.run(
        [
            (b"TTL X? Y? Z? F?\r", b":A X=0 Y=0 Z=0 F=1\r\n"),
            (b"TTL X=10\r", ACK),
            (b"TTL X?\r", b":A X=10\r\n"),
        ]
    )
    ms.input("ttl_in0", pulse_ms=1)
    assert ms.get("ttl_out0") == 1


@pytest.mark.smoke
@pytest.mark.control
@pytest.mark.timing
def test_tv_078_out0_pulse_after_each_move(ms: Host) -> None:
    """TV-78 (MS-91, MS-93): in OUT0 mode 2 a pulse of RT Y = 5 ms starts when the move completes
    (event times are exact device times)."""
    ms.run([(b"TTL Y=2\r", ACK), (b"RT Y=5\r", ACK)])
    ctl = ms.target.ctl()
    ctl.subscribe("dut")
    ms.run([(b"M X=1000\r", ACK), IDLE])
    events = []
    for event in ctl.events(timeout=1.0):
        events.append(event)
        if event["ev"] == "ttl_out0" and event["level"] == 0:
            break
    done = next(e for e in events if e["ev"] == "move_complete")
    edges = [(e["level"], e["t"]) for e in events if e["ev"] == "ttl_out0"]
    assert [level for level, _ in edges] == [1, 0]
    assert edges[0][1] == pytest.approx(done["t"], abs=1e-9)
    assert edges[1][1] - edges[0][1] == pytest.approx(0.005, abs=1e-9)


@pytest.mark.control
def test_tv_079_out0_modes_and_polarity(ms: Host) -> None:
    """TV-79 (MS-91): OUT0 mode 3 is refused; `F=-1` inverts the low output; F is ±1 only."""
    ms.run([(b"TTL Y=3\r", b":N-4\r\n"), (b"TTL F=-1\r", ACK)])
    assert ms.get("ttl_out0") == 1
    ms.run([(b"TTL F=2\r", b":N-4\r\n"), (b"TTL Y=1 F=1\r", ACK)])
    assert ms.get("ttl_out0") == 1


@pytest.mark.control
def test_tv_080_bare_ttl_reads_in0_inverted(ms: Host) -> None:
    """TV-80 (MS-92): bare `TTL` answers 1 while IN0 is low, 0 while it is high."""
    ms.ask(b"TTL\r", b":A 1\r\n")
    ms.input("ttl_in0", level=1)
    ms.ask(b"TTL\r", b":A 0\r\n")


def _z_stack(ms: Host) -> None:
    ms.run([(b"ZS X=10 Y=3 Z=0 F=500\r", ACK), (b"TTL X=4\r", ACK)])


def _pulse_then_where_z(ms: Host, reply: bytes) -> float:
    """An IN0 pulse, then `W Z` once the step has landed; returns the device time of the pulse."""
    at = ms.now()
    ms.input("ttl_in0", pulse_ms=1)
    ms.run([IDLE, (b"W Z\r", reply)])
    return at


@pytest.mark.control
def test_tv_082_z_stack_sawtooth(ms: Host) -> None:
    """TV-82 (MS-94, MS-90): each IN0 pulse steps Z by 10 units; after 3 steps the next returns to
    the start. Pulses are 100 ms apart (device time), well inside the 500 ms timeout."""
    _z_stack(ms)
    pulse = _pulse_then_where_z(ms, b":A 10\r\n")
    for reply in (b":A 20\r\n", b":A 30\r\n", b":A 0\r\n"):
        ms.wait_device(pulse + 0.1)
        pulse = _pulse_then_where_z(ms, reply)


@pytest.mark.control
def test_tv_083_z_stack_timeout_restarts(ms: Host) -> None:
    """TV-83 (MS-94): a pulse more than F = 500 ms after the previous one returns to the start, and
    the stack goes on from there."""
    _z_stack(ms)
    pulse = _pulse_then_where_z(ms, b":A 10\r\n")
    ms.wait_device(pulse + 0.1)
    pulse = _pulse_then_where_z(ms, b":A 20\r\n")
    ms.wait_device(pulse + 0.6)
    pulse = _pulse_then_where_z(ms, b":A 0\r\n")
    ms.wait_device(pulse + 0.1)
    _pulse_then_where_z(ms, b":A 10\r\n")


@pytest.mark.control
def test_tv_084_in0_repeats_the_last_relative_move(ms: Host) -> None:
    """TV-84 (MS-90): IN0 mode 2 repeats `R X=100`."""
    ms.run([(b"R X=100\r", ACK), IDLE, (b"TTL X=2\r", ACK)])
    ms.input("ttl_in0", pulse_ms=1)
    ms.run([IDLE, (b"W X\r", b":A 200\r\n")])


@pytest.mark.control
def test_tv_085_position_reports(ms: Host) -> None:
    """TV-85 (MS-90, MS-18): in IN0 mode 5 a pulse starts `<ms> <X> <Y>` lines every RT X = 100 ms
    (the `RM Y` axes); the next pulse, sent as soon as the second line is in (about 11 ms after it
    left, 90 ms before the third), stops them."""
    ms.run([(b"TTL X=5\r", ACK), (b"RT X=100\r", ACK)])
    ms.input("ttl_in0", pulse_ms=1)
    ms.expect(b"100 0 0\r\n200 0 0\r\n")
    ms.input("ttl_in0", pulse_ms=1)
    ms.silent(0.3)


@pytest.mark.control
def test_tv_086_ensync_output(ms: Host) -> None:
    """TV-86 (MS-95): ENSYNC goes low at `ES` and toggles when X crosses 0.5 mm, both ways; ES takes
    X or Y."""
    ms.ask(b"ES X=0.5\r", ACK)
    assert ms.get("ensync_out") == 0
    ms.run([(b"M X=10000\r", ACK), IDLE])
    assert ms.get("ensync_out") == 1
    ms.run([(b"ES Z=1\r", b":N-2\r\n"), (b"ES X?\r", b":A X=0.500000\r\n"), (b"M X=0\r", ACK), IDLE])
    assert ms.get("ensync_out") == 0


@pytest.mark.smoke
@pytest.mark.control
def test_tv_089_in1_edges_reported(ms: Host) -> None:
    """TV-89 (MS-96): with `VB X=4` each IN1 edge sends `H` (rising) or `L` (falling)."""
    ms.ask(b"VB X=4\r", ACK)
    ms.input("ttl_in1", level=1)
    ms.expect(b"H\r\n")
    ms.input("ttl_in1", level=0)
    ms.expect(b"L\r\n")


@pytest.mark.control
def test_vb_y_reads_in1(ms: Host) -> None:
    """Beside TV-91 (MS-109): `VB Y?` reads the IN1 input, so it follows its level."""
    ms.ask(b"VB Y?\r", b":A Y=0\r\n")
    ms.input("ttl_in1", level=1)
    ms.ask(b"VB Y?\r", b":A Y=1\r\n")
