"""The thin client (protocols/clients/mp285.py) driving the port through whole sessions: what an
acquisition program does, byte-exact underneath because the client is."""

from __future__ import annotations

import pytest

from protocols.clients.mp285 import BadCommand, Mp285
from protocols.mp285 import Vector, Velocity
from tests.conformance.mp285.wire import CHAR, OpenTarget, connect, frozen, wait_state


def test_client_session(open_target: OpenTarget) -> None:
    """Status, velocity, moves in µm in both modes, an interrupted move, origin, a program with a
    pause, reset (MP-32 ... MP-73)."""
    host = connect(open_target)
    stage = Mp285(host.port)
    status = stage.status()
    assert (status.version, status.step_div) == (340, 25)
    assert stage.velocity == Velocity(200)

    stage.set_velocity(2000)
    stage.move_to_um(20.0, -10.0, 4.0)
    assert stage.position_um() == (20.0, -10.0, 4.0)
    stage.relative()
    stage.move_by_um(-20.0, 10.0, -4.0)
    assert stage.position() == (0, 0, 0)

    stage.set_velocity(1000)
    stage.move_by_um(2000.0, 0.0, 0.0, wait=False)  # 2 s
    host.quiet(0.3)
    assert stage.interrupt() is True
    halted = stage.position()
    x, y, z = stage.to_um(halted)
    assert (y, z) == (0, 0)
    if host.target.virtual:  # the move's frame (14 characters) was on the wire as the 0.3 s began
        assert halted[0] == int((0.3 - 13 * CHAR) * 25_000)
    else:
        assert 250 < x < 400  # 0.3 s at 1000 µm/s, plus the host's latencies
    stage.set_origin()
    assert stage.position() == (0, 0, 0)

    program = (Vector.move(250, 0, 0), Vector.pause(), Vector.move(0, -250, 0))
    stage.download(1, program)
    assert stage.upload(1) == program
    stage.execute(1)
    assert stage.paused == 1
    assert stage.position() == (250, 0, 0)
    stage.continue_program()
    assert stage.paused is None
    assert stage.position() == (250, -250, 0)

    stage.reset()
    assert (stage.mode, stage.velocity) == ("absolute", None)
    stage.move_to(0, 0, 0)
    assert stage.velocity == Velocity(200)  # read from the status to size the move's timeout
    assert stage.position() == (0, 0, 0)

    # the origin back where it was: a real unit keeps it for the tests that follow
    stage.set_velocity(2000)
    stage.move_by(*(-v for v in halted))
    stage.set_origin()


def test_client_on_the_usb_profile(open_target: OpenTarget) -> None:
    """MP-2, MP-38: an MP-285A on its USB port (RTS/CTS from the profile) clamps 6000 µm/s to 3000
    at low resolution, and the client tracks the clamped speed."""
    stage = Mp285(connect(open_target, "mp285a").port, model="mp285a")
    assert stage.port.rtscts
    stage.set_velocity(6000)
    assert stage.velocity == Velocity(3000) == stage.status().velocity
    stage.move_to_um(300.0, 0.0, -300.0)
    assert stage.position_um() == (300.0, 0.0, -300.0)


def test_client_mt800_units(open_target: OpenTarget) -> None:
    """MP-28: 20 µsteps per µm on an MT-800's X and Y, 25 on Z."""
    stage = Mp285(connect(open_target, "mp285-mt800").port, stage="mt800")
    stage.move_to_um(50.0, -25.0, 10.0)
    assert stage.position() == (1000, -500, 250)


@pytest.mark.smoke
def test_client_typed_errors(open_target: OpenTarget) -> None:
    """MP-19, MP-36: with `out_of_range: error4` a target beyond travel raises `BadCommand`, code '4',
    and nothing moves."""
    stage = Mp285(connect(open_target, overrides={"knobs": {"out_of_range": "error4"}}).port)
    with pytest.raises(BadCommand) as info:
        stage.move_to(400_000, 0, 0)
    assert info.value.code == 0x34
    assert stage.position() == (0, 0, 0)


@pytest.mark.control
def test_client_interrupt_after_the_move_ended(open_target: OpenTarget) -> None:
    """MP-49, TV-36: a ^C sent after the move's `0D` was sent gets an idle `0D` behind it; the
    client reads both and reports that nothing was halted."""
    target, host, clock = frozen(open_target)
    stage = Mp285(host.port)
    stage.move_to(250, 250, 250, wait=False)
    wait_state(target, "MOVING")
    clock.start()
    clock.past(0.2)
    assert stage.interrupt() is False
    assert stage.position() == (250, 250, 250)
