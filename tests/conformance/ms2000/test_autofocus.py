"""AUTOFOCUS module (§9.6) on profile `ms2000-af`: TV-169…TV-180.

A run takes about 3 s of device time and a calibration about 8 s, longer than the port's read
timeout: those vectors wait in `Host.scaled` (a faster device clock on a daemon, a longer read
timeout in virtual time) and measure device time.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host

AF = "ms2000-af"
FAILED = b":N-5\r\n"
#: device time runs this much faster than wall time during runs
FAST = 5.0


@pytest.fixture
def af(connect: Callable[..., Host]) -> Host:
    return connect(AF)


def z_units(host: Host) -> int:
    return int(host.reply(b"W Z\r")[3:-2])


@pytest.mark.smoke
def test_tv_169_af_parameters(af: Host) -> None:
    """TV-169 (MS-AF-1): factory scan parameters; mode 2 is reserved."""
    af.run(
        [
            (b"AF X? Y? Z? F?\r", b":A X=2 Y=0.100000 Z=0 F=50\r\n"),
            (b"AF Z=2\r", b":N-4\r\n"),
            (b"AF X=101\r", b":N-4\r\n"),
            (b"AF Y=-0.1\r", b":N-4\r\n"),
            (b"AF X? Y? Z? F?\r", b":A X=2 Y=0.100000 Z=0 F=50\r\n"),
        ]
    )


def test_tv_170_ra_z_reads_the_focus_value(af: Host) -> None:
    """TV-170 (MS-AF-2, MS-117): in focus (peak 0) the value is baseline + amplitude; it is the Z
    channel of `RA`."""
    af.run([(b"RA Z\r", b":A 1050\r\n"), (b"RA X Y Z F\r", b":A 128 128 1050 0\r\n")])


@pytest.mark.control
def test_tv_171_run_lands_on_the_peak(af: Host) -> None:
    """TV-171 (MS-AF-3, MS-AF-2, MS-33): `AF` replies when the run is over, ≈3 s later, with Z at
    the peak (10 µm = 100 units); meanwhile Z runs as in homing (status `B`, MS-81); AFINFO reports
    the run."""
    af.input("focus", peak_um=10)
    with af.scaled(FAST):
        start = af.now()
        af.write(b"AF\r")
        af.wait_device(start + 0.5)
        assert af.axis("Z")["activity"] == "home"
        af.expect(ACK)
        took = af.now() - start
    assert 2.5 <= took <= 3.5
    final = z_units(af)
    assert 80 <= final <= 120
    info = af.reply(b"AFINFO\r")[:-2].split(b"\r")
    assert info[-3].startswith(b"Last max focus: 10")
    assert info[-2:] == [b"Start pos: 0", b"Final pos: " + str(final).encode()]


@pytest.mark.control
def test_tv_172_hill_detect_stops_early(af: Host) -> None:
    """TV-172 (MS-AF-3): hill-detect turns back soon after the peak at −20 µm, far below the top
    of the range (+50 µm)."""
    af.input("focus", peak_um=-20)
    af.ask(b"AF Z=1 F=50\r", ACK)
    with af.scaled(FAST):
        start = af.now()
        af.ask(b"AF\r", ACK)
        assert af.now() - start < 2.0
    assert af.axis("Z")["max_user_mm"] < 0.045
    assert -220 <= z_units(af) <= -180


@pytest.mark.control
def test_tv_173_no_contrast(af: Host) -> None:
    """TV-173 (MS-AF-4): a flat focus curve fails with 300, back at the start."""
    af.input("focus", amplitude=0)
    with af.scaled(FAST):
        af.ask(b"AF\r", FAILED)
    af.run([(b"W Z\r", b":A 0\r\n"), (b"DU Y\r", b"300\r:A\r\n")])


@pytest.mark.smoke
@pytest.mark.control
def test_tv_174_clutch_disengaged(af: Host) -> None:
    """TV-174 (MS-AF-4): with the clutch open the run fails at once with 302; nothing moves."""
    assert af.input("clutch", engaged=False) == {"engaged": False}
    af.run([(b"AF\r", FAILED), (b"DU Y\r", b"302\r:A\r\n")])
    assert af.get("busy") is False


def test_tv_175_safety_limit(af: Host) -> None:
    """TV-175 (MS-AF-5): a 0.5 mm range would go 0.25 mm from the start: refused, 148."""
    af.run([(b"AF Y=0.5\r", ACK), (b"AF\r", FAILED), (b"DU Y\r", b"148\r:A\r\n")])


@pytest.mark.control
def test_tv_175_safety_limit_lifted(af: Host) -> None:
    """TV-175 (MS-AF-5), the other way: with `AL Z=0` the same 0.5 mm range runs, here to a peak at
    100 µm, found within one focus sample: at 10 % speed the samples are about 6 µm apart, and where
    they fall depends on when the run starts against the camera's frames."""
    af.input("focus", peak_um=100)
    af.run([(b"AF Y=0.5\r", ACK), (b"AL Z=0\r", ACK), (b"AF X=10\r", ACK)])
    with af.scaled(FAST):
        af.ask(b"AF\r", ACK)
    assert 965 <= z_units(af) <= 1035


