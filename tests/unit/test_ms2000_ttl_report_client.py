"""The TTL REPORT frame codec and the client's reader of the auxiliary port (MS-TTLREP-2, MS-TTLREP-4),
over pyserial's loopback."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import serial

from protocols.clients import NoReply, TtlReportPort
from protocols.ms2000 import ttl_report
from protocols.ms2000.ttl_report import TtlReport, TtlReportError

#: TV-154: X 4540 counts, Y -2292, Z 0
FRAME = b"\x18\xbc\x11\x00\x00\x19\x0c\xf7\xff\xff\x1a\x00\x00\x00\x00\x0d"


@pytest.fixture
def loop() -> Iterator[serial.SerialBase]:
    port = serial.serial_for_url("loop://", timeout=0.2)
    yield port
    port.close()


def test_encode_and_decode_the_vector_frame() -> None:
    report = TtlReport(((0x18, 4540), (0x19, -2292), (0x1A, 0)))
    assert ttl_report.encode(report.positions) == FRAME
    assert ttl_report.decode(FRAME) == report
    assert report.by_axis() == {"X": 4540, "Y": -2292, "Z": 0}
    assert report.by_axis({0x18: "A"}) == {"A": 4540, "#25": -2292, "#26": 0}
    assert ttl_report.frame_length(3) == len(FRAME)


def test_counts_wrap_at_32_bits() -> None:
    frame = ttl_report.encode([(0x18, 2**31), (0x19, -(2**31) - 1)])
    assert ttl_report.decode(frame).positions == ((0x18, -(2**31)), (0x19, 2**31 - 1))


@pytest.mark.parametrize("data", [FRAME[:-1], FRAME[:-1] + b"\n", b"1000 -505 0\r\n"])
def test_decode_refuses_what_is_not_a_frame(data: bytes) -> None:
    with pytest.raises(TtlReportError):
        ttl_report.decode(data)


def test_reader_takes_frames_by_length_even_with_cr_inside(loop: serial.SerialBase) -> None:
    """A count holding 0x0D does not end the frame early."""
    inner_cr = ttl_report.encode([(0x18, 0x0D), (0x19, 0x0D0D), (0x1A, -1)])
    loop.write(FRAME + inner_cr)
    reader = TtlReportPort(loop)
    assert reader.read().by_axis() == {"X": 4540, "Y": -2292, "Z": 0}
    assert reader.read().by_axis() == {"X": 13, "Y": 0x0D0D, "Z": -1}


def test_reader_two_axis_build_and_a_missing_frame(loop: serial.SerialBase) -> None:
    reader = TtlReportPort(loop, axes=2)
    loop.write(FRAME[:10] + b"\r")
    assert reader.read().by_axis() == {"X": 4540, "Y": -2292}
    loop.write(FRAME[:5])
    with pytest.raises(NoReply, match="no complete frame"):
        reader.read()


def test_reader_ascii_lines(loop: serial.SerialBase) -> None:
    loop.write(b"1000 -505 0\r\n1000.1 -504.9 0.0\r")
    with TtlReportPort(loop) as reader:
        assert reader.read_line() == (1000, -505, 0)
        assert reader.read_line() == (1000.1, -504.9, 0.0)
        with pytest.raises(NoReply, match="no complete line"):
            reader.read_line()
    assert not loop.is_open
