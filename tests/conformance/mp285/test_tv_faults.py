"""TV-46 ... TV-49: field failure modes and the `query_interrupts_move` knob (MP-76 ... MP-80, MP-51)."""

from __future__ import annotations

import pytest

from tests.conformance.mp285.wire import (
    CHAR,
    CR,
    GET_POSITION,
    LONG_X,
    ZEROS,
    OpenTarget,
    begin,
    connect,
    expect_at,
    frozen,
    hx,
    position,
    wait_for,
)

pytestmark = pytest.mark.control


@pytest.mark.smoke
def test_tv_046_crashed_unit_answers_nul(open_target: OpenTarget) -> None:
    """TV-46 (MP-77): fault `crash`: sixteen `00` at once, then one `00` per byte received, nothing
    executed: `63 0D` gives `00 00`, 400 × `0D` 400 × `00`, and the unit is still crashed."""
    target, host, _ = frozen(open_target)
    target.input("crash")
    host.expect(bytes(16))
    host.exchange(GET_POSITION, bytes(2))
    host.exchange(CR * 400, bytes(400))
    assert target.get("crashed") is True
    host.quiet(0.05)


def test_tv_046_power_cycle_recovers(open_target: OpenTarget) -> None:
    """TV-46 (MP-76): after fault `crash` and fault `power_cycle` the unit is silent and deaf for
    1 s: a `63 0D` 0.5 s after the power cycle gets nothing, one at 1.1 s the 13 position bytes.
    (Real time: bytes lost while powering on leave no trace a paused clock could wait for; both are
    0.1 s or more from the 1 s boundary, beyond the timing slack.)"""
    host = connect(open_target)
    target = host.target
    target.input("crash")
    host.expect(bytes(16))
    target.input("power_cycle")
    cycled = host.now()  # at or after the power cycle
    host.quiet_until(cycled + 0.5 - 2 * CHAR)
    host.send(GET_POSITION)
    host.quiet_until(cycled + 1.1 - 2 * CHAR)
    host.exchange(GET_POSITION, ZEROS + CR)
    host.quiet(0.05)


def test_tv_046_ctrl_c_recovery(open_target: OpenTarget) -> None:
    """TV-46 (MP-78): `crash_recovery: ctrl_c`: a ^C revives a crashed unit and is answered `0D`."""
    target, host, _ = frozen(open_target, overrides={"knobs": {"crash_recovery": "ctrl_c"}})
    target.input("crash")
    host.expect(bytes(16))
    host.exchange(hx("03"), CR)
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_046_cr_burst_recovery(open_target: OpenTarget) -> None:
    """TV-46 (MP-77, MP-78): `crash_recovery: cr_burst` and the `zero_char` crash signature: sixteen
    `30` at once, one `30` per byte received, a stray byte restarting the count; the 200th
    consecutive CR revives the unit, unanswered and with no deaf time: `63 0D` is answered."""
    target, host, _ = frozen(open_target, overrides={"knobs": {"crash_recovery": "cr_burst"}})
    target.input("crash", signature="zero_char")
    host.expect(b"0" * 16)
    host.exchange(CR * 199 + b"x" + CR * 200, b"0" * (199 + 1 + 199))
    assert target.get("crashed") is False
    host.exchange(GET_POSITION, ZEROS + CR)
    host.quiet(0.05)


def test_tv_047_roe_crash(open_target: OpenTarget) -> None:
    """TV-47 (MP-79): `roe_crash: true`; one ROE click on X moves it by ROE_VARI = 7 µsteps; a
    `63 0D` 0.3 s later is answered, one 0.7 s later (inside [0.5, 1.0)) crashes the unit: sixteen
    `00`, then `00 00` for the two bytes."""
    target, host, clock = frozen(open_target, overrides={"knobs": {"roe_crash": True}})
    assert target.input("roe", axis="X", clicks=1) == {"position_usteps": {"X": 7, "Y": 0, "Z": 0}}
    clock.start()
    clock.to(0.3)
    host.exchange(GET_POSITION, position(7))
    clock.to(0.7)
    host.exchange(GET_POSITION, bytes(18))
    assert target.get("crashed") is True


def test_tv_048_incomplete_frame_locks_up(open_target: OpenTarget) -> None:
    """TV-48 (MP-80): `lockup_incomplete_frame_s: 1.0`: `6D 01 02` then 1.5 s of silence locks the
    unit: `63 0D` gets nothing; after fault `power_cycle` and 1.0 s, `63 0D` gives 13 bytes."""
    target, host, clock = frozen(open_target, overrides={"knobs": {"lockup_incomplete_frame_s": 1.0}})
    begin(target, host, clock, hx("6D 01 02"), "COLLECTING")
    clock.to(1.5)
    assert target.get("state") == "LOCKED"
    host.send(GET_POSITION)
    host.quiet(0.1)
    target.input("power_cycle")
    clock.start()  # the power cycle (the silence above passed device time in virtual time only)
    clock.past(1.0)
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_049_query_without_interrupting(open_target: OpenTarget) -> None:
    """TV-49 (MP-51, MP-46): `query_interrupts_move: false`: during the TV-31 move, `63` at 1.000 s
    and its CR one character later are answered at once with X = 5005 (interpolated at the CR); the
    move goes on: `0D` at 5.150 s, then X = 25,000."""
    target, host, clock = frozen(open_target, overrides={"knobs": {"query_interrupts_move": False}})
    begin(target, host, clock, LONG_X)
    clock.to(1.0)
    host.send(hx("63"))
    wait_for(target, "parser", lambda parser: parser == "collecting")
    clock.to(1.0 + CHAR)
    host.exchange(CR, hx("8D 13 00 00") + bytes(8) + CR)
    assert target.get("state") == "MOVING"
    expect_at(host, clock, 5.15, CR)
    host.exchange(GET_POSITION, hx("A8 61 00 00") + bytes(8) + CR)