def test_tv_176_al_parameters(af: Host) -> None:
    """TV-176 (MS-AF-5, MS-27, MS-40): the highlighted area and safety flag; both sizes 90 fail."""
    af.run(
        [
            (b"AL X? Y? Z?\r", b":A X=80 Y=50 Z=1\r\n"),
            (b"AL X=90 Y=90\r", FAILED),
            (b"AL X=1000 Y=-12\r", b":N-4\r\n"),
            (b"AL X?\r", b":A X=80\r\n"),
            (b"AL\r", b":N-3\r\n"),
            (b"AL X=1000 Q=1\r", b":N-2\r\n"),
            (b"AL X=95 Y=89\r", ACK),
            (b"AL Y=90\r", FAILED),
            (b"AL X? Y?\r", b":A X=95 Y=89\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_177_reply_value_knob(connect: Callable[..., Host]) -> None:
    """TV-177 (MS-AF-3): knob `af_reply_value` makes a successful run reply its peak value."""
    host = connect(AF, {"knobs": {"af_reply_value": True}})
    host.input("focus", peak_um=10)
    with host.scaled(FAST):
        reply = host.reply(b"AF\r")
    assert reply.startswith(b":A ")
    assert 1000 <= int(reply[3:-2]) <= 1050


@pytest.mark.control
def test_tv_178_calibration_and_halt(af: Host) -> None:
    """TV-178 (MS-AF-6, MS-33): calibration replies after its three scans of 2.6 s, back at the start,
    and sets AFADJ (the peak, 1050, already fills the scale: no gain; the background, 50, is
    zeroed); HALT right after `AFC` cancels it (`:N-21`) and, the axis being on the move, answers
    `:N-21` itself; AFADJ stays as it was."""
    af.ask(b"AFC X?\r", b":A X=18\r\n")
    with af.scaled(FAST):
        start = af.now()
        af.ask(b"AFC\r", ACK)
        assert af.now() - start > 7.5
    af.run(
        [
            (b"W Z\r", b":A 0\r\n"),
            (b"AFADJ X? Y? Z?\r", b":A X=0 Y=100 Z=0\r\n"),
            (b"AFADJ X=50\r", ACK),
            (b"AFC\r\\\r", b":N-21\r\n:N-21\r\n"),
            IDLE,
            (b"AFADJ X? Y? Z?\r", b":A X=50 Y=100 Z=0\r\n"),
        ]
    )


def test_tv_179_afadj_and_afinfo(af: Host) -> None:
    """TV-179 (MS-AF-7): adjustments, their range, and the nine-line AFINFO report."""
    af.run([(b"AFADJ X? Y? Z?\r", b":A X=50 Y=100 Z=0\r\n"), (b"AFADJ Z=4\r", b":N-4\r\n")])
    lines = [
        b"Speed: 2 %",
        b"Range: 0.100000 mm",
        b"Mode: Normal",
        b"Hill offset: 50 %",
        b"Min contrast: 18",
        b"Frame offset: 3.500000",
        b"Last max focus: 0",
        b"Start pos: 0",
        b"Final pos: 0",
    ]
    af.ask(b"AFINFO\r", b"\r".join(lines) + b"\r\n")


@pytest.mark.control
def test_tv_180_autofocus_after_xy_move(af: Host) -> None:
    """TV-180 (MS-AF-8): with `AM X=1` an XY move is followed by a silent autofocus; OUT0 mode
    10 is high once it completes, low while the next one (after the next move) runs."""
    af.input("focus", peak_um=10)
    af.run([(b"AM X=1\r", ACK), (b"TTL Y=10\r", ACK)])
    with af.scaled(FAST):
        af.ask(b"M X=1000\r", ACK)
        af.advance(0.5)
        assert af.axis("Z")["activity"] == "home"  # the autofocus run
        af.silent()  # no reply for the autofocus, while it runs
        af.idle()
        assert af.get("ttl_out0") == 1
        assert 80 <= z_units(af) <= 120
        af.ask(b"M Y=1000\r", ACK)
        af.advance(0.5)
        assert af.get("ttl_out0") == 0
        af.idle()
    assert af.get("ttl_out0") == 1
    af.run([(b"AM X=0\r", ACK), (b"AM X? Y?\r", b":A X=0 Y=0\r\n")])
