"""DAC OUT (§9.7) on the manual clock: TV-181…TV-183 and the rest of MS-DAC-1…MS-DAC-3.

The vectors run on `ms2000-seq`, the piezo build on `ms2000-pz-crisp`.
"""

from __future__ import annotations

import pytest

from emulator.devices.ms2000.modules.dac_out import code_of, volts_of
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def seq() -> Harness:
    return Harness("ms2000-seq")


@pytest.fixture
def piezo() -> Harness:
    return Harness("ms2000-pz-crisp")


def test_tv_181_set_read_and_quantised_output(seq: Harness) -> None:
    """TV-181 (MS-DAC-1, MS-DAC-2): 1.1 V reads back as set; the output is code 7209 of 65535."""
    assert seq.cmd("WRDAC X=1.1") == ACK
    assert seq.cmd("WRDAC X?") == b"X=1.100000 :A\r\n"
    assert seq.get("dac_out_v") == pytest.approx(1.100023, abs=1e-6)
    assert code_of(1.1) == 7209


def test_tv_182_range_and_missing_value(seq: Harness) -> None:
    """TV-182 (MS-DAC-1, MS-31)."""
    assert seq.cmd("WRDAC X=20") == b":N-4\r\n"
    assert seq.cmd("WRDAC X=-1") == b":N-4\r\n"
    assert seq.cmd("WRDAC") == b":N-3\r\n"
    assert seq.get("dac_out_v") == 0.0


def test_full_scale_and_default_not_saved_ms_dac_1(seq: Harness) -> None:
    """MS-DAC-1: 10 V is the top code; 0 V at power-up, `SS Z` keeps nothing of it."""
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


def test_tv_183_piezo_build_drives_focus_axis(piezo: Harness) -> None:
    """TV-183 (MS-DAC-3): WRDAC is refused; the DAC follows Z across its ±50 µm travel, also
    while it moves."""
    assert piezo.cmd("WRDAC X=1") == b":N-5\r\n"
    assert piezo.get("dac_out_v") == pytest.approx(5.0, abs=2e-4)
    assert piezo.cmd("M Z=250") == ACK
    piezo.wait(0.001)
    assert 5.0 < piezo.get("dac_out_v") < 7.5
    piezo.idle()
    assert piezo.get("dac_out_v") == pytest.approx(7.5, abs=2e-4)


def test_command_needs_the_module_ms_118() -> None:
    """MS-118: WRDAC without DAC OUT is an unknown command."""
    assert Harness().cmd("WRDAC X=1") == b":N-1\r\n"
