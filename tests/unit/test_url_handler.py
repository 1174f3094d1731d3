"""The `stageemu://` pyserial URL handler (emulator/urlhandler/): a device model inside the test's
own process, on real time. Exchanges use the MS2000's `V` (a 23-byte version line) and the MP-285's
`c` (a 13-byte position)."""

from __future__ import annotations

import importlib
import sys
import threading
import time
from pathlib import Path

import pytest
import serial

import emulator.urlhandler
from emulator.urlhandler.protocol_stageemu import Serial as StageEmuSerial
from tests.unit.conftest import OpenUrl

VERSION = b":A Version: USB-9.2k \r\n"
CHAR_9600 = 10 / 9600  # one 8N1 character on the wire


def ask(port: serial.SerialBase, command: bytes, count: int) -> bytes:
    port.write(command)
    return port.read(count)


def test_the_package_registers_the_scheme_once() -> None:
    importlib.reload(emulator.urlhandler)
    assert serial.protocol_handler_packages.count("emulator.urlhandler") == 1


def test_open_exchange_close(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000?timing=fast")
    assert isinstance(port, StageEmuSerial) and port.is_open
    assert ask(port, b"V\r", len(VERSION)) == VERSION
    port.close()
    port.close()  # closing twice is harmless, as on every pyserial port
    assert not port.is_open
    with pytest.raises(serial.PortNotOpenError):
        port.read(1)
    with pytest.raises(serial.PortNotOpenError):
        port.write(b"V\r")


def test_open_later_and_twice(open_url: OpenUrl) -> None:
    port = open_url("stageemu://mp285?timing=fast", do_not_open=True)
    assert not port.is_open
    port.open()
    assert ask(port, b"c\r", 13) == bytes(12) + b"\r"
    with pytest.raises(serial.SerialException, match="already open"):
        port.open()


def test_each_open_is_a_factory_fresh_device(open_url: OpenUrl) -> None:
    first = open_url("stageemu://ms2000?timing=fast")
    assert ask(first, b"S X=3.3\r", 4) == b":A\r\n"
    second = open_url("stageemu://ms2000?timing=fast")
    assert ask(second, b"S X?\r", 15) == b":A X=5.145600\r\n"


def test_read_waits_for_its_timeout(open_url: OpenUrl) -> None:
    """In real time a read that gets nothing sleeps its timeout (no less; load may add, so the upper
    bound only catches a hang); in virtual time exactly its timeout passes, and none at timeout 0."""
    port = open_url("stageemu://ms2000?timing=fast", timeout=0.2)
    start = time.monotonic()
    assert port.read(1) == b""
    assert 0.2 <= time.monotonic() - start < 10
    virtual = open_url("stageemu://ms2000?timing=fast&time=virtual", timeout=0.2)
    start = virtual.device_time
    assert virtual.read(1) == b""
    assert virtual.device_time - start == pytest.approx(0.2, abs=1e-9)
    virtual.timeout = 0
    start = virtual.device_time
    assert virtual.read(1) == b""
    assert virtual.device_time == start


def test_realistic_timing_paces_both_directions(open_url: OpenUrl) -> None:
    """2 bytes in, 23 out: 25 character times at 9600 8N1 (the runner releases output 0.5 ms early)."""
    port = open_url("stageemu://ms2000")
    start = time.monotonic()
    assert ask(port, b"V\r", len(VERSION)) == VERSION
    assert time.monotonic() - start >= 25 * CHAR_9600 - 0.001


def test_scale_runs_device_time_slower(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000?scale=0.1")
    start = time.monotonic()
    assert ask(port, b"V\r", len(VERSION)) == VERSION
    assert time.monotonic() - start >= 10 * (25 * CHAR_9600 - 0.001)


def test_write_in_waiting_out_waiting_and_flush(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000")
    # `V` then an unfinished line: exactly one reply, 23 characters after the first two
    assert port.write(b"V\r" + b"x" * 98) == 100  # taken at once: a driver's transmit buffer
    assert port.out_waiting > 90  # crossing the wire at 9600 baud
    start = time.monotonic()
    port.flush()
    assert port.out_waiting == 0
    assert time.monotonic() - start >= 90 * CHAR_9600
    time.sleep(0.1)  # the reply was complete 25 characters (26 ms) after the write
    assert port.in_waiting == len(VERSION)
    port.reset_input_buffer()
    assert port.in_waiting == 0


def test_write_blocks_while_the_wire_is_full(open_url: OpenUrl) -> None:
    """4096 bytes are 4.3 s of wire at 9600: the emulated transmit buffer is full, and in 0.1 s of
    device time (virtual: exact, whatever the load) the wire frees 96 characters, not 100."""
    port = open_url("stageemu://ms2000?time=virtual", write_timeout=0.1)
    port.write(b"x" * 4096)
    with pytest.raises(serial.SerialTimeoutException):
        port.write(b"x" * 100)
    port.reset_output_buffer()
    assert port.out_waiting == 0
    port.write_timeout = 0  # non-blocking: takes what fits
    assert port.write(b"x" * 5000) == 4096


def test_a_host_at_another_baud_gets_garbled_traffic(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000?timing=fast", baudrate=19200, timeout=0.3)
    assert ask(port, b"V\r", len(VERSION)) != VERSION
    port.baudrate = 9600
    port.reset_input_buffer()
    assert ask(port, b"V\r", len(VERSION)) == VERSION


@pytest.mark.parametrize(("setting", "value"), [("parity", serial.PARITY_EVEN), ("bytesize", 7)])
def test_parity_and_data_bits_reach_the_model(open_url: OpenUrl, setting: str, value: object) -> None:
    """What a pseudo-terminal cannot show: a host at 8E1 or 7N1 is not understood (MS-4)."""
    port = open_url("stageemu://ms2000?timing=fast", timeout=0.3)
    setattr(port, setting, value)
    assert ask(port, b"V\r", len(VERSION)) != VERSION
    setattr(port, setting, {"parity": serial.PARITY_NONE, "bytesize": 8}[setting])
    port.reset_input_buffer()
    assert ask(port, b"V\r", len(VERSION)) == VERSION


def test_mark_parity_is_refused(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000?timing=fast")
    with pytest.raises(ValueError, match="parity"):
        port.parity = serial.PARITY_MARK


def test_a_blocked_reader_is_woken_by_a_write_from_another_thread(open_url: OpenUrl) -> None:
    """Nothing is scheduled, so only the write's notice ends the reader's wait: without it the read
    would sleep its whole 60 s timeout. The bound is far below that and far above any load."""
    port = open_url("stageemu://ms2000?timing=fast", timeout=60.0)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(port.read(len(VERSION))))
    reader.start()
    time.sleep(0.1)  # the reader is waiting by now (if not, it finds the reply at once: same result)
    written = time.monotonic()
    port.write(b"V\r")
    reader.join(30.0)
    assert got == [VERSION]
    assert time.monotonic() - written < 20.0


def test_cancel_read_ends_a_read_without_timeout(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000?timing=fast", timeout=None)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(port.read(1)))
    reader.start()
    time.sleep(0.1)
    port.cancel_read()
    reader.join(5.0)
    assert got == [b""]


def test_a_profile_file_and_a_state_directory(open_url: OpenUrl, tmp_path: Path) -> None:
    profile = tmp_path / "stage.yaml"
    profile.write_text("spec: 1\ndevice: ms2000\nextends: ms2000\ndescription: my stage\n")
    url = f"stageemu://?profile={profile}&timing=fast&state={tmp_path / 'nv'}"
    port = open_url(url)
    assert ask(port, b"S X=3.3\r", 4) == b":A\r\n"
    assert ask(port, b"SS Z\r", 4) == b":A\r\n"
    port.close()
    assert ask(open_url(url), b"S X?\r", 15) == b":A X=3.300000\r\n"


@pytest.mark.parametrize(
    ("url", "problem"),
    [
        ("stageemu://ms2000?speed=fast", "unknown parameter 'speed'"),
        ("stageemu://ms2000?timing=slow", "timing must be one of"),
        ("stageemu://ms2000?timing=fast&timing=fast", "given 2 times"),
        ("stageemu://ms2000?scale=abc", "scale"),
        ("stageemu://ms2000?scale=0", "scale"),
        ("stageemu://ms2000?scale=nan", "scale"),
        ("stageemu://ms2000?state=", "state needs a directory"),
        ("stageemu://ms2000?profile=mp285", "give one"),
        ("stageemu://", "no profile"),
        ("stageemu://ms2000/extra", "unexpected"),
        ("stageemu://nosuchprofile", "no such profile"),
    ],
)
def test_bad_urls_raise_value_error(url: str, problem: str) -> None:
    with pytest.raises(ValueError, match=problem) as info:
        serial.serial_for_url(url)
    assert "\n" not in str(info.value)


def test_the_handler_imports_without_posix_terminal_modules(monkeypatch: pytest.MonkeyPatch) -> None:
    """Windows has no termios, fcntl, pty or tty: the whole in-process path must load without them."""
    for name in ("termios", "fcntl", "pty", "tty"):
        monkeypatch.setitem(sys.modules, name, None)  # importing it now raises ImportError
    loaded = {name: module for name, module in sys.modules.items() if name.split(".")[0] == "emulator"}
    for name in loaded:
        del sys.modules[name]
    try:
        handler = importlib.import_module("emulator.urlhandler.protocol_stageemu")
        port = handler.Serial("stageemu://ms2000?timing=fast", timeout=1.0)
        try:
            assert ask(port, b"V\r", len(VERSION)) == VERSION
        finally:
            port.close()
    finally:
        for name in [n for n in sys.modules if n.split(".")[0] == "emulator"]:
            del sys.modules[name]
        sys.modules.update(loaded)
