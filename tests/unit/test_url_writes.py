"""Writes larger than the emulated transmit buffer on a `stageemu://` port (emulator/urlhandler/):
at fast timing the wire takes them at once, as a daemon's PTY does; at realistic timing they block
for their wire time, bounded by `write_timeout`. Either way the device answers as on a PTY: an
MS2000 line longer than `max_line` is answered `:N-6` (MS-9, TV-7), an MP-285 run of bad bytes
gets its buffer-overrun replies (MP-23)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import TypeVar

import pytest
import serial

import emulator.urlhandler  # noqa: F401  (registers stageemu://)
from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock
from emulator.hosting.port import INPUT_BACKLOG
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.transports.pty import READ_CHUNK
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST
from tests.support.memory_transport import MemoryTransport

CHAR_9600 = 10 / 9600
#: how long a write that should complete may take on a loaded machine before it counts as a hang
JOIN_S = 10.0
OVERLONG = b"A" * 20000 + b"\r"
T = TypeVar("T")


@pytest.fixture
def ports() -> Iterator[list[serial.SerialBase]]:
    opened: list[serial.SerialBase] = []
    yield opened
    for port in opened:
        port.close()


def open_port(opened: list[serial.SerialBase], url: str, **settings: object) -> serial.SerialBase:
    settings.setdefault("timeout", 1.0)
    port = serial.serial_for_url(url, **settings)
    opened.append(port)
    return port


def finishes(call: Callable[[], T]) -> T:
    """`call()`'s result, run in a thread: a call still blocked after JOIN_S fails the test rather
    than hanging it."""
    results: list[T] = []
    errors: list[BaseException] = []

    def run() -> None:
        try:
            results.append(call())
        except BaseException as exc:  # handed to the test's thread
            errors.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(JOIN_S)
    assert not thread.is_alive(), f"still blocked after {JOIN_S} s"
    if errors:
        raise errors[0]
    return results[0]


@pytest.mark.parametrize("size", [INPUT_BACKLOG, INPUT_BACKLOG + 104, 20000])
def test_fast_timing_takes_a_write_of_any_size_at_once(ports: list[serial.SerialBase], size: int) -> None:
    """The write used to wait, with nothing due to wake it, once it had filled the transmit buffer;
    the device had already taken those bytes (MS-9: the overlong line ends in `:N-6`)."""
    port = open_port(ports, "stageemu://ms2000?timing=fast")
    line = b"A" * size + b"\r"
    assert finishes(lambda: port.write(line)) == len(line)
    assert port.read(6) == b":N-6\r\n"
    port.write(b"/\r")
    assert port.read(3) == b"N\r\n"  # TV-7: the controller is ready for the next line


def test_fast_timing_non_blocking_write_takes_everything(ports: list[serial.SerialBase]) -> None:
    """`write_timeout=0` returns what the wire takes now: at fast timing, all of it."""
    port = open_port(ports, "stageemu://ms2000?timing=fast", write_timeout=0)
    assert finishes(lambda: port.write(OVERLONG)) == len(OVERLONG)
    assert port.read(6) == b":N-6\r\n"


def test_a_reader_thread_does_not_stall_a_large_write(ports: list[serial.SerialBase]) -> None:
    """A host that reads in one thread while writing in another (`stage-emu replay`, miniterm)."""
    port = open_port(ports, "stageemu://ms2000?timing=fast", timeout=5.0)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(port.read(6)), daemon=True)
    reader.start()
    assert finishes(lambda: port.write(OVERLONG)) == len(OVERLONG)
    reader.join(JOIN_S)
    assert got == [b":N-6\r\n"]


def mp285_reference(data: bytes) -> bytes:
    """What an MP-285 at fast timing answers to `data` handed over as a daemon's PTY hands it over
    (READ_CHUNK bytes per read), on a manual clock."""
    profile = load_profile("mp285")
    runner = DeviceRunner(
        lambda now: family("mp285").factory("ref", profile, now, DeviceServices()), ManualClock()
    )
    wire = MemoryTransport()
    runner.attach_transport("main", wire, FAST)
    wire.attach(LineSettings(9600, 8, "none", 1, False, False))
    for start in range(0, len(data), READ_CHUNK):
        wire.send(data[start : start + READ_CHUNK])
    return wire.take()


def test_mp285_answers_a_long_write_as_on_a_pty(ports: list[serial.SerialBase]) -> None:
    """20 000 bytes of a bad frame: a `2` CR for each run past `input_buffer_size` (MP-23), the same
    replies the model gives fed through a PTY's reads; then the device still answers `c`."""
    expected = mp285_reference(OVERLONG)
    assert expected.startswith(b"2\r") and len(expected) > 100
    port = open_port(ports, "stageemu://mp285?timing=fast", timeout=0.5)
    assert finishes(lambda: port.write(OVERLONG)) == len(OVERLONG)
    assert port.read(len(expected) + 1) == expected
    port.write(b"c\r")
    assert port.read(13) == bytes(12) + b"\r"


def test_realistic_timing_blocks_for_the_wire_time(ports: list[serial.SerialBase]) -> None:
    """At 9600 baud the write returns once all but a transmit buffer's worth has crossed the wire
    (device time, `scale=100` keeps the test short); the reply follows the last byte."""
    port = open_port(ports, "stageemu://ms2000?scale=100", timeout=JOIN_S)
    clock = port._device.clock  # type: ignore[attr-defined]
    start = clock.now()
    assert finishes(lambda: port.write(OVERLONG)) == len(OVERLONG)
    assert clock.now() - start >= (len(OVERLONG) - INPUT_BACKLOG) * CHAR_9600
    assert port.read(6) == b":N-6\r\n"
    assert clock.now() - start >= (len(OVERLONG) + 6) * CHAR_9600


@pytest.mark.parametrize("url", ["stageemu://ms2000", "stageemu://ms2000?scale=100"])
def test_realistic_write_timeout_raises_and_the_port_recovers(
    ports: list[serial.SerialBase], url: str
) -> None:
    """The write needs >= 16 s of device time: 0.16 s of wall time even at `scale=100`, past its
    0.05 s write_timeout whatever the machine's load."""
    port = open_port(ports, url, write_timeout=0.05)
    with pytest.raises(serial.SerialTimeoutException):
        finishes(lambda: port.write(OVERLONG))
    port.reset_output_buffer()
    port.write_timeout = None
    finishes(lambda: port.write(b"\r"))
    assert port.read_until(b"\n").startswith(b":N-")  # what crossed is a line, and no command
    port.write(b"/\r")
    assert port.read(3) == b"N\r\n"


def test_realistic_non_blocking_write_takes_the_transmit_buffer(ports: list[serial.SerialBase]) -> None:
    """`write_timeout=0` at 9600 baud: what fits the transmit buffer, at once."""
    port = open_port(ports, "stageemu://ms2000", write_timeout=0)
    assert finishes(lambda: port.write(OVERLONG)) == INPUT_BACKLOG
