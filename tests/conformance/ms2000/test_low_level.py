"""Low-level binary mode (§8, LL COMMANDS): TV-122…TV-128.

A write frame is never answered; the vectors' "⇒ ∅" after a frame or a 0xFF pair is checked by the
exact reply of the read frame that follows (any stray byte would come first), and with a 1 s silence
where nothing follows.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, SILENT, VERSION, Host

ENTER, LEAVE, HUNDREDTHS, TENTHS = b"\xffB", b"\xffA", b"\xffH", b"\xffT"
READ_POSITION = b"\x18a\x03:"
READ_BUSY = b"\x18?\x00:"


def wait_idle_low_level(host: Host, timeout: float = 30.0) -> None:
    """The vectors' "(idle)" in low-level mode: poll the busy frame until `b`, pausing between
    polls as `Host.idle` does."""
    deadline = host.monotonic() + timeout
    while True:
        host.write(READ_BUSY)
        answer = host.port.read(1)
        assert answer in (b"B", b"b")
        if answer == b"b":
            return
        assert host.monotonic() < deadline, f"still busy after {timeout} s"
        host.poll_pause()


def test_tv_122_to_126_low_level_session(ms: Host) -> None:
    """TV-122…TV-126 (MS-119…MS-124), one session as the vectors chain them.

    TV-122: 0xFF `B` enters low-level mode silently; `a` reads -12345 as 24-bit LSB first.
    TV-123: `?` busy, `~` status (bit 1 always set), `l` position + status.
    TV-124: `T` moves to 100000 tenths of a micron; busy `B` until it lands (polled, rather than the
    vector's fixed 3 s wait: the 11.2 mm move takes 2.2 s).
    TV-125: `D` writes the increment, `d` reads it, `+` steps by it; the vector waits 1 s (silent).
    TV-126: a zero-data frame without n, an unknown axis id and an ASCII line are consumed silently;
    0xFF `A` returns to ASCII, where X reads 2 (enabled, manual input off after `K`).
    """
    ms.ask(b"H X=-12345\r", ACK)
    ms.run([(ENTER, b""), (READ_POSITION, b"\xc7\xcf\xff")])
    ms.run([(READ_BUSY, b"b"), (b"\x18~\x01:", b"\x0a"), (b"\x18l\x03:", b"\xc7\xcf\xff\x0a")])
    ms.run([(b"\x18T\x03\xa0\x86\x01:", b""), (READ_BUSY, b"B")])
    wait_idle_low_level(ms)
    ms.ask(READ_POSITION, b"\xa0\x86\x01")
    ms.run([(b"\x18D\x03\xe8\x03\x00:", b""), (b"\x18d\x03:", b"\xe8\x03\x00"), (b"\x18+\x00:", b""), SILENT])
    ms.ask(READ_POSITION, b"\x88\x8a\x01")
    ms.run([(b"\x18K:", b""), (b"\x20a\x03:", b""), (b"V\r", b""), (LEAVE, b""), SILENT])
    ms.ask(b"RS X\r", b":A 2\r\n")


@pytest.mark.smoke
def test_tv_127_where_decimals_by_control_pair(ms: Host) -> None:
    """TV-127 (MS-119): 0xFF `H` makes WHERE print one decimal (hundredths of a micron), 0xFF `T`
    none, without a reply."""
    ms.run(
        [
            (b"H X=-12345\r", ACK),
            (HUNDREDTHS, b""),
            (b"W X\r", b":A -12345.0\r\n"),
            (TENTHS, b""),
            (b"W X\r", b":A -12345\r\n"),
        ]
    )


def test_tv_128_no_low_level_without_the_module(connect: Callable[..., Host]) -> None:
    """TV-128 (MS-119): without LL COMMANDS the pair 0xFF `B` is dropped and ASCII goes on."""
    host = connect(overrides={"modules": ["RING BUFFER", "INO_INT", "LED DIMMER"]})
    host.ask(ENTER + b"V\r", VERSION)


@pytest.mark.parametrize(
    ("frames", "reply"),
    [
        pytest.param(
            b"\x18a\x03\x99\x99:", b"\x00\x00\x00", id="read_with_stray_data", marks=pytest.mark.smoke
        ),
        pytest.param(b"\x18Q\x03:" + READ_POSITION, b"\x00\x00\x00", id="unknown_command_consumed"),
        pytest.param(b"\x19a\x03:\x1al\x03:", b"\x00\x00\x00\x00\x00\x00\x0a", id="other_axes"),
    ],
)
def test_frames_beyond_the_vectors(ms: Host, frames: bytes, reply: bytes) -> None:
    """Beside TV-122…TV-126 (MS-123): bytes before a read's `:` are ignored, an unknown command is
    consumed up to `:`, and the Y and Z ids answer for their axes."""
    ms.write(ENTER)
    ms.ask(frames, reply)
