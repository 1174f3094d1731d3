"""Helpers for the MP-285 conformance tests: the host's side of the port, and device time on the
emulator.

Every instant a test measures is on the test's clock, `Target.monotonic()`: device time when the
device is served in the test process in virtual time (the default target), the wall clock on a
daemon's port or a real one. Three ways a test meets time:

- `Host` on the test's clock: replies are awaited with serial timeouts. Timing assertions
  (`Host.assert_at`, tests marked `timing`) compare the instant the last byte of a reply was read
  with the instant the device had the last byte of the host's frame, estimated as the start of the
  write plus its wire time at the host's baud (10 bits per character at 8N1 ÷ baud). In virtual time
  both are exact, so they must agree to the microsecond; on a daemon's port within the scheduling
  slack of two processes; a real controller's own latency is not specified, so there they are
  not checked.
- `fast_forward`: on a daemon, device time runs `scale` times faster than wall time, so long moves
  and silences cost little; in virtual time they cost nothing anyway, and on a real port nothing
  changes. Only for tests whose assertions do not depend on the host's timing precision (bytes,
  order, positions with a tolerance scaled alike).
- `DeviceClock` (tests marked `control`, targets opened with `timing="fast"`): the emulator's clock
  is paused and stepped by the test (`to(t)` for actions at `t`, `past(t)` to see what is due), host
  bytes are processed the instant the device reads them and replies leave at once, so every exchange
  happens at an exact device instant and positions after an interrupt come out byte for byte.
  Before stepping on a daemon, the test waits until it has the bytes it wrote (a reply arrived, or
  an observable changed): `wait_for`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import serial

from emulator.urlhandler.url import SCHEME
from protocols.mp285 import MAX_SPEED_HIGH_UM_S, Move, SetVelocity, unpack_xyz

if TYPE_CHECKING:
    from tests.conformance.conftest import Target
    from tests.support.daemon import RunningDaemon

CR = b"\r"
ZEROS = bytes(12)
CHAR = 10 / 9600  # one 8N1 character at 9600 baud (MP-3)
#: how late a reply may be on a daemon's port: the daemon's and the host's scheduling on a loaded
#: 2-core machine (a few ms typically, tens at worst), plus reading the reply through the PTY
SLACK = 0.030
#: and later still for load alone: the smoke runs in the background of `make test`, beside its
#: workers (and, in the load proof, two busy loops). Exact instants are asserted in virtual time;
#: load cannot make a reply early, so only the upper bound gets this.
LOAD = 1.0
#: how early: never by design (the device cannot act before the host's bytes have crossed the
#: wire); 1 ms covers rounding in the device's pacing and the two processes reading one clock
EARLY = 0.001
#: in virtual time every instant is exact: only float sums of device seconds may differ
EXACT = 1e-6
#: extra time a read may wait beyond the device time it expects, so a slow run fails by its
#: assertion rather than by a too short timeout (a read returns as soon as its bytes are in)
READ_MARGIN = 0.5 + LOAD
#: `DeviceClock.past` steps 1 µs past an instant so that what is due at it has happened (float sums)
NUDGE = 1e-6

DUMP_A = bytes.fromhex(
    "40 00 02 04 07 00 63 00 63 00 14 00 88 13 01 78 70 17 10 27 50 00 00 00 19 00 04 00 C8 00 54 01 0D"
)
DUMP_B = bytes.fromhex(
    "62 03 01 01 04 00 14 00 63 00 05 00 88 13 01 78 C4 09 88 13 50 00 00 00 19 00 04 00 DC 05 2E 01 0D"
)
#: TV-18: +10 µm on every axis, 0.05 s at 200 µm/s
TEN_UM = bytes.fromhex("6D FA 00 00 00 FA 00 00 00 FA 00 00 00 0D")
#: TV-29, TV-38: X = 250 (10 µm)
X_250 = bytes.fromhex("6D FA 00 00 00 00 00 00 00 00 00 00 00 0D")
#: TV-31: X + 25,000 µsteps = 1000 µm, 5 s at 200 µm/s (5000 µsteps/s)
LONG_X = bytes.fromhex("6D A8 61 00 00 00 00 00 00 00 00 00 00 0D")
#: TV-31's speed in µsteps/s: 200 µm/s × 25
LONG_X_SPEED = 5000
OpenTarget = Callable[..., "Target"]  # the `open_target` fixture

GET_POSITION = b"c\r"
GET_STATUS = b"s\r"
RESET = b"r\r"


def hx(text: str) -> bytes:
    return bytes.fromhex(text)


def position(x: int, y: int = 0, z: int = 0) -> bytes:
    """A 13-byte `c` reply (MP-27)."""
    return b"".join(v.to_bytes(4, "little", signed=True) for v in (x, y, z)) + CR


def show(data: bytes) -> str:
    """Hex for assertion messages: diffs of hex strings are readable."""
    return data.hex(" ").upper()


@dataclass
class Host:
    """A port opened as a host program opens it. Durations are device seconds: `scale` (from
    `fast_forward`) converts them to the test's clock."""

    port: serial.SerialBase
    target: Target
    scale: float = 1.0

    @property
    def char(self) -> float:
        """Wire time of one character at the host's settings."""
        port = self.port
        bits = 1 + port.bytesize + (0 if port.parity == serial.PARITY_NONE else 1) + port.stopbits
        return bits / port.baudrate

    def now(self) -> float:
        """The test's clock (`Target.monotonic`)."""
        return self.target.monotonic()

    def send(self, data: bytes) -> float:
        """Write `data`; return when the device has its last byte at the earliest (test's clock)."""
        start = self.now()
        self.port.write(data)
        return start + len(data) * self.char / self.scale

    def read(self, count: int, within: float = 1.0) -> bytes:
        """Exactly `count` bytes, due within `within` device seconds."""
        self.port.timeout = within / self.scale + READ_MARGIN
        data = self.port.read(count)
        assert len(data) == count, f"expected {count} bytes within {within} s, got {len(data)}: {show(data)}"
        return data

    def expect(self, expected: bytes, within: float = 1.0) -> float:
        """Read `len(expected)` bytes, assert they are `expected`; return when they had all arrived."""
        data = self.read(len(expected), within)
        arrived = self.now()
        assert data == expected, f"got {show(data)}, expected {show(expected)}"
        return arrived

    def quiet(self, seconds: float) -> None:
        """Nothing arrives for `seconds` device seconds."""
        self.port.timeout = seconds / self.scale
        data = self.port.read(1)
        assert data == b"", f"expected silence for {seconds} s, got {show(data)}"

    def quiet_until(self, instant: float) -> None:
        """Nothing arrives until `instant` (test's clock)."""
        self.quiet(max(0.0, instant - self.now()) * self.scale)

    def drain(self, silence: float = 0.3) -> bytes:
        """Whatever arrives until `silence` seconds pass without a byte (a read of one byte returns
        as it arrives; a longer one would wait out its timeout)."""
        self.port.timeout = silence / self.scale
        data = b""
        while chunk := self.port.read(1):
            data += chunk + self.port.read(self.port.in_waiting)
        return data

    def exchange(self, frame: bytes, expected: bytes, within: float = 1.0) -> float:
        """Send `frame`, expect `expected`; return when it had all arrived."""
        self.send(frame)
        return self.expect(expected, within)

    def status(self) -> bytes:
        self.send(GET_STATUS)
        return self.read(33)

    def position(self) -> bytes:
        self.send(GET_POSITION)
        return self.read(13)

    def after(self, instant: float, seconds: float) -> float:
        """`seconds` device seconds after `instant`, on the test's clock."""
        return instant + seconds / self.scale

    def assert_at(self, measured: float, expected: float) -> None:
        """`measured` (after the bytes were read) is `expected`: exactly in virtual time, within
        -EARLY ... +SLACK+LOAD on a daemon's port (wall time is the point there: the daemon's and the
        host's scheduling); not checked on a real controller, whose latency is not specified."""
        late = measured - expected
        if self.target.virtual:
            assert abs(late) <= EXACT, f"{late * 1e6:+.3f} µs from the expected instant"
        elif not self.target.real:
            assert -EARLY <= late <= SLACK + LOAD, f"{late * 1000:+.1f} ms from the expected instant"

    def expect_at(self, expected: bytes, instant: float, within: float = 1.0) -> None:
        """Expect `expected`, its last byte arriving at `instant` (`assert_at`)."""
        self.assert_at(self.expect(expected, within), instant)


