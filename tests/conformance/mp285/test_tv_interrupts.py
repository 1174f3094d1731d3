"""TV-30 ... TV-37: ^C, and bytes that arrive while a move is outstanding (MP-48 ... MP-53).

Exact positions after an interrupt depend on the instant the device acts on it, so each vector has a
test on the paused emulator clock (`control`, byte for byte). TV-31 ... TV-33 and TV-36 also run on
the host's clock, as on hardware (device time 4× on a daemon for the long move, a tenth for TV-36's
short window), where a halted position is checked against the host's own timing: to the microstep
in virtual time, within the host's timing slack elsewhere.
"""

from __future__ import annotations

from typing import Any

import pytest

from tests.conformance.mp285.wire import (
    CHAR,
    CR,
    GET_POSITION,
    LONG_X,
    TEN_UM,
    ZEROS,
    Host,
    OpenTarget,
    assert_halted,
    begin,
    connect,
    expect_at,
    frozen,
    hx,
    position,
    wait_state,
)

HALTED = position(5000)  # TV-31: 1.000 s into the move
FINAL_TEN_UM = position(250, 250, 250)
X_0 = hx("6D 00 00 00 00 00 00 00 00 00 00 00 00 0D")


def start_long_move(host: Host) -> float:
    """Start the TV-31 move and let 1.0 s of it pass; returns when the device had the frame."""
    done = host.send(LONG_X)
    host.quiet_until(done + 1.0 / host.scale)
    return done


@pytest.mark.parametrize(
    ("frame", "reply"),
    [("03", "0D"), ("03 0D", "0D 0D"), pytest.param("03 0D 0A", "0D 0D 0D", marks=pytest.mark.smoke)],
)
def test_tv_030_idle_ctrl_c(open_target: OpenTarget, frame: str, reply: str) -> None:
    """TV-30 (MP-49): an idle ^C is answered `0D`; an Igor Pro procedure's `03 0D` gets `0D 0D`, the
    vendor-written driver's `03 0D 0A` `0D 0D 0D`."""
    host = connect(open_target)
    host.exchange(hx(frame), hx(reply))
    host.quiet(0.05)


@pytest.mark.control
def test_tv_031_ctrl_c_halts_a_move(open_target: OpenTarget) -> None:
    """TV-31 (MP-48, MP-46, MP-14): ^C at 1.000 s into a 5 s move: `3D` at once, the axes stop at
    X = 5000, `0D` at 1.150 s."""
    target, host, clock = frozen(open_target)
    begin(target, host, clock, LONG_X)
    clock.to(1.0)
    host.exchange(hx("03"), hx("3D"))
    expect_at(host, clock, 1.15, CR)
    host.exchange(GET_POSITION, HALTED)


def test_tv_031_ctrl_c_halts_a_move_on_the_host_clock(open_target: OpenTarget) -> None:
    """TV-31 (MP-48, MP-46): `3D`, then `0D`; the axes stopped where the ^C found them."""
    host = connect(open_target, scale=4)
    done = start_long_move(host)
    sent = host.send(hx("03"))
    host.expect(hx("3D"))
    host.expect(CR, within=0.15)
    assert_halted(host, host.position(), sent - done)


@pytest.mark.control
def test_tv_032_ctrl_c_and_query(open_target: OpenTarget) -> None:
    """TV-32 (MP-48, MP-52): `03 63 0D` at 1.000 s: `3D`, the `c` answered at once with the halted
    position, so by 1.020 s exactly 14 bytes have come; the 15th, `0D`, at 1.150 s."""
    target, host, clock = frozen(open_target)
    begin(target, host, clock, LONG_X)
    clock.to(1.0)
    host.exchange(hx("03 63 0D"), hx("3D") + HALTED)
    clock.past(1.020)
    assert host.port.in_waiting == 0
    expect_at(host, clock, 1.15, CR)


