"""Fixtures shared by the unit tests of the in-process `stageemu://` port."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
import serial

import emulator.urlhandler  # noqa: F401  (registers stageemu:// URLs)

OpenUrl = Callable[..., serial.SerialBase]


@pytest.fixture
def open_url() -> Iterator[OpenUrl]:
    """`open_url(url, **settings)`: a port through `serial.serial_for_url`, closed after the test."""
    ports: list[serial.SerialBase] = []

    def factory(url: str, **settings: object) -> serial.SerialBase:
        settings.setdefault("timeout", 1.0)
        port = serial.serial_for_url(url, **settings)
        ports.append(port)
        return port

    yield factory
    for port in ports:
        port.close()
