"""The project's thin client (protocols/clients/ms2000.py) on the port: every reply shape it parses,
motion helpers and typed errors. These run unchanged against a real controller."""

from __future__ import annotations

import pytest

from protocols.clients.ms2000 import MS2000, Halted, OutOfRange, UnknownAxis, UnknownCommand
from tests.conformance.ms2000.conftest import Host


@pytest.fixture
def stage(ms: Host) -> MS2000:
    return MS2000(ms.port)


def test_identity(stage: MS2000) -> None:
    """MS-99…MS-102, MS-105: version, build, modules, axes, who and compile date."""
    assert stage.version() == "USB-9.2k"
    assert stage.build() == "STD_XYZ"
    info = stage.build_info()
    assert info["axes"] == ["X", "Y", "Z"]
    assert info["cmd_letters"] == "XYZFTR"
    assert info["modules"] == ["LL COMMANDS", "RING BUFFER 50", "INO_INT", "LED DIMMER"]
    assert stage.axes() == ("X", "Y", "Z")
    assert stage.who() == "ASI-MS2000-XYBR-Zs-USB"
    assert stage.compile_date() == "Mar 14 2016:17:32:08"


def test_move_wait_and_where(stage: MS2000) -> None:
    """MS-51, MS-69, MS-77, MS-78: positions come back keyed in hardware order whatever the query
    order; `wait_until_idle` polls `/` (back to back: its pause between polls is a wall-clock sleep,
    which passes no device time in virtual time)."""
    assert stage.where() == {"X": 0.0, "Y": 0.0, "Z": 0.0}
    stage.move(X=1000, Y=-505)
    assert stage.is_busy()
    stage.wait_until_idle(timeout=10, poll=0)
    assert not stage.is_busy()
    assert stage.where("Y", "X") == {"X": 1000.0, "Y": -505.0}
    stage.movrel(Z=250)
    stage.wait_until_idle(timeout=10, poll=0)
    assert stage.where("Z") == {"Z": 250.0}
    stage.here(X=0)
    assert stage.where("X") == {"X": 0.0}


def test_settings_in_every_reply_shape(stage: MS2000) -> None:
    """MS-35: `:A X=v` (S), `:X=v A` (B, AC), `X=v :A` (LED), `:A v v` (MC), named values (JS)."""
    assert stage.get("S", "X", "Y") == {"X": 5.1456, "Y": 5.1456}
    stage.set("S", X=1.5)
    assert stage.get("S", "X") == {"X": 1.5}
    assert stage.get("B", "X") == {"X": 0.04}
    assert stage.get("AC", "Z", "X") == {"X": 70, "Z": 50}
    stage.set("LED", X=25)
    assert stage.get("LED", "X") == {"X": 25}
    assert stage.get("MC", "Y", "X") == {"X": 1, "Y": 1}
    assert stage.get("JS", "X", "Y") == {"JS_FAST": 100, "JS_SLOW": 5}
    assert stage.status_byte("X") == 10


@pytest.mark.smoke
def test_errors_are_typed(stage: MS2000) -> None:
    """MS-39: `:N-<code>` raises the matching exception, carrying the command."""
    with pytest.raises(OutOfRange) as error:
        stage.set("S", X=0)
    assert error.value.code == 4 and error.value.command == "S X=0"
    with pytest.raises(UnknownCommand):
        stage.command("FOO")
    with pytest.raises(UnknownAxis):
        stage.get("S", "Q")


def test_halt(stage: MS2000) -> None:
    """MS-76: HALT reports whether a commanded move was running (`:N-21`, raised as `Halted` by
    `command`)."""
    assert stage.halt() is False
    stage.move(X=100000)
    assert stage.halt() is True
    stage.move(X=0)
    with pytest.raises(Halted):
        stage.command("\\")


def test_info_parsing(stage: MS2000) -> None:
    """MS-106: INFO rows hold two 33-column items; values keep their units and command tags."""
    info = stage.info("X")
    assert len(info) == 42
    assert info["Axis Name"] == "X"
    assert info["Run Speed"] == "5.14560(mm/s)[S]"
    assert info["Kp"] == "100 [KP]"
    assert info["Finish Error"] == "0.000022 (mm)[PC}"
    assert info["Enc Cnts/mm"] == "45396.00 [C]"
    assert info["Button Enable"] == "31 [BE]"