def test_tv_032_ctrl_c_and_query_on_the_host_clock(open_target: OpenTarget) -> None:
    """TV-32 (MP-48, MP-52): `3D`, the 13 position bytes, then the move's `0D`."""
    host = connect(open_target, scale=4)
    done = start_long_move(host)
    sent = host.send(hx("03 63 0D"))  # the ^C is the first of three bytes
    host.expect(hx("3D"))
    assert_halted(host, host.read(13), sent - done - 2 * CHAR / host.scale)
    host.expect(CR, within=0.15)


@pytest.mark.control
@pytest.mark.parametrize(
    ("overrides", "answer", "final", "error"),
    [
        (None, HALTED, "0D", ""),
        ({"knobs": {"move_interrupt_reply": "error8"}}, HALTED, "38 0D", "ERR 8"),
        ({"knobs": {"move_interrupt_reply": "error8_4"}}, b"", "3C 0D", "ERR 4"),
    ],
    ids=["cr", "error8", "error8_4"],
)
def test_tv_033_query_interrupts_a_move(
    open_target: OpenTarget, overrides: dict[str, Any] | None, answer: bytes, final: str, error: str
) -> None:
    """TV-33 (MP-51, MP-52, MP-53, MP-75): `63 0D` at 1.000 s halts the move at X = 5000 and is
    answered at once; the move's final reply at 1.150 s is `0D` (12 data bytes + `0D 0D` in all),
    `38 0D` with `error8`, and with `error8_4` the `c` is dropped and the reply is `3C 0D`; the
    display's second line shows the error."""
    target, host, clock = frozen(open_target, overrides=overrides)
    begin(target, host, clock, LONG_X)
    clock.to(1.0)
    host.send(GET_POSITION)
    wait_state(target, "STOPPING")
    host.expect(answer)
    expect_at(host, clock, 1.15, hx(final))
    assert target.get("display")[1] == error
    host.exchange(GET_POSITION, HALTED)


def test_tv_033_query_interrupts_a_move_on_the_host_clock(open_target: OpenTarget) -> None:
    """TV-33 (MP-51, MP-52): a `c` during the move halts it and is answered before its `0D`."""
    host = connect(open_target, scale=4)
    done = start_long_move(host)
    sent = host.send(GET_POSITION)  # its first byte halts the move
    assert_halted(host, host.read(13), sent - done - CHAR / host.scale)
    host.expect(CR, within=0.15)


@pytest.mark.control
def test_tv_034_second_move_is_held(open_target: OpenTarget) -> None:
    """TV-34 (MP-51, MP-52): a second `m` (X = 0) at 1.000 s halts the first at 5000 (`0D` at
    1.150 s), then runs: 200 µm in 1.0 s, `0D` at 2.300 s."""
    target, host, clock = frozen(open_target)
    begin(target, host, clock, LONG_X)
    clock.to(1.0)
    host.send(X_0)
    wait_state(target, "STOPPING")
    expect_at(host, clock, 1.15, CR)
    assert target.get("position")["usteps"]["X"] == 5000
    expect_at(host, clock, 2.3, CR)
    host.exchange(GET_POSITION, ZEROS + CR)


@pytest.mark.control
def test_tv_035_every_ctrl_c_is_acknowledged(open_target: OpenTarget) -> None:
    """TV-35 (MP-48): ^C at 1.000 s and again at 1.050 s (STOPPING): `3D`, `3D`, and the end of
    STOPPING is unchanged: `0D` at 1.150 s."""
    target, host, clock = frozen(open_target)
    begin(target, host, clock, LONG_X)
    clock.to(1.0)
    host.exchange(hx("03"), hx("3D"))
    clock.to(1.05)
    host.exchange(hx("03"), hx("3D"))
    expect_at(host, clock, 1.15, CR)
    host.exchange(GET_POSITION, HALTED)


