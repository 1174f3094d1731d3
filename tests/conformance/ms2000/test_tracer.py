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


class RecordingSerial(serial.Serial):
    """A port that keeps every byte the host writes, to check what the client library sent."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.written = bytearray()
        super().__init__(*args, **kwargs)

    def write(self, data: Any) -> int | None:
        self.written += bytes(data)
        return super().write(data)


def test_tv_199_tracer_build(tracer: Host) -> None:
    """TV-199 (MS-TRACER-1): the build name ends `_TRACER`, `BU X` lists `TRACER`, and the
    controller moves like any other."""
    tracer.ask(b"BU\r", b"STD_XYZ_TRACER\r\n")
    assert b"TRACER" in tracer.reply(b"BU X\r")[:-2].split(b"\r")
    tracer.ask(b"M X=1000\r", ACK)


@pytest.mark.control
def test_tv_200_ready_only_at_115200(tracer: Host) -> None:
    """TV-200 (MS-TRACER-2): ready at 115200; with DIP 4 and 5 up and a power cycle the controller
    runs at 9600, still answers, and reports not ready."""
    assert tracer.get("tracer")["ready"] is True
    tracer.input("dip", sw4="up", sw5="up")
    tracer.input("power_cycle")
    assert tracer.get("tracer")["ready"] is False
    tracer.port.baudrate = 9600
    tracer.ask(b"V\r", VERSION)


@pytest.mark.control
def test_tv_201_ttl_output_for_m03_and_m05(tracer: Host) -> None:
    """TV-201 (MS-TRACER-3): `TTL Y=1` asserts OUT0, `TTL Y=0` de-asserts it."""
    tracer.ask(b"TTL Y=1\r", ACK)
    assert tracer.get("ttl_out0") == 1
    tracer.ask(b"TTL Y=0\r", ACK)
    assert tracer.get("ttl_out0") == 0


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
    port = RecordingSerial(target.path, baudrate=target.profile.line.baud, timeout=2.0)
    with port, MS2000(port) as stage:
        executor = GcodeExecutor(stage)
        executor.run(parse_program("G21 G90 G01 X1 F60\nM03", start=executor.start_position()))
        lines = bytes(port.written).decode("ascii").split("\r")
        assert stage.where("X") == {"X": 10000.0}
    speed, move, output = lines.index("S X=1.000000"), lines.index("M X=10000"), lines.index("TTL Y=1")
    assert speed < move < output
    assert set(lines[move + 1 : output]) == {"/"}


def test_tv_204_tracer_stream_bytes_are_ordinary_input(tracer: Host) -> None:
    """TV-204 (MS-TRACER-6, MS-119): `\\xFF\\x31` is discarded as an unknown control sequence and
    the `A` left over is an unknown command."""
    tracer.ask(b"\xff\x31A\r", b":N-1\r\n")
