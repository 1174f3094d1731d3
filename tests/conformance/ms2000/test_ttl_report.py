"""TTL REPORT (§9.4): position frames on the auxiliary port on IN0 edges in mode 6, TV-154…TV-156.

The auxiliary port is opened like the main one (`Target.open_aux`, MS-5: same baud); on a real
controller it is `--aux-port PATH`, and the tests skip without it.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, SILENT, Host

TTLREP = "ms2000-ttlrep"
#: X at 1000 units, Y at -505, Z at 0 as counts (MS-TTLREP-2)
FRAME = b"\x18\xbc\x11\x00\x00\x19\x0c\xf7\xff\xff\x1a\x00\x00\x00\x00\x0d"


@pytest.mark.smoke
@pytest.mark.control
def test_tv_154_frame_on_the_aux_port(connect: Callable[..., Host]) -> None:
    """TV-154 (MS-TTLREP-2, MS-TTLREP-1, MS-5): one 16-byte frame per IN0 edge on the auxiliary port
    (also told as an `aux_tx` event), nothing on the main port."""
    ms = connect(TTLREP)
    aux = ms.target.open_aux()
    assert ms.is_port_path(ms.get("ports")["aux"])
    ms.run([(b"M X=1000 Y=-505\r", ACK), IDLE, (b"TTL X=6\r", ACK)])
    ctl = ms.target.ctl()
    ctl.subscribe("dut")
    ms.input("ttl_in0", pulse_ms=0.1)
    assert aux.read(len(FRAME)) == FRAME
    assert [e["data"] for e in ctl.events(timeout=0.1) if e["ev"] == "aux_tx"] == [FRAME.hex()]
    ms.run([SILENT])
    aux.timeout = 0.2
    assert aux.read(1) == b""


@pytest.mark.control
def test_tv_155_overrun_drops_the_second_frame(connect: Callable[..., Host]) -> None:
    """TV-155 (MS-TTLREP-3): an edge 0.5 ms after the last, while its frame (1.5 ms at 115200) is
    still going out, is dropped and logs code 87."""
    ms = connect(TTLREP)
    aux = ms.target.open_aux()
    ms.ask(b"TTL X=6\r", ACK)
    ctl = ms.target.ctl()
    ctl.pause()
    try:
        ms.input("ttl_in0", pulse_ms=0.1)
        ctl.step(0.0005)
        ms.input("ttl_in0", pulse_ms=0.1)
        ctl.step(0.01)
    finally:
        ctl.resume()
    aux.timeout = 1.0
    assert aux.read(2 * len(FRAME)) == b"\x18\0\0\0\0\x19\0\0\0\0\x1a\0\0\0\0\r"
    ms.ask(b"DU Y\r", b"87\r:A\r\n")
    assert ms.get("ttl_report") == {
        "port": "aux",
        "format": "binary",
        "frames": 1,
        "overruns": 1,
        "sending": False,
    }


@pytest.mark.control
def test_tv_156_ascii_format(connect: Callable[..., Host]) -> None:
    """TV-156 (MS-TTLREP-4): with `ttl_report_format: ascii` a pulse sends the W-formatted positions
    as one line, without `:A`, in WHERE's current form (decimals and CR only with `VB Z=1 X=8`)."""
    ms = connect(TTLREP, {"knobs": {"ttl_report_format": "ascii"}})
    aux = ms.target.open_aux()
    ms.run([(b"M X=1000 Y=-505\r", ACK), IDLE, (b"TTL X=6\r", ACK)])
    ms.input("ttl_in0", pulse_ms=1)
    assert aux.read_until(b"\r\n") == b"1000 -505 0\r\n"
    ms.ask(b"VB X=8 Z=1\r", ACK)
    where = ms.reply(b"W X Y Z\r", end=b"\r")
    assert b"." in where
    ms.silent(0.01)
    ms.input("ttl_in0", pulse_ms=1)
    assert aux.read_until(b"\r") == where.removeprefix(b":A ")
