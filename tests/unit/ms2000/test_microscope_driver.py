"""python-microscope 0.7.0's ASIMS2000 driver against the model, through a fake serial port on the
manual clock: the parts of its use too slow or too build-specific for the conformance run of TV-218
(tests/conformance/ms2000/test_microscope_driver.py): INFO probing of a two-axis build, where the
absent axis must stay silent, and homing by SPIN to each limit and HERE (tens of seconds of motion
per axis)."""

from __future__ import annotations

from typing import Any

import pytest

from tests.unit.ms2000.conftest import Harness

asi = pytest.importorskip("microscope.controllers.asi")


class FakeSerial:
    """The part of pyserial the driver uses; reads block by moving the model's clock."""

    harness: Harness

    def __init__(self, **settings: Any) -> None:
        self.timeout = settings.get("timeout", 1.0)
        self._buffer = bytearray()

    def write(self, data: bytes) -> int:
        self._buffer += self.harness.send(data)
        return len(data)

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        end = self._buffer.find(expected)
        if end < 0:
            self.harness.wait(self.timeout)
            self._buffer += self.harness.output()
            end = self._buffer.find(expected)
        cut = len(self._buffer) if end < 0 else end + len(expected)
        data = bytes(self._buffer[:cut])
        del self._buffer[:cut]
        return data

    def readline(self) -> bytes:
        return self.read_until(b"\n")

    def flushInput(self) -> None:
        self._buffer.clear()


@pytest.fixture
def driver(monkeypatch: pytest.MonkeyPatch) -> tuple[Any, Harness]:
    def make(profile: str = "ms2000") -> tuple[Any, Harness]:
        harness = Harness(profile)
        FakeSerial.harness = harness
        monkeypatch.setattr(asi.serial, "Serial", FakeSerial)
        monkeypatch.setattr(asi.time, "sleep", harness.wait)
        return asi.ASIMS2000("fake", lights=["led1"]), harness

    return make  # type: ignore[return-value]


def test_absent_axis_stays_silent_for_the_driver_ms107(driver: Any) -> None:
    controller, _ = driver("ms2000-xy")
    assert sorted(controller.devices["stage"].axes) == ["X", "Y"]


def test_driver_homing_spins_to_limits_ms71_ms69(driver: Any) -> None:
    controller, _ = driver()
    axis = controller.devices["stage"].axes["Y"]
    limits = axis.find_limits()
    assert limits.lower == 0.0
    assert limits.upper == pytest.approx(800000, abs=1)
