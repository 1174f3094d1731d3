"""Units, moves, limits, status and manual inputs (§5, §6): TV-26…TV-38, TV-45, TV-47…TV-56,
TV-59…TV-61, TV-65…TV-75.

Long moves run on a faster emulator clock on a daemon (`Host.scaled`, control channel; in virtual
time they cost no wall time anyway); their time checks are in device time, read from the control
channel, so on a daemon wall-clock jitter is divided by the scale and in virtual time it is none.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import pytest

from tests.conformance.ms2000.conftest import ACK, CHAR_S, IDLE, VERSION, Host, Step

AT_1000: list[Step] = [(b"M X=1000\r", ACK), IDLE]
#: device seconds per wall second for moves that take 10 s or more: checks in the middle of a phase
#: keep 0.5 s of device time, 25 ms of wall time, from its ends
FAST = 20.0


VECTORS = [
    pytest.param(
        [
            (b"M X=1000 Y=-505\r", ACK),
            IDLE,
            (b"W Z X Y\r", b":A 1000 -505 0\r\n"),
            # TV-27: 1000 units are 4540 counts, read back as 1000.088 units
            (b"VB Z=1\r", ACK),
            (b"W X\r", b":A 1000.1\r\n"),
            (b"VB Z=3\r", ACK),
            (b"W X Y\r", b":A 1000.088 -504.890\r\n"),
        ],
        id="tv026_tv027_move_where_decimals",
    ),
    pytest.param(
        [
            *AT_1000,
            (b"M X Y\r", ACK),
            IDLE,
            (b"W X Y\r", b":A 0 0\r\n"),
            (b"M X=\r", ACK),
            (b"M X=abc\r", ACK),
            (b"W X\r", b":A 0\r\n"),
        ],
        id="tv030_missing_values_are_zero",
    ),
    pytest.param(
        [
            (b"M X=1e3\r", ACK),
            IDLE,
            (b"W X\r", b":A 1000\r\n"),
            (b"M X=.5e1\r", ACK),
            IDLE,
            (b"W X\r", b":A 5\r\n"),
        ],
        id="tv031_number_forms",
    ),
    pytest.param(
        [
            (b"SU X?\r", b":A X=110.000\r\n"),
            (b"H X=10000\r", ACK),
            (b"SU X?\r", b":A X=111.000\r\n"),
            (b"HM X?\r", b":A X=1001.000\r\n"),
            (b"W X\r", b":A 10000\r\n"),
        ],
        id="tv048_limits_are_machine_positions",
    ),
    pytest.param(
        [
            (b"H X=1234 Y=4321 Z\r", ACK),
            (b"W X Y Z\r", b":A 1234 4321 0\r\n"),
            (b"Z\r", ACK),
            (b"W X Y Z\r", b":A 0 0 0\r\n"),
        ],
        id="tv049_here_and_zero",
    ),
    pytest.param(
        [
            (b"SU X=5\r", ACK),
            (b"M X=100000\r", ACK),
            IDLE,
            (b"W X\r", b":A 50000\r\n"),
            (b"RS X\r", b":A 74\r\n"),
        ],
        id="tv051_target_clamped_at_soft_limit",
    ),
    pytest.param(
        [
            (b"M X=10000\r", ACK),
            IDLE,
            (b"SU X+\r", ACK),
            (b"SU X?\r", b":A X=1.000\r\n"),
            (b"SU X-\r", ACK),
            (b"SU X?\r", b":A X=110.000\r\n"),
            (b"SL Z=200\r", ACK),
            (b"SL Z?\r", b":A Z=-110.000\r\n"),
        ],
        id="tv052_soft_limit_flags",
    ),
    pytest.param(
        [
            (b"M X=10000\r", ACK),
            IDLE,
            (b"HM X+\r", ACK),
            (b"HM X?\r", b":A X=1.000\r\n"),
            (b"HM X-\r", ACK),
            (b"HM X?\r", b":A X=1000.000\r\n"),
        ],
        id="tv054_home_position_flags",
    ),
    pytest.param(
        [
            (b"MC X- Y+\r", ACK),
            (b"MC X? Y?\r", b":A 0 1\r\n"),
            (b"RS X\r", b":A 8\r\n"),
            (b"RS X-\r", b":A D\r\n"),
            (b"M X=1000\r", ACK),
            (b"W X\r", b":A 0\r\n"),
            (b"MC X+\r", ACK),
            (b"RS X\r", b":A 10\r\n"),
        ],
        id="tv059_motor_disabled",
    ),
    pytest.param(
        [(b"M X=100000\r", ACK), (b"\\\r", b":N-21\r\n"), (b"/\r", b"N\r\n")],
        id="tv060_halt_during_move",
        marks=pytest.mark.smoke,
    ),
    pytest.param([(b"HALT\r", ACK), (b"\\\r", ACK), (b"\\ junk\r", ACK)], id="tv061_halt_when_idle"),
    pytest.param(
        [*AT_1000, (b"EXTRA M=4\r", ACK), IDLE, (b"W X\r", b":A 0\r\n"), (b"EXTRA M?\r", b":A 4\r\n")],
        id="tv074_extra_runs_home_press",
    ),
]


@pytest.mark.parametrize("steps", VECTORS)
def test_tv_exchanges(ms: Host, steps: Sequence[Step]) -> None:
    """Each case is one test vector on the default profile, every reply byte for byte (MS-25, MS-26,
    MS-45…MS-51, MS-64…MS-66, MS-68…MS-70, MS-75, MS-76, MS-77, MS-79, MS-81, MS-85, MS-86, MS-109)."""
    ms.run(steps)


@pytest.mark.control
def test_tv_028_targets_are_whole_counts(ms: Host) -> None:
    """TV-28 (MS-45, MS-43): 12345 units = 1.2345 mm, 56041.36 counts, rounded to 56041."""
    ms.run([(b"M X=12345\r", ACK), IDLE, (b"W X\r", b":A 12345\r\n")])
    assert ms.axis("X")["machine_counts"] == 56041


@pytest.mark.control
def test_tv_029_relative_moves_accumulate_quantisation(ms: Host) -> None:
    """TV-29 (MS-45, MS-51): each `R X=10` adds round(45.396) = 45 counts to the target."""
    ms.run([(b"R X=10\r", ACK)] * 3 + [IDLE, (b"W X\r", b":A 30\r\n")])
    assert ms.axis("X")["target_counts"] == 135


@pytest.mark.control
def test_tv_032_negative_unit_multiplier(ms: Host) -> None:
    """TV-32 (MS-44, MS-43, MS-46): a negative UM reverses commanded and reported positions."""
    ms.run(
        [
            (b"UM X?\r", b":A X=10000.000000\r\n"),
            (b"UM X=-10000 Y=10000\r", ACK),
            (b"M X=1000\r", ACK),
            IDLE,
            (b"W X\r", b":A 1000\r\n"),
        ]
    )
    assert ms.axis("X")["machine_counts"] == -4540
    ms.ask(b"UM X=0\r", b":N-4\r\n")


@pytest.mark.control
@pytest.mark.timing
def test_tv_033_trapezoid_duration(ms: Host) -> None:
    """TV-33 (MS-52, MS-53, MS-32): 10 mm at 1 mm/s with 100 ms ramps takes 10.1 s: `/` is `B` at
    10.0 s and `N` at 10.2 s (±50 ms).

    The move starts when the CR of `M X=100000` has crossed the wire (11 characters after the bytes
    reach the emulator) and at least the 4 characters of `:A` before the host has read them, so the
    device-clock readings around the exchange bound the start; the completion event carries its
    exact device time. In virtual time both bounds are the start itself and the duration is exactly
    10.1 s; on a daemon both bounds of the duration must be within the vector's ±50 ms. There the
    clock runs 5 times faster: the `B` poll lands at most 9.99 s after the start, 0.11 s of device
    time (22 ms of wall time) before the end.
    """
    ms.run([(b"S X=1\r", ACK), (b"AC X=100\r", ACK), (b"B X=0\r", ACK)])
    ms.target.ctl().subscribe("dut")
    move = b"M X=100000\r"
    with ms.scaled(5.0):
        before = ms.now()
        ms.ask(move, ACK)
        after = ms.now()
        earliest, latest = before + len(move) * CHAR_S, after - len(ACK) * CHAR_S
        ms.wait_device(before + 10.0)
        ms.ask(b"/\r", b"B\r\n")
        ms.wait_device(latest + 10.2)
        ms.ask(b"/\r", b"N\r\n")
    done = next(e for e in ms.target.ctl().events(timeout=1.0) if e["ev"] == "move_complete")
    assert done["t"] - earliest <= 10.1 + ms.slack(0.05)
    assert done["t"] - latest >= 10.1 - ms.slack(0.05)


@pytest.mark.control
@pytest.mark.timing
@pytest.mark.parametrize(
    ("overrides", "ramp_up", "ramp_down"),
    [
        pytest.param(None, b":A 63\r\n", b":A 31\r\n", id="tv034_ramp_up_sets_bit5"),
        pytest.param(
            {"knobs": {"status_bit5_up_is_one": False}}, b":A 31\r\n", b":A 63\r\n", id="tv035_older_reading"
        ),
    ],
)
def test_tv_034_035_status_byte_while_ramping(
    connect: Callable[..., Host], overrides: dict[str, Any] | None, ramp_up: bytes, ramp_down: bytes
) -> None:
    """TV-34/TV-35 (MS-79, MS-80): with S 1 mm/s and AC 1 s, a 10 mm move ramps up in its first
    second, cruises until 10 s and ramps down until 11 s; `RS X` is read in the middle of each phase
    (0.5 s margins, far above the few milliseconds an exchange takes)."""
    host = connect(overrides=overrides)
    host.run([(b"S X=1\r", ACK), (b"AC X=1000\r", ACK)])
    with host.scaled(FAST):
        start = host.now()
        host.ask(b"M X=100000\r", ACK)
        for at, reply in ((0.5, ramp_up), (5.5, b":A 15\r\n"), (10.5, ramp_down)):
            host.wait_device(start + at)
            host.ask(b"RS X\r", reply)
        host.idle()


@pytest.mark.control
def test_tv_036_new_target_replans(ms: Host) -> None:
    """TV-36 (MS-63): a new target 0.5 s into a 10 mm move re-plans from where the axis is: it brakes,
    comes back to 0 and never gets near the old target."""
    ms.ask(b"M X=100000\r", ACK)
    ms.silent(0.5)
    ms.run([(b"M X=0\r", ACK), IDLE, (b"W X\r", b":A 0\r\n")])
    assert ms.axis("X")["max_user_mm"] < 10


@pytest.mark.control
def test_tv_037_backlash_finishes_upwards(ms: Host) -> None:
    """TV-37 (MS-57, MS-35): a move down first goes B = 0.04 mm below the target."""
    ms.run([(b"B X?\r", b":X=0.040000 A\r\n"), (b"M X=10000\r", ACK), IDLE, (b"M X=0\r", ACK), IDLE])
    assert ms.axis("X")["min_user_mm"] == pytest.approx(-0.040, abs=0.0001)
    ms.ask(b"W X\r", b":A 0\r\n")


@pytest.mark.control
def test_tv_038_overshoot(ms: Host) -> None:
    """TV-38 (MS-58, MS-36): OS is kept in whole counts (2269 / 45396 mm) and passed by every move."""
    ms.run(
        [
            (b"OS X=.05 Y=0\r", ACK),
            (b"OS X?\r", b":A X=0.049982\r\n"),
            (b"B X=0\r", ACK),
            (b"M X=10000\r", ACK),
            IDLE,
        ]
    )
    assert ms.axis("X")["max_user_mm"] == pytest.approx(1.049982, abs=0.0001)
    ms.ask(b"W X\r", b":A 10000\r\n")


@pytest.mark.timing
def test_tv_045_wait_time_keeps_the_axis_busy(ms: Host) -> None:
    """TV-45 (MS-56, MS-81): after landing, WT 300 ms of `P` and busy. A 1 µm move lands within
    8 ms of its start, which is before its `:A` has reached the host (4 characters, 4 ms), so
    "landing" is taken as the moment `:A` is read; the checks at 100 ms and 400 ms after it leave
    about 100 ms either side of the 300 ms wait for the exchanges and scheduling."""
    ms.run([(b"WT X?\r", b":X=0 A\r\n"), (b"WT X=300\r", ACK)])
    ms.ask(b"M X=10\r", ACK)
    landed = ms.monotonic()
    ms.wait_until(landed + 0.1)
    ms.run([(b"/\r", b"B\r\n"), (b"RS X+\r", b":A P\r\n")])
    ms.wait_until(landed + 0.4)
    ms.ask(b"/\r", b"N\r\n")


@pytest.mark.smoke
@pytest.mark.control
@pytest.mark.timing
def test_tv_047_autozero_blocks_for_half_a_second(ms: Host) -> None:
    """TV-47 (MS-98, MS-33): `AZ X` answers when its 0.5 s balancing ends; the wire adds the 5
    characters of the command and the 4 of the reply. Exact in virtual time; on a daemon or a real
    port 50 ms early covers the host's clock readings, and load may only make it later."""

    def autozero(reply: bytes) -> None:
        start = ms.monotonic()
        ms.ask(b"AZ X\r", reply)
        elapsed = ms.monotonic() - start - (5 + len(reply)) * CHAR_S
        assert 0.5 - ms.slack(0.05) <= elapsed <= 0.5 + ms.late(0.05)

    autozero(ACK)
    ms.write(b"AZ X\r")
    ms.ask(b"V\r", ACK + VERSION)  # a command sent meanwhile is answered once the balancing is over
    ms.ask(b"AZ X?\r", b":A X=127\r\n")
    ms.input("az_fail", axis="X")
    autozero(b"NOT Zerod\r\n")


