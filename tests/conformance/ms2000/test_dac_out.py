"""DAC OUT module (§9.7): TV-181…TV-183.

TV-181 and TV-182 run on `ms2000-seq`, TV-183 on the piezo build `ms2000-pz-crisp`.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, Host


@pytest.mark.control
def test_tv_181_set_read_and_quantised_output(connect: Callable[..., Host]) -> None:
    """TV-181 (MS-DAC-1, MS-DAC-2): the volts read back as set, value first; the
    output is the nearest of 65536 steps of 10 V."""
    host = connect("ms2000-seq")
    host.run([(b"WRDAC X=1.1\r", ACK), (b"WRDAC X?\r", b"X=1.100000 :A\r\n")])
    assert host.get("dac_out_v") == pytest.approx(1.100023, abs=1e-6)


@pytest.mark.smoke
def test_tv_182_range_and_missing_value(connect: Callable[..., Host]) -> None:
    """TV-182 (MS-DAC-1, MS-31): outside 0–10 V is out of range; no item is missing
    parameters."""
    connect("ms2000-seq").run(
        [
            (b"WRDAC X=20\r", b":N-4\r\n"),
            (b"WRDAC X=-1\r", b":N-4\r\n"),
            (b"WRDAC\r", b":N-3\r\n"),
            (b"WRDAC X?\r", b"X=0.000000 :A\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_183_piezo_build_drives_focus_axis(connect: Callable[..., Host]) -> None:
    """TV-183 (MS-DAC-3) on ms2000-pz-crisp: WRDAC is refused; the DAC follows Z over its ±50 µm
    travel (0 is 5 V, 25 µm is 7.5 V), also while it moves (the 25 µm take about 60 ms)."""
    host = connect("ms2000-pz-crisp")
    host.ask(b"WRDAC X=1\r", b":N-5\r\n")
    assert host.get("dac_out_v") == pytest.approx(5.0, abs=2e-4)
    host.ask(b"M Z=250\r", ACK)
    assert 5.0 < host.get("dac_out_v") < 7.5
    host.idle()
    assert host.get("dac_out_v") == pytest.approx(7.5, abs=2e-4)
