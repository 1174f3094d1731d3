"""Helpers for the MP-285 conformance tests: the host's side of the port, and device time on the
emulator.

Three ways a test meets time:

- `Host` on a real clock (the default): replies are awaited with serial timeouts. Timing
  assertions (`assert_at`, tests marked `timing`) compare the host's monotonic clock with the instant
  the device had the last byte of the host's frame, estimated as the start of the write plus its
  wire time at the host's baud (10 bits per character at 8N1 ÷ baud).
- `fast_forward`: on the emulator, device time runs `scale` times faster than wall time, so long
  moves and silences cost little; a no-op on a real port. Only for tests whose assertions do not
  depend on the host's timing precision (bytes, order, positions with a tolerance scaled alike).
- `DeviceClock` (tests marked `control`, targets opened with `timing="fast"`): the emulator's clock
  is paused and stepped by the test (`to(t)` for actions at `t`, `past(t)` to see what is due), host
  bytes are processed the instant the daemon reads them and replies leave at once, so every exchange
  happens at an exact device instant and positions after an interrupt come out byte for byte.
  Before stepping, the test waits until the daemon has the bytes it wrote (a reply arrived, or an
  observable changed): `wait_for`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import serial

from protocols.mp285 import MAX_SPEED_HIGH_UM_S, Move, SetVelocity, unpack_xyz

if TYPE_CHECKING:
    from tests.conformance.conftest import Target
    from tests.support.daemon import RunningDaemon

CR = b"\r"
ZEROS = bytes(12)
CHAR = 10 / 9600  # one 8N1 character at 9600 baud (MP-3)
#: how late a reply may be on the host's clock: the daemon's and the host's scheduling on a loaded
#: 2-core machine (a few ms typically, tens at worst), plus reading the reply through the PTY
SLACK = 0.030
#: how early: never by design (the device cannot act before the host's bytes have crossed the
#: wire); 1 ms covers rounding in the device's pacing and the two processes reading one clock
EARLY = 0.001
#: extra wall time a read may wait beyond the device time it expects, so a slow run fails by its
#: assertion rather than by a too short timeout
READ_MARGIN = 0.5
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
    `fast_forward`) converts them to wall time."""

    port: serial.Serial
    target: Target
    scale: float = 1.0

    @property
    def char(self) -> float:
        """Wire time of one character at the host's settings."""
        port = self.port
        bits = 1 + port.bytesize + (0 if port.parity == serial.PARITY_NONE else 1) + port.stopbits
        return bits / port.baudrate

    def send(self, data: bytes) -> float:
        """Write `data`; return when the device has its last byte at the earliest (host clock)."""
        start = time.monotonic()
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
        arrived = time.monotonic()
        assert data == expected, f"got {show(data)}, expected {show(expected)}"
        return arrived

    def quiet(self, seconds: float) -> None:
        """Nothing arrives for `seconds` device seconds."""
        self.port.timeout = seconds / self.scale
        data = self.port.read(1)
        assert data == b"", f"expected silence for {seconds} s, got {show(data)}"

    def quiet_until(self, instant: float) -> None:
        """Nothing arrives until `instant` (host clock)."""
        self.quiet(max(0.0, instant - time.monotonic()) * self.scale)

    def drain(self, silence: float = 0.3) -> bytes:
        """Whatever arrives until `silence` seconds pass without a byte (a read of one byte returns
        as it arrives; a longer one would wait out its timeout)."""
        self.port.timeout = silence / self.scale
        data = b""
        while chunk := self.port.read(1):
            data += chunk + self.port.read(self.port.in_waiting)
        return data

    def exchange(self, frame: bytes, expected: bytes, within: float = 1.0) -> None:
        self.send(frame)
        self.expect(expected, within)

    def status(self) -> bytes:
        self.send(GET_STATUS)
        return self.read(33)

    def position(self) -> bytes:
        self.send(GET_POSITION)
        return self.read(13)


def connect(
    open_target: Callable[..., Target],
    profile: str = "mp285",
    overrides: dict[str, Any] | None = None,
    *,
    scale: float = 1.0,
    **settings: Any,
) -> Host:
    """The port opened as the vector's host opens it (`settings` change the profile's line
    settings), device time `scale`× on the emulator (`fast_forward`). A real controller is first
    brought back to the vectors' starting point: the emulator starts every test factory-fresh, a
    real unit keeps what the previous test left."""
    target = open_target(profile, overrides)
    if target.real:
        port = target.open()
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


def assert_at(measured: float, expected: float) -> None:
    """`measured` (host clock, after the bytes were read) is `expected` within -EARLY ... +SLACK."""
    late = measured - expected
    assert -EARLY <= late <= SLACK, f"{late * 1000:+.1f} ms from the expected instant"


def fast_forward(target: Target, scale: float) -> float:
    """On the emulator run device time `scale` times faster than wall time; returns the scale in
    force (1 on a real port, where nothing changes)."""
    if target.real:
        return 1.0
    target.ctl().clock(scale)
    return scale


def wait_for(target: Target, name: str, wanted: Callable[[Any], bool], timeout: float = 2.0) -> Any:
    """Poll observable `name` until `wanted(value)`: the daemon has acted on what the host wrote."""
    deadline = time.monotonic() + timeout
    while True:
        value = target.get(name)
        if wanted(value):
            return value
        assert time.monotonic() < deadline, f"{name} is still {value!r} after {timeout} s"


def wait_state(target: Target, state: str) -> None:
    wait_for(target, "state", lambda value: value == state)


@dataclass
class DeviceClock:
    """The emulator's clock, paused; `to(t)` steps it to `t` seconds after `start()`."""

    target: Target
    now: float = field(init=False)
    zero: float = field(init=False)

    def __post_init__(self) -> None:
        self.now = self.zero = self.target.ctl().pause()["now"]

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
        if wanted > self.now:
            self.now = self.target.ctl().step(wanted - self.now)["now"]


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


@dataclass
class DaemonLog:
    """The warnings a daemon writes to its stderr (MP-5), read without blocking."""

    daemon: RunningDaemon
    _seen: int = field(default=0, repr=False)

    def drain(self) -> list[str]:
        """Lines written since the last call."""
        with self.daemon.log.changed:
            lines = self.daemon.log.lines[self._seen :]
        self._seen += len(lines)
        return lines

    def wait_line(self, needle: str, timeout: float = 2.0) -> str:
        """The next line containing `needle`."""
        found = self.daemon.log.wait_line(needle, self._seen, timeout)
        assert found is not None, f"no log line with {needle!r} within {timeout} s"
        self._seen = found[0] + 1
        return found[1]
