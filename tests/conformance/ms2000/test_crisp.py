"""CRISP module (§9.5): TV-157…TV-168 on `ms2000-crisp`."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, Host, Step

PROFILE = "ms2000-crisp"
READY: list[Step] = [(b"LK\r", ACK), (b"LK X?\r", b":A R\r\n")]
LOCKED_STATES = (b":A K\r\n", b":A F\r\n")


@pytest.fixture
def crisp(connect: Callable[..., Host]) -> Host:
    return connect(PROFILE)


def lock_in_focus(host: Host) -> None:
    """From `R`: lock, and let 200 ms of device time pass for the lock to settle in `F`."""
    host.ask(b"LK F=83\r", ACK)
    host.advance(0.2)
    host.ask(b"LK X?\r", b":A F\r\n")


def test_tv_157_idle_then_ready(crisp: Host) -> None:
    """TV-157 (MS-CRISP-1, MS-CRISP-2): `I` at power-up; bare `LK` advances to `R`."""
    crisp.run([(b"LK X?\r", b":A I\r\n"), *READY])


@pytest.mark.control
def test_tv_158_lock_unlock_idle(crisp: Host) -> None:
    """TV-158 (MS-CRISP-3, MS-CRISP-2): 83 locks (`K`, then `F` within 200 ms with the surface at
    Z = 0), 85 unlocks, 79 goes idle."""
    crisp.run(READY)
    crisp.ask(b"LK F=83\r", ACK)
    assert crisp.reply(b"LK X?\r") in LOCKED_STATES
    crisp.advance(0.2)
    crisp.run(
        [
            (b"LK X?\r", b":A F\r\n"),
            (b"LK F=85\r", ACK),
            (b"LK X?\r", b":A R\r\n"),
            (b"LK F=79\r", ACK),
            (b"LK X?\r", b":A I\r\n"),
        ]
    )


@pytest.mark.smoke
def test_tv_159_readings(crisp: Host) -> None:
    """TV-159 (MS-CRISP-4): readings end with one space before the terminator."""
    crisp.run(
        [
            *READY,
            (b"LK Y?\r", b":A 0 \r\n"),
            (b"LK T?\r", b":A 3000 \r\n"),
            (b"LK Z=5\r", ACK),
            (b"LK Z?\r", b":A 5 \r\n"),
            (b"LK M=20\r", ACK),
            (b"LK M?\r", b":A 20 \r\n"),
            (b"LK Y?\r", b":A -5 \r\n"),
        ]
    )


@pytest.mark.control
def test_tv_160_extra_line_and_lcd(crisp: Host) -> None:
    """TV-160 (MS-CRISP-4, MS-CRISP-9): `EXTRA X?` (or `EX X?`) is the bare CRISP LCD line, also on
    LCD line 2."""
    crisp.run([*READY, (b"EXTRA X?\r", b"R 3000    0 \r\n"), (b"EX X?\r", b"R 3000    0 \r\n")])
    assert "R 3000    0" in crisp.get("lcd")[1]


def test_tv_161_settings_defaults(crisp: Host) -> None:
    """TV-161 (MS-CRISP-5): what Micro-Manager's CRISP device reads at start-up, A_axis F6."""
    crisp.run(
        [
            (b"LR Y?\r", b":A Y=0.650000\r\n"),
            (b"LR Z?\r", b":A Z=1.000000\r\n"),
            (b"LR F?\r", b":A F=0.005000\r\n"),
            (b"UL X?\r", b":A X=99.000000\r\n"),
            (b"AL Z?\r", b":A Z=0.000100\r\n"),
            (b"RT F?\r", b":A F=1.000000\r\n"),
            (b"LR T?\r", b":A T=4.000000\r\n"),
            (b"UL X? Y? Z? F?\r", b":A X=99.000000 Y=10.000000 Z=2.000000 F=2.000000\r\n"),
            (b"AL X? Z?\r", b":A X=1.000000 Z=0.000100\r\n"),
            (b"EXTRA Y?\r", b":A 0.0\r\n"),  # the LED: off, then on at `LK`
            (b"LK\r", ACK),
            (b"EXTRA Y?\r", b":A 30.0\r\n"),
        ]
    )