def assert_halted(host: Host, data: bytes, seconds: float) -> None:
    """A `c` reply during the TV-31 move: Y = Z = 0 and X where `seconds` (test's clock) of motion
    put it: in virtual time to the microstep the device rounds to, elsewhere within the host's
    timing uncertainty (SLACK at each end, scaled to device time)."""
    x = int.from_bytes(data[:4], "little", signed=True)
    assert data[4:] == ZEROS[4:] + CR, show(data)
    moved = LONG_X_SPEED * seconds * host.scale
    bound = 1 if host.target.virtual else LONG_X_SPEED * SLACK * host.scale
    assert abs(x - moved) <= bound, (x, moved)


def connect(
    open_target: Callable[..., Target],
    profile: str = "mp285",
    overrides: dict[str, Any] | None = None,
    *,
    scale: float = 1.0,
    timing: str = "realistic",
    **settings: Any,
) -> Host:
    """The port opened as the vector's host opens it (`settings` change the profile's line
    settings), device time `scale`× on a daemon (`fast_forward`). A real controller is first
    brought back to the vectors' starting point: the emulator starts every test factory-fresh (a
    `stageemu://` URL as `--port` too: each open makes a device), a real unit keeps what the
    previous test left."""
    target = open_target(profile, overrides, timing)
    if target.real:
        port = target.open()
        if not target.path.startswith(f"{SCHEME}://"):
            restore_baseline(Host(port, target))
        for name, value in settings.items():
            setattr(port, name, value)
    else:
        port = target.open(**settings)
    return Host(port, target, fast_forward(target, scale))