@pytest.mark.control
@pytest.mark.parametrize(
    ("at", "answer", "final_at"),
    [(0.201, CR + CR + FINAL_TEN_UM, None), (0.160, hx("3D") + FINAL_TEN_UM, 0.200)],
    ids=["after-final", "stopping"],
)
def test_tv_036_reply_order_depends_on_timing(
    open_target: OpenTarget, at: float, answer: bytes, final_at: float | None
) -> None:
    """TV-36 (MP-49, MP-52): `03 63 0D` during the TV-18 move (final `0D` at 0.200 s). At 0.201 s
    the ^C is an idle one: `0D` (final), `0D`, 12 position bytes, `0D`. At 0.160 s (STOPPING): `3D`,
    the position, then `0D` at 0.200 s."""
    target, host, clock = frozen(open_target)
    begin(target, host, clock, TEN_UM)
    clock.to(at)
    host.exchange(hx("03 63 0D"), answer)
    if final_at is not None:
        expect_at(host, clock, final_at, CR)
    host.quiet(0.05)


@pytest.mark.smoke
def test_tv_036_reply_order_on_the_host_clock(open_target: OpenTarget) -> None:
    """TV-36 (MP-49, MP-52): sent in the middle of STOPPING (0.05 ... 0.200 s), `03 63 0D` gives
    `3D`, the final position and the move's `0D`; sent after the move's `0D`, the ^C is idle:
    `0D`, then the position. On a daemon device time runs at a tenth, so the 75 ms either side of
    the middle are 750 ms of wall time: in the background of `make test` a host, a cable or a
    daemon stalled for 75 ms is routine (the bytes then landed after the move's end)."""
    host = connect(open_target, scale=0.1)
    done = host.send(TEN_UM)
    host.quiet_until(done + 0.125 / host.scale)
    host.exchange(hx("03 63 0D"), hx("3D") + FINAL_TEN_UM + CR, within=0.2)
    host.exchange(TEN_UM, CR, within=0.15)  # already there: the settle time only
    host.exchange(hx("03 63 0D"), CR + FINAL_TEN_UM)


@pytest.mark.parametrize(
    ("overrides", "answer"),
    [(None, FINAL_TEN_UM), ({"knobs": {"terminators_interrupt_move": True}}, position(5, 5, 5))],
    ids=["default", "terminators_interrupt_move"],
)
def test_tv_037_lf_after_a_move(
    open_target: OpenTarget, overrides: dict[str, Any] | None, answer: bytes
) -> None:
    """TV-37 (MP-50): the vendor-written driver's LF one character time after the move's CR does not
    interrupt: the move's `0D`, then `0D` for the LF; `63 0D 0A` then gives the position and
    `0D 0D`. With `terminators_interrupt_move` the LF halts the axes at (5, 5, 5). Both bytes come
    in one write, so the LF's instant is exact even through a PTY."""
    host = connect(open_target, overrides=overrides)
    host.exchange(TEN_UM + hx("0A"), CR + CR, within=0.2)
    host.exchange(hx("63 0D 0A"), answer + CR)


@pytest.mark.timing
@pytest.mark.parametrize(
    ("overrides", "seconds"),
    [
        pytest.param(None, 0.200 - CHAR, marks=pytest.mark.smoke),
        ({"knobs": {"terminators_interrupt_move": True}}, 0.150),
    ],
    ids=["default", "terminators_interrupt_move"],
)
def test_tv_037_lf_reply_times(
    open_target: OpenTarget, overrides: dict[str, Any] | None, seconds: float
) -> None:
    """TV-37 (MP-50): the move's `0D` at 0.200 s after its CR, the LF's `0D` right behind it; with
    `terminators_interrupt_move` the LF (0.001 s) halts the move and `0D` comes at 0.151 s."""
    host = connect(open_target, overrides=overrides)
    lf_done = host.send(TEN_UM + hx("0A"))
    host.expect_at(CR + CR, lf_done + seconds + 2 * CHAR, within=0.2)
