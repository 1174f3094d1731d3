"""TRACER module (§9.11) on the model harness: what lies around the test vectors, which run in
tests/conformance/ms2000 (TV-199…TV-204)."""

from __future__ import annotations

import pytest

from emulator.device import ControlError
from emulator.devices.ms2000.modules.tracer import analog_volts
from emulator.devices.ms2000.schema import SCHEMA
from emulator.profiles.schema import Section
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def tracer() -> Harness:
    return Harness("ms2000-tracer")


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
