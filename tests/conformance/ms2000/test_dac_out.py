"""DAC OUT module (§9.7): TV-181…TV-183.

`ms2000-seq` and `ms2000-pz-crisp` belong to later issues: these vectors run on the default profile
with overrides (tests/support/ms2000_builds.py): `SEQ_LIKE` is ms2000-seq without SEQUENCER,
`PIEZO_LIKE` the piezo Z build of ms2000-pz-crisp without CRISP.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host
from tests.support.ms2000_builds import PIEZO_LIKE, SEQ_LIKE


@pytest.mark.control
def test_tv_181_set_read_and_quantised_output(connect: Callable[..., Host]) -> None:
    """TV-181 (MS-DAC-1, MS-DAC-2) on SEQ_LIKE: the volts read back as set, value first; the
    output is the nearest of 65536 steps of 10 V."""
    host = connect(overrides=SEQ_LIKE)
    host.run([(b"WRDAC X=1.1\r", ACK), (b"WRDAC X?\r", b"X=1.100000 :A\r\n")])
    assert host.get("dac_out_v") == pytest.approx(1.100023, abs=1e-6)


def test_tv_182_range_and_missing_value(connect: Callable[..., Host]) -> None:
    """TV-182 (MS-DAC-1, MS-31) on SEQ_LIKE: outside 0–10 V is out of range; no item is missing
    parameters."""
    connect(overrides=SEQ_LIKE).run(
        [(b"WRDAC X=20\r", b":N-4\r\n"), (b"WRDAC X=-1\r", b":N-4\r\n"), (b"WRDAC\r", b":N-3\r\n")]
    )


@pytest.mark.control
def test_tv_183_piezo_build_drives_focus_axis(connect: Callable[..., Host]) -> None:
    """TV-183 (MS-DAC-3) on PIEZO_LIKE: WRDAC is refused; the DAC follows Z over its ±50 µm
    travel (25 µm is 7.5 V)."""
    host = connect(overrides=PIEZO_LIKE)
    host.run([(b"WRDAC X=1\r", b":N-5\r\n"), (b"M Z=250\r", ACK), IDLE])
    assert host.get("dac_out_v") == pytest.approx(7.5, abs=2e-4)
