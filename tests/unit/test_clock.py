"""Clock modes: manual (exact), scaled (device seconds per wall second), pause/resume/step."""

from __future__ import annotations

import pytest

from emulator.hosting.clock import MAX_SCALE, MAX_STEP, MIN_SCALE, ManualClock, ScaledClock


class FakeWall:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_manual_clock_moves_only_when_told() -> None:
    clock = ManualClock()
    seen: list[float] = []
    clock.on_change(lambda: seen.append(clock.now()))
    assert clock.now() == 0.0
    assert clock.wall_delay(5.0) is None
    clock.advance(1.5)
    clock.set(2.0)
    assert seen == [1.5, 2.0]
    with pytest.raises(ValueError):
        clock.advance(-1)
    with pytest.raises(ValueError):
        clock.set(1.0)


def test_real_time_is_one_to_one() -> None:
    wall = FakeWall()
    clock = ScaledClock(1.0, wall)
    wall.t += 2.0
    assert clock.now() == pytest.approx(2.0)
    assert clock.wall_delay(3.0) == pytest.approx(1.0)
    assert clock.wall_delay(1.0) == 0.0


def test_scaled_clock_runs_faster_and_rescales_without_jumps() -> None:
    wall = FakeWall()
    clock = ScaledClock(10.0, wall)
    wall.t += 1.0
    assert clock.now() == pytest.approx(10.0)
    assert clock.wall_delay(20.0) == pytest.approx(1.0)
    clock.set_scale(2.0)
    assert clock.now() == pytest.approx(10.0)
    wall.t += 1.0
    assert clock.now() == pytest.approx(12.0)


def test_pause_step_resume() -> None:
    wall = FakeWall()
    clock = ScaledClock(1.0, wall)
    changes: list[bool] = []
    clock.on_change(lambda: changes.append(clock.paused))
    wall.t += 1.0
    clock.pause()
    wall.t += 5.0
    assert clock.now() == pytest.approx(1.0)
    assert clock.wall_delay(2.0) is None
    clock.step(0.5)
    assert clock.now() == pytest.approx(1.5)
    clock.resume()
    wall.t += 1.0
    assert clock.now() == pytest.approx(2.5)
    assert changes == [True, True, False]
    with pytest.raises(ValueError):
        clock.step(-1)
    with pytest.raises(ValueError):
        clock.set_scale(0)


@pytest.mark.parametrize("scale", [float("nan"), float("inf"), -float("inf"), 1e300, 0, -1, 1e-9, True, "2"])
def test_scale_must_be_finite_and_in_range(scale: object) -> None:
    clock = ScaledClock(1.0)
    with pytest.raises(ValueError, match="time scale must be"):
        clock.set_scale(scale)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="time scale must be"):
        ScaledClock(scale)  # type: ignore[arg-type]
    assert clock.scale == 1.0


@pytest.mark.parametrize("seconds", [float("nan"), float("inf"), 1e300, MAX_STEP + 1, -0.5])
def test_step_must_be_finite_and_in_range(seconds: float) -> None:
    clock = ScaledClock(1.0)
    clock.pause()
    before = clock.now()
    with pytest.raises(ValueError, match="step must be"):
        clock.step(seconds)
    assert clock.now() == before


def test_scale_and_step_limits_are_inclusive() -> None:
    clock = ScaledClock(MAX_SCALE)
    clock.set_scale(MIN_SCALE)
    clock.pause()
    clock.step(MAX_STEP)
    assert clock.now() >= MAX_STEP