def restore_baseline(host: Host) -> None:
    """The starting point of the vectors (§13) on a real unit: nothing outstanding, absolute mode,
    the power-on `V` word, at the origin. The way back to the origin is taken at the fastest high
    resolution speed (TV-21 leaves X 12.5 mm out: 62.5 s at the power-on 200 µm/s, 9.5 s so)."""
    host.send(hx("03 0D"))  # ^C halts a move or abandons a program; the CR ends a partial frame
    host.drain()
    reset(host)
    x, y, z = unpack_xyz(host.position()[:12])
    if (x, y, z) != (0, 0, 0):
        host.exchange(SetVelocity.of(MAX_SPEED_HIGH_UM_S, high=True).encode(), CR)
        seconds = (abs(x) + abs(y) + abs(z)) / 25 / MAX_SPEED_HIGH_UM_S
        host.exchange(Move(0, 0, 0).encode(), CR, within=seconds + 1.0)
        reset(host)


def reset(host: Host) -> None:
    """`r`: absolute mode, the power-on `V` word, no pending input; positions are kept (MP-57)."""
    host.send(RESET)
    host.drain()  # the deaf time, and the NUL some units send (MP-58)


def fast_forward(target: Target, scale: float) -> float:
    """On a daemon run device time `scale` times faster than wall time; returns the scale in force:
    1 in virtual time (a wait costs nothing there, and every instant stays exact) and on a real
    port (where nothing changes)."""
    if target.real or target.virtual:
        return 1.0
    target.ctl().clock(scale)
    return scale


def wait_for(target: Target, name: str, wanted: Callable[[Any], bool], timeout: float = 2.0) -> Any:
    """Observable `name` once `wanted(value)`: the device has acted on what the host wrote. In
    virtual time it has as soon as the write returns (on a `fast` port the device takes host bytes
    as they are handed over); a daemon reads them in its own time, so it is polled, on the wall
    clock: the device's is paused."""
    value = target.get(name)
    deadline = time.monotonic() + timeout
    while not wanted(value):
        assert not target.virtual and time.monotonic() < deadline, f"{name} is still {value!r}"
        value = target.get(name)
    return value


def wait_state(target: Target, state: str) -> None:
    wait_for(target, "state", lambda value: value == state)