@pytest.mark.control
def test_tv_050_hardware_limit_stops_a_move(ms: Host) -> None:
    """TV-50 (MS-66, MS-50, MS-41, MS-108): a target beyond travel stops at the 60 mm switch,
    reads the upper-limit bit and `U`, and logs 34."""
    with ms.scaled(FAST):
        ms.run([(b"M X=2000000\r", ACK), IDLE])
    ms.run(
        [
            (b"W X\r", b":A 600000\r\n"),
            (b"RS X\r", b":A 74\r\n"),
            (b"RS X-\r", b":A U\r\n"),
            (b"DU Y\r", b"34\r:A\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_053_home_runs_to_the_first_limit(ms: Host) -> None:
    """TV-53 (MS-67, MS-31): `!` heads for HM (1000 mm) and stops at the 60 mm switch; busy `B`."""
    with ms.scaled(FAST):
        ms.run([(b"! X\r", ACK), (b"/\r", b"B\r\n"), (b"RS X+\r", b":A B\r\n"), IDLE])
    ms.run([(b"W X\r", b":A 600000\r\n"), (b"!\r", b":N-3\r\n")])


@pytest.mark.control
def test_tv_055_spin_until_the_limit(ms: Host) -> None:
    """TV-55 (MS-71): `@ X=100` runs open loop at 100 × 0.055 mm/s, busy `s`, and reaches the 60 mm
    switch after 60 / 5.5 = 10.9 s ("≈ 11 s": checked within ±1 s in device time, which also covers
    the "(idle)" polls' spacing)."""
    with ms.scaled(FAST):
        start = ms.now()
        ms.run([(b"@ X=100\r", ACK), (b"RS X\r", b":A 15\r\n"), (b"RS X+\r", b":A s\r\n"), IDLE])
        assert ms.now() - start == pytest.approx(10.9, abs=1.0)
    ms.run(
        [
            (b"RS X\r", b":A 74\r\n"),
            (b"W X\r", b":A 600000\r\n"),
            (b"@ X=200\r", b":N-4\r\n"),
            (b"DU Y\r", b"34\r:A\r\n"),
        ]
    )


def test_tv_056_constant_velocity(ms: Host) -> None:
    """TV-56 (MS-72): VE is clamped to the maximum, busy while moving, and ramps down within AC
    (70 ms) after `VE X=0`; `/` is asked 100 ms after that reply."""
    ms.run([(b"VE X=10\r", ACK), (b"VE X?\r", b":A X=7.680000\r\n"), (b"/\r", b"B\r\n"), (b"VE X=0\r", ACK)])
    ms.silent(0.1)
    ms.run([(b"/\r", b"N\r\n"), (b"VE X?\r", b":A X=0.000000\r\n")])


@pytest.mark.control
def test_tv_065_drift_is_corrected(ms: Host) -> None:
    """TV-65 (MS-88, MS-61): with MA 0 a 5 µm push is moved back, and nothing is logged."""
    ms.advance(0.2, ("disturb", {"axis": "X", "um": 5}))
    ms.run([(b"W X\r", b":A 0\r\n"), (b"DU Y\r", b":A\r\n")])


@pytest.mark.control
def test_tv_066_correction_gives_up_then_maintain_2(ms: Host) -> None:
    """TV-66 (MS-61, MS-88): a held push defeats 18 corrections in 0.5 s (code 60); MA 2 keeps the
    servo on (status 14). Released, the axis first ramps back the 5 µm; the status is read once
    that correction is over (0.5 s of device time), so a slow host cannot catch it mid-ramp."""
    ms.advance(0.6, ("disturb", {"axis": "X", "um": 5, "hold": True}))
    ms.run([(b"DU Y\r", b"60\r:A\r\n"), (b"MA X=4\r", b":N-4\r\n"), (b"MA X=2\r", ACK)])
    ms.advance(0.5, ("disturb", {"axis": "X", "um": 0}))
    ms.run([(b"RS X\r", b":A 14\r\n"), (b"W X\r", b":A 0\r\n")])


@pytest.mark.control
def test_tv_067_runaway_disables_the_axis(ms: Host) -> None:
    """TV-67 (MS-62): a 2 mm push exceeds RU 1.5 mm: the axis is disabled (`D`) and 30 is logged."""
    ms.input("disturb", axis="X", um=2000, hold=True)
    ms.run([(b"RS X\r", b":A 8\r\n"), (b"RS X-\r", b":A D\r\n"), (b"DU Y\r", b"30\r:A\r\n")])


@pytest.mark.control
def test_tv_068_stall(ms: Host) -> None:
    """TV-68 (MS-88, MS-41): a stalled axis stops dead, ends the move and logs 20."""
    ms.ask(b"M X=100000\r", ACK)
    assert ms.input("stall", axis="X") is True
    ms.run([(b"/\r", b"N\r\n"), (b"DU Y\r", b"20\r:A\r\n")])


@pytest.mark.control
def test_tv_069_closed_limit_switch(ms: Host) -> None:
    """TV-69 (MS-87): a closed upper switch sets bit 6 and blocks motion towards it (code 34)."""
    ms.input("limit", axis="X", end="upper", closed=True)
    ms.run(
        [
            (b"RS X\r", b":A 74\r\n"),
            (b"M X=10000\r", ACK),
            IDLE,
            (b"W X\r", b":A 0\r\n"),
            (b"DU Y\r", b"34\r:A\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_070_joystick(ms: Host) -> None:
    """TV-70 (MS-83, MS-117): full deflection runs X at 7.68 mm/s and is not busy. The deflection
    ends on a paused clock 1.0 s after a clock reading taken just before it began: in virtual time
    it lasts exactly 1.0 s, 76800 units; on a daemon 1.0 s less at most one control round trip,
    inside the vector's 76000…77600."""
    start = ms.now()
    ms.input("joystick", x=1.0, y=0)
    ms.run([(b"/\r", b"N\r\n"), (b"RA X Y\r", b":A 255 128\r\n")])
    ctl = ms.target.ctl()
    ctl.pause()
    try:
        ctl.step(start + 1.0 - ms.now())
        ms.input("joystick", x=0, y=0)
    finally:
        ctl.resume()
    where = ms.reply(b"W X\r")
    assert where.startswith(b":A ")
    assert abs(int(where[3:-2]) - 76800) <= ms.slack(800)


@pytest.mark.control
def test_tv_071_focus_wheel(ms: Host) -> None:
    """TV-71 (MS-84): 100 wheel counts of 0.5 µm move Z by 50 µm."""
    ms.advance(0.5, ("wheel", {"counts": 100}))
    ms.run([(b"W Z\r", b":A 500\r\n"), (b"/\r", b"N\r\n")])


@pytest.mark.control
def test_tv_072_zero_button(ms: Host) -> None:
    """TV-72 (MS-85, MS-86): a normal zero press zeroes every axis and is flagged (64) once."""
    ms.run(AT_1000)
    ms.advance(0.2, ("button", {"name": "zero", "ms": 200}))
    ms.run([(b"W X Y Z\r", b":A 0 0 0\r\n"), (b"EXTRA M?\r", b":A 64\r\n"), (b"EXTRA M?\r", b":A 0\r\n")])


@pytest.mark.control
def test_tv_073_disabled_zero_button(ms: Host) -> None:
    """TV-73 (MS-86): `BE Z=12` leaves only the joystick button and `@` enabled."""
    ms.run([*AT_1000, (b"BE X?\r", b":A X=31\r\n"), (b"BE Z=12\r", ACK)])
    ms.advance(0.2, ("button", {"name": "zero", "ms": 200}))
    ms.ask(b"W X\r", b":A 1000\r\n")


@pytest.mark.control
def test_tv_075_joystick_button_toggles_speed(ms: Host) -> None:
    """TV-75 (MS-85, MS-81): each normal press toggles slow/fast, shown left for 1 s as `s`/`f`, then
    gone."""
    for char in (b"s", b"f"):
        ms.advance(0.2, ("button", {"name": "joystick", "ms": 200}))
        ms.ask(b"RS X-\r", b":A " + char + b"\r\n")
    ms.silent(1.0)
    ms.ask(b"RS X-\r", b":A  \r\n")
