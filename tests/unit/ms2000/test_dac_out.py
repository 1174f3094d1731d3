"""DAC OUT (§9.7) on the manual clock: the rest of MS-DAC-1…MS-DAC-3 beyond the test vectors, which
run in tests/conformance/ms2000 (TV-181…TV-183)."""

from __future__ import annotations

import pytest

from emulator.devices.ms2000.modules.dac_out import code_of, volts_of
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def seq() -> Harness:
    return Harness("ms2000-seq")


def test_codes_full_scale_and_default_not_saved_ms_dac_1_ms_dac_2(seq: Harness) -> None:
    """MS-DAC-2: 1.1 V is code 7209 of 65535; MS-DAC-1: 10 V is the top code; 0 V at power-up,
    `SS Z` keeps nothing of it."""
    assert code_of(1.1) == 7209
    assert seq.cmd("WRDAC X=10") == ACK
    assert seq.get("dac_out_v") == 10.0
    assert seq.cmd("SS Z") == ACK
    seq.input("power_cycle")
    assert seq.cmd("WRDAC X?") == b"X=0.000000 :A\r\n"
    assert volts_of(code_of(5.0)) == pytest.approx(5.0, abs=10 / 65535)


def test_lcd_segment(seq: Harness) -> None:
    """§9.0: the DAC's LCD segment is `D v.v`; beside SEQUENCER, whose segment takes line 2 alone
    (MS-SEQ-8), it is left out."""
    dac_only = Harness("ms2000", {"modules": ["LL COMMANDS", "DAC OUT"]})
    for h in (dac_only, seq):
        h.cmd("WRDAC X=2.46")
    assert "D 2.5" in dac_only.get("lcd")[1]
    assert "D" not in seq.get("lcd")[1]


def test_command_needs_the_module_ms_118() -> None:
    """MS-118: WRDAC without DAC OUT is an unknown command."""
    assert Harness().cmd("WRDAC X=1") == b":N-1\r\n"
