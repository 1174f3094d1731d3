"""TRACER module (§9.11) on the model harness: TV-199…TV-202, TV-204 and what lies around them."""

from __future__ import annotations

import pytest

from emulator.device import ControlError
from emulator.devices.ms2000.modules.tracer import analog_volts
from emulator.devices.ms2000.schema import SCHEMA
from emulator.schema import Section
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def tracer() -> Harness:
    return Harness("ms2000-tracer")


def test_tv_199_tracer_build_is_a_standard_controller(tracer: Harness) -> None:
    """TV-199 (MS-TRACER-1): `_TRACER` build name, a `TRACER` line in `BU X`, ordinary moves."""
    assert tracer.cmd("BU") == b"STD_XYZ_TRACER\r\n"
    lines = tracer.cmd("BU X").rstrip(b"\r\n").split(b"\r")
    assert lines[0] == b"STD_XYZ_TRACER"
    assert lines[-4:] == [b"LL COMMANDS", b"RING BUFFER 50", b"INO_INT", b"TRACER"]
    assert tracer.cmd("M X=1000") == ACK
    tracer.idle()
    assert tracer.cmd("W X") == b":A 1000\r\n"


def test_tv_200_ready_only_at_115200(tracer: Harness) -> None:
    """TV-200 (MS-TRACER-2, MS-2): ready at the profile's 115200; the switches count only from the
    next power-up, after which the controller answers at 9600 and reports not ready."""
    assert tracer.get("baud") == 115200
    assert tracer.get("tracer") == {"ready": True}
    tracer.input("dip", sw4="up", sw5="up")
    assert tracer.get("tracer") == {"ready": True}
    tracer.input("power_cycle")
    assert tracer.get("baud") == 9600
    assert tracer.get("tracer") == {"ready": False}
    assert tracer.cmd("V") == b":A Version: USB-9.2k \r\n"


def test_tv_201_ttl_output_is_m03_and_m05(tracer: Harness) -> None:
    """TV-201 (MS-TRACER-3): M03/M05 are `TTL Y=1`/`TTL Y=0`; each edge is an event."""
    assert tracer.cmd("TTL Y=1") == ACK
    assert tracer.get("ttl_out0") == 1
    assert tracer.cmd("TTL Y=0") == ACK
    assert tracer.get("ttl_out0") == 0
    assert [e["level"] for e in tracer.take_events("ttl_out0")] == [1, 0]


def _set_piezo_range_and_move(h: Harness) -> None:
    for command in ("SL Z=-.05", "SU Z=.05", "M Z=200"):
        assert h.cmd(command) == ACK, command
    h.idle()


def test_tv_202_analog_output_follows_z_in_range(tracer: Harness) -> None:
    """TV-202 (MS-TRACER-4, MS-TRACER-3): Z = 20 µm in [−50, 50] µm is 7 V (V = 0.1·Z + 5)."""
    _set_piezo_range_and_move(tracer)
    assert tracer.get("analog_out_v") == pytest.approx(7.0, abs=0.001)


def test_tv_202_decreasing_polarity_knob(make: type[Harness]) -> None:
    """TV-202 (MS-TRACER-4): `tracer_analog_polarity: decreasing` follows the document's prose."""
    h = make("ms2000-tracer", overrides={"knobs": {"tracer_analog_polarity": "decreasing"}})
    _set_piezo_range_and_move(h)
    assert h.get("analog_out_v") == pytest.approx(3.0, abs=0.001)


def test_analog_output_mid_range_and_fixed_to_the_machine(tracer: Harness) -> None:
    """MS-TRACER-4, MS-49: factory limits ±110 mm put Z = 0 at 5 V; the limits are machine
    positions, so a new origin (`H`) changes the reported Z but not the voltage."""
    assert tracer.get("analog_out_v") == pytest.approx(5.0)
    assert tracer.cmd("SL Z=-.05") == ACK
    assert tracer.cmd("SU Z=.05") == ACK
    assert tracer.cmd("H Z=1000") == ACK
    assert tracer.get("analog_out_v") == pytest.approx(5.0)


def test_analog_output_ramps_with_the_move(tracer: Harness) -> None:
    """MS-TRACER-4: the BNC follows where Z is, not where it is going."""
    tracer.cmd("SL Z=-.05")
    tracer.cmd("SU Z=.05")
    tracer.cmd("M Z=500")
    tracer.wait(0.02)
    during = tracer.get("analog_out_v")
    tracer.idle()
    assert 5.0 < during < 10.0
    assert tracer.get("analog_out_v") == pytest.approx(10.0)


@pytest.mark.parametrize(
    ("z", "polarity", "volts"),
    [
        (-0.05, "increasing", 0.0),
        (0.05, "increasing", 10.0),
        (0.0, "decreasing", 5.0),
        (0.05, "decreasing", 0.0),
        (1.0, "increasing", 10.0),
        (-1.0, "decreasing", 10.0),
    ],
)
def test_analog_volts_mapping_ms_tracer_4(z: float, polarity: str, volts: float) -> None:
    assert analog_volts(z, -0.05, 0.05, polarity) == pytest.approx(volts)


def test_analog_volts_without_a_range_rests_at_zero() -> None:
    assert analog_volts(0.0, 0.1, 0.1, "increasing") == 0.0


def test_tv_204_tracer_stream_bytes_are_ordinary_input(tracer: Harness) -> None:
    """TV-204 (MS-TRACER-6, MS-119): 0xFF and the byte after it are dropped; `A` is no command."""
    assert tracer.send(b"\xff\x31A\r") == b":N-1\r\n"
    assert tracer.cmd("V") == b":A Version: USB-9.2k \r\n"


def test_tracer_observables_only_in_tracer_builds(tracer: Harness, ms: Harness) -> None:
    """§9.0, Appendix B: `tracer` and `analog_out_v` exist with the module, not without it."""
    assert {"tracer", "analog_out_v"} <= set(tracer.dev.control_names()["observables"])
    for name in ("tracer", "analog_out_v"):
        with pytest.raises(ControlError, match="no observable"):
            ms.get(name)


def test_no_lcd_segment(tracer: Harness) -> None:
    """§9.0: TRACER has no LCD segment; line 2 shows RING BUFFER's and the uptime."""
    assert tracer.get("lcd")[1] == "RB 0/0 00:00:00"


def test_polarity_knob_in_the_schema() -> None:
    config = Section(SCHEMA).check({}, ())
    assert config.knobs.tracer_analog_polarity == "increasing"