@dataclass
class DeviceClock:
    """The emulator's clock, paused; `to(t)` steps it to `t` seconds after `start()`."""

    target: Target
    zero: float = field(init=False)
    _stepped: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.zero = self._stepped = self.target.ctl().pause()["now"]

    @property
    def now(self) -> float:
        """The device's time: in virtual time a host's wait (a silent read) moves it too; a paused
        daemon's moves only by steps."""
        return self.target.monotonic() if self.target.virtual else self._stepped

    def start(self) -> None:
        """t = 0 of a vector: the instant the device processed the frame just written."""
        self.zero = self.now

    def to(self, t: float) -> None:
        """Step to `t`: bytes written next are processed at `t`."""
        self._step_to(self.zero + t)

    def past(self, t: float) -> None:
        """Step just past `t` (NUDGE): everything due at `t` has happened when this returns."""
        self._step_to(self.zero + t + NUDGE)

    def _step_to(self, wanted: float) -> None:
        now = self.now
        if wanted > now:
            self._stepped = self.target.ctl().step(wanted - now)["now"]


def frozen(
    open_target: Callable[..., Target], profile: str = "mp285", overrides: dict[str, Any] | None = None
) -> tuple[Target, Host, DeviceClock]:
    """An emulator target on a `timing="fast"` port with its clock paused (tests marked `control`)."""
    target = open_target(profile, overrides, timing="fast")
    return target, Host(target.open(), target), DeviceClock(target)


def begin(target: Target, host: Host, clock: DeviceClock, frame: bytes, state: str = "MOVING") -> None:
    """t = 0 of a vector: write `frame`, wait until the device shows `state`, start the clock there."""
    host.send(frame)
    wait_state(target, state)
    clock.start()


def expect_at(host: Host, clock: DeviceClock, t: float, reply: bytes) -> None:
    """The final reply `reply` is sent exactly at `t`: 1 ms before, the device still owes it."""
    clock.to(t - 0.001)
    state = clock.target.get("state")
    assert state in ("MOVING", "STOPPING"), f"1 ms before {t} s the device is {state}, no reply owed"
    assert host.port.in_waiting == 0, f"{host.port.in_waiting} byte(s) before {t} s"
    clock.past(t)
    host.expect(reply)


class DeviceLog:
    """The warnings the emulator logs (MP-5: line mismatches), as lines from the port's name on
    (`main: host uses ...`): a daemon's stderr (`stage-emu: dut/main: ...`), or, in virtual time, the
    records of the `stage_emu` logger in this process (`mp285/main: ...`)."""

    def drain(self) -> list[str]:
        """Lines logged since the last call."""
        raise NotImplementedError

    def wait_line(self, needle: str, timeout: float = 2.0) -> str:
        """The next line containing `needle`, waiting up to `timeout` seconds (test's clock)."""
        raise NotImplementedError


def port_part(line: str) -> str:
    """`stage-emu: dut/main: text` or `mp285/main: text` -> `main: text`."""
    return line.split("/", 1)[-1]


@dataclass
class DaemonLog(DeviceLog):
    """A daemon's stderr, read without blocking."""

    daemon: RunningDaemon
    _seen: int = field(default=0, repr=False)

    def drain(self) -> list[str]:
        with self.daemon.log.changed:
            lines = self.daemon.log.lines[self._seen :]
        self._seen += len(lines)
        return [port_part(line) for line in lines]

    def wait_line(self, needle: str, timeout: float = 2.0) -> str:
        found = self.daemon.log.wait_line(needle, self._seen, timeout)
        assert found is not None, f"no log line with {needle!r} within {timeout} s"
        self._seen = found[0] + 1
        return port_part(found[1])


class HostedLog(DeviceLog, logging.Handler):
    """The warnings of a device served in this process; `wait_line` lets device time pass as a
    host's wait does until one comes."""

    def __init__(self, target: Target) -> None:
        logging.Handler.__init__(self, logging.WARNING)
        self.target = target
        self.lines: list[str] = []
        self._seen = 0

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(port_part(record.getMessage()))

    def drain(self) -> list[str]:
        lines = self.lines[self._seen :]
        self._seen = len(self.lines)
        return lines

    def wait_line(self, needle: str, timeout: float = 2.0) -> str:
        hosted = self.target.hosted
        assert hosted is not None

        def found() -> int | None:
            return next((i for i in range(self._seen, len(self.lines)) if needle in self.lines[i]), None)

        hosted.wait_for(lambda: found() is not None, hosted.deadline(timeout))
        index = found()
        assert index is not None, f"no log line with {needle!r} within {timeout} s"
        self._seen = index + 1
        return self.lines[index]