def test_tv_162_numerical_aperture(crisp: Host) -> None:
    """TV-162 (MS-CRISP-5, MS-31): NA 1.3 halves the cal range and the in-focus window; bare `AL`
    is missing parameters."""
    crisp.run(
        [
            (b"LR Y=1.3\r", ACK),
            (b"LR F?\r", b":A F=0.002500\r\n"),
            (b"AL Z?\r", b":A Z=0.000050\r\n"),
            (b"AL\r", b":N-3\r\n"),
            (b"LR\r", b":N-3\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_163_lock_follows_drift(crisp: Host) -> None:
    """TV-163 (MS-CRISP-6, MS-CRISP-5): drifting 1 µm/s for 5 s, the lock stays in focus throughout
    (read every 100 ms) and Z follows 5 µm (45…55 units); bare `UL` unlocks, and nothing is busy."""
    crisp.run(READY)
    lock_in_focus(crisp)
    crisp.input("crisp", drift_um_per_s=1)
    for _ in range(50):
        crisp.advance(0.1)
        assert crisp.get("crisp")["state"] == "F"
    crisp.ask(b"LK X?\r", b":A F\r\n")
    where = crisp.reply(b"W Z\r")
    assert where.startswith(b":A ") and 45 <= int(where[3:-2]) <= 55
    crisp.run([(b"UL\r", ACK), (b"LK X?\r", b":A R\r\n"), (b"/\r", b"N\r\n")])


@pytest.mark.control
def test_tv_164_lock_lost(crisp: Host) -> None:
    """TV-164 (MS-CRISP-2, MS-CRISP-6): a surface 2 mm away pulls Z beyond `LR Z` = 1 mm: error `E`,
    Z stopped just past 1 mm; bare `LK` goes from `E` to `R`."""
    crisp.run(READY)
    lock_in_focus(crisp)
    crisp.advance(3.0, ("crisp", {"surface_um": 2000}))
    crisp.ask(b"LK X?\r", b":A E\r\n")
    assert 1.0 < crisp.axis("Z")["user_mm"] < 1.1
    crisp.run([(b"LK\r", ACK), (b"LK X?\r", b":A R\r\n")])


def test_tv_165_direct_codes(crisp: Host) -> None:
    """TV-165 (MS-CRISP-3): the code of a state character enters it; Tiger-only and unknown codes
    are out of range and change nothing; `LK X=82` is the historical form of `LK F=82`."""
    crisp.run(
        [
            (b"LK F=66\r", ACK),
            (b"LK X?\r", b":A B\r\n"),
            (b"LK F=84\r", b":N-4\r\n"),
            (b"LK F=200\r", b":N-4\r\n"),
            *[(bad, b":N-4\r\n") for bad in (b"LK F=90\r", b"LK F=65\r", b"LK F=75.5\r", b"LK X=0\r")],
            (b"LK X?\r", b":A B\r\n"),
            (b"LK X=82\r", ACK),
            (b"LK X?\r", b":A R\r\n"),
            (b"LK X\r", ACK),
            (b"LK X?\r", b":A R\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_166_ttl_lock_and_in_focus_output(crisp: Host) -> None:
    """TV-166 (MS-CRISP-7): IN0 mode 9 locks on a high level from `R` and unlocks on a low one;
    OUT0 mode 12 is high in `F` only."""
    crisp.run([*READY, (b"TTL X=9\r", ACK)])
    crisp.input("ttl_in0", level=1)
    assert crisp.reply(b"LK X?\r") in LOCKED_STATES
    crisp.input("ttl_in0", level=0)
    crisp.run([(b"LK X?\r", b":A R\r\n"), (b"TTL Y=12\r", ACK)])
    assert crisp.get("ttl_out0") == 0
    lock_in_focus(crisp)
    assert crisp.get("ttl_out0") == 1
    crisp.run([(b"LK Z=500\r", ACK), (b"LK X?\r", b":A K\r\n")])  # far outside the in-focus window
    assert crisp.get("ttl_out0") == 0
    crisp.advance(0.3)
    crisp.ask(b"LK X?\r", b":A F\r\n")
    assert crisp.get("ttl_out0") == 1


def test_tv_167_focus_curve(crisp: Host) -> None:
    """TV-167 (MS-CRISP-8, MS-18): `ack`, then `<z> <error>` lines across ± `LR F` (-50…50, rising),
    then `end`; the previous state comes back, Z where it was."""
    crisp.run([*READY, (b"LK F=97\r", ACK)])
    crisp.port.timeout = 15.0  # about 3500 characters at 9600 baud
    stream = crisp.port.read_until(b"end\r\n")
    check_focus_curve(stream)
    crisp.run([(b"LK X?\r", b":A R\r\n"), (b"W Z\r", b":A 0\r\n")])


@pytest.mark.control
def test_tv_167_focus_curve_states(crisp: Host) -> None:
    """TV-167 (MS-CRISP-8): while the curve is swept the state goes through `a`…`e`, then back to
    `R`; read every 10 ms of device time on a paused clock, the stream taken as it comes."""
    crisp.run([*READY, (b"LK F=97\r", ACK)])
    seen, stream = set(), b""
    ctl = crisp.target.ctl()
    ctl.pause()
    try:
        for _ in range(300):
            ctl.step(0.01)
            seen.add(crisp.get("crisp")["state"])
            stream += crisp.port.read(crisp.port.in_waiting)
    finally:
        ctl.resume()
    crisp.port.timeout = 15.0
    stream += crisp.port.read_until(b"end\r\n")
    check_focus_curve(stream)
    assert seen == set("abcdeR")


def check_focus_curve(stream: bytes) -> None:
    """TV-167's stream: 351 `<z> <error>` lines, z rising from -50 to 50, then `end`."""
    assert stream.endswith(b"\r\nend\r\n")
    lines = stream.decode().split("\r\n")[:-2]
    assert all(
        len(pair) == 2 and all(v.lstrip("-").isdigit() for v in pair) for pair in map(str.split, lines)
    )
    samples = [tuple(map(int, line.split())) for line in lines]
    assert len(samples) == 351 and 3000 <= len(stream) <= 4000
    assert samples[0] == (-50, 500) and samples[-1] == (50, -500)
    assert all(z1 <= z2 for (z1, _), (z2, _) in itertools.pairwise(samples))


@pytest.mark.control
def test_tv_168_observable(crisp: Host) -> None:
    """TV-168 (MS-CRISP-9, MS-CRISP-1): `crisp` gives {state, error, offset, sum} as the queries
    read them."""
    crisp.run([*READY, (b"LK Z=-7\r", ACK)])
    crisp.input("crisp", surface_um=0.3, sum=2500)
    seen = crisp.get("crisp")
    crisp.run(
        [
            (b"LK X?\r", f":A {seen['state']}\r\n".encode()),
            (b"LK Y?\r", f":A {seen['error']} \r\n".encode()),
            (b"LK Z?\r", f":A {seen['offset']} \r\n".encode()),
            (b"LK T?\r", f":A {seen['sum']} \r\n".encode()),
        ]
    )
    assert (seen["state"], seen["error"], seen["offset"], seen["sum"]) == ("R", 37, -7, 2500)
    crisp.ask(b"LK X? Y? Z? T?\r", b":A R 37 -7 2500 \r\n")
