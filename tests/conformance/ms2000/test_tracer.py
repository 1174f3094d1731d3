"""TRACER module (§9.11) on the `ms2000-tracer` profile, and the client library's G-code
interpreter on its port: TV-199…TV-204."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
import serial

from protocols.clients.gcode import GcodeExecutor, parse_program
from protocols.clients.ms2000 import MS2000
from tests.conformance.conftest import Target
from tests.conformance.ms2000.conftest import ACK, IDLE, VERSION, Host

PROFILE = "ms2000-tracer"


@pytest.fixture
def tracer(connect: Callable[..., Host]) -> Host:
    return connect(PROFILE)


def recording(port: serial.SerialBase) -> bytearray:
    """Keep every byte the host writes to `port` from now on (to check what the client library
    sent), whatever kind of port it is: a device path, an RFC 2217 or an in-process URL."""
    written = bytearray()
    send = port.write

    def write(data: Any) -> int | None:
        written.extend(bytes(data))
        return send(data)

    port.write = write  # type: ignore[method-assign]
    return written


def test_tv_199_tracer_build(tracer: Host) -> None:
    """TV-199 (MS-TRACER-1): the build name ends `_TRACER`, `BU X` lists `TRACER` after the other
    modules, and the controller moves like any other."""
    tracer.ask(b"BU\r", b"STD_XYZ_TRACER\r\n")
    lines = tracer.reply(b"BU X\r")[:-2].split(b"\r")
    assert lines[0] == b"STD_XYZ_TRACER"
    assert lines[-4:] == [b"LL COMMANDS", b"RING BUFFER 50", b"INO_INT", b"TRACER"]
    tracer.run([(b"M X=1000\r", ACK), IDLE, (b"W X\r", b":A 1000\r\n")])


@pytest.mark.control
def test_tv_200_ready_only_at_115200(tracer: Host) -> None:
    """TV-200 (MS-TRACER-2, MS-2): ready at 115200; the switches count from the next power-up only:
    with DIP 4 and 5 up and a power cycle the controller runs at 9600, still answers, and reports
    not ready."""
    assert tracer.get("baud") == 115200
    assert tracer.get("tracer") == {"ready": True}
    tracer.input("dip", sw4="up", sw5="up")
    assert tracer.get("tracer") == {"ready": True}
    tracer.input("power_cycle")
    assert tracer.get("baud") == 9600
    assert tracer.get("tracer") == {"ready": False}
    tracer.port.baudrate = 9600
    tracer.ask(b"V\r", VERSION)


@pytest.mark.control
def test_tv_201_ttl_output_for_m03_and_m05(tracer: Host) -> None:
    """TV-201 (MS-TRACER-3): `TTL Y=1` asserts OUT0, `TTL Y=0` de-asserts it; each edge is an
    event."""
    ctl = tracer.target.ctl()
    ctl.subscribe("dut")
    tracer.ask(b"TTL Y=1\r", ACK)
    assert tracer.get("ttl_out0") == 1
    tracer.ask(b"TTL Y=0\r", ACK)
    assert tracer.get("ttl_out0") == 0
    assert [e["level"] for e in ctl.events(timeout=0.1) if e["ev"] == "ttl_out0"] == [1, 0]


@pytest.mark.control
def test_tv_202_analog_output_from_z(connect: Callable[..., Host]) -> None:
    """TV-202 (MS-TRACER-4, MS-TRACER-3): with Z's range set to ±50 µm, Z = 20 µm gives 7 V; the
    `decreasing` polarity knob gives 3 V."""
    steps = [(b"SL Z=-.05\r", ACK), (b"SU Z=.05\r", ACK), (b"M Z=200\r", ACK), IDLE]
    for overrides, volts in ((None, 7.0), ({"knobs": {"tracer_analog_polarity": "decreasing"}}, 3.0)):
        host = connect(PROFILE, overrides)
        host.run(steps)
        assert host.get("analog_out_v") == pytest.approx(volts, abs=0.001)


def test_tv_203_gcode_through_the_client_library(open_target: Callable[..., Target]) -> None:
    """TV-203 (MS-TRACER-5): `G21 G90 G01 X1 F60` makes the library send `S X=1.000000` and
    `M X=10000` and poll `/` until the move ends; `M03` sends `TTL Y=1`."""
    target = open_target(PROFILE)
    port = target.open()
    written = recording(port)
    with MS2000(port) as stage:
        # polls back to back: the library pauses between polls on the wall clock (time.sleep), which
        # passes no device time in virtual time (a 1 s move would cost 2300 polls of 10 ms)
        executor = GcodeExecutor(stage, poll_s=0)
        executor.run(parse_program("G21 G90 G01 X1 F60\nM03", start=executor.start_position()))
        lines = bytes(written).decode("ascii").split("\r")
        assert stage.where("X") == {"X": 10000.0}
    speed, move, output = lines.index("S X=1.000000"), lines.index("M X=10000"), lines.index("TTL Y=1")
    assert speed < move < output
    assert set(lines[move + 1 : output]) == {"/"}


@pytest.mark.smoke
def test_tv_204_tracer_stream_bytes_are_ordinary_input(tracer: Host) -> None:
    """TV-204 (MS-TRACER-6, MS-119): `\\xFF\\x31` is discarded as an unknown control sequence and
    the `A` left over is an unknown command."""
    tracer.run([(b"\xff\x31A\r", b":N-1\r\n"), (b"V\r", VERSION)])
