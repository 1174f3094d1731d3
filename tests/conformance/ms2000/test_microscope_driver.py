"""A real third-party host: python-microscope 0.7.0's ASIMS2000 driver on the port (TV-218).

The driver is used as its users use it, with its defaults (9600 baud, 0.5 s timeout), so the test
runs unchanged against a real controller. It reads up to CR only, so every reply after the first
starts with the LF left over from the previous one; it recognises an absent axis by silence and
reads several replies at fixed offsets (MS-106, MS-107, MS-54, MS-81, MS-LED-2). In virtual time the
driver opens the device's in-process URL and sleeps in device time. Homing (a spin to each limit)
and the two-axis build are exercised on the model in tests/unit/ms2000.
"""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import pytest
import serial

from tests.conformance.ms2000.conftest import Host

if TYPE_CHECKING:
    from tests.conformance.conftest import Target

asi = pytest.importorskip("microscope.controllers.asi")

#: a 2 mm move at the driver's speed (0.67 × 7.68 mm/s) takes 0.46 s, so the driver's own wait
#: (0.2 s, then `RDSTAT X` polls) sees the axis busy before it sees it land
OFFSET = 20000


def test_tv_218_microscope_driver(
    open_target: Callable[..., Target], monkeypatch: pytest.MonkeyPatch
) -> None:
    """TV-218 (MS-106, MS-54, MS-78, MS-81, MS-77, MS-LED-2): the driver initialises, lists X Y Z,
    reads positions and settings, moves X by an offset and waits for the move with `RDSTAT`, and
    switches its LED on and off reading the brightness back."""
    target = open_target("ms2000")
    if target.virtual:
        # The driver opens a device path with serial.Serial and waits with time.sleep. In virtual
        # time it opens the device's in-process URL instead, and its sleeps pass device time (a wall
        # sleep passes none); everything else is the driver as its users run it.
        def open_url(port: str, **settings: Any) -> serial.SerialBase:
            return serial.serial_for_url(port, **settings)

        monkeypatch.setattr(asi, "serial", SimpleNamespace(**{**vars(serial), "Serial": open_url}))
        monkeypatch.setattr(asi, "time", SimpleNamespace(sleep=target.ctl().step))
    elif "://" in target.path:
        pytest.skip("python-microscope's driver opens a device path (serial.Serial), not a URL")
    if target.real:
        with target.open() as port:
            Host(target, port).restart()
    controller: Any = asi.ASIMS2000(target.path, baudrate=9600, timeout=0.5, lights=["led1"])
    try:
        stage = controller.devices["stage"]
        assert list(stage.axes) == ["X", "Y", "Z"]
        info = controller._conn.axis_info["X"]
        assert info["Kp"] == {"value": "100", "command": "KP", "units": None}
        assert info["Enc Cnts/mm"]["value"] == "45396.00"
        # it set every axis to 0.67 × the maximum it read back (its reads end at CR: the LF of the
        # previous reply comes first)
        assert controller._conn.get_command(b"SPEED X?") == b"\n:A X=5.145600\r"
        # settings tagged with their command in INFO, read through the `:A X=v` and `:X=v A` shapes
        assert stage.get_setting("Kp X") == 100
        assert stage.get_setting("Max Lim X") == 110.0
        stage.set_setting("Wait Time X", 5)
        assert stage.get_setting("Wait Time X") == 5

        assert [stage.axes[a].position for a in "XYZ"] == [0.0, 0.0, 0.0]
        stage.axes["X"].move_by(OFFSET)
        assert controller._conn.motor_moving("X") == 0
        assert [stage.axes[a].position for a in "XYZ"] == [float(OFFSET), 0.0, 0.0]

        led = controller.devices["led1"]
        assert led.power == 0.0 and not led.get_is_on()  # the driver switches it off at start
        led.power = 0.5
        assert led.power == pytest.approx(0.5) and led.get_is_on()
        led.disable()
        assert led.power == 0.0 and not led.get_is_on()
        led.enable()
        assert led.power == pytest.approx(0.5) and led.get_is_on()
    finally:
        controller.shutdown()
        # Device.__del__ shuts the devices down again when they are collected, perhaps during a
        # later test: let that talk to a loopback port rather than to the emulator or a closed port
        driver_port = controller._conn._serial
        controller._conn._serial = serial.serial_for_url("loop://", timeout=0)
        driver_port.close()
