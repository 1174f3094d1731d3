"""The host side of the MS2000 conformance suite: a `Host` writes bytes to the port exactly as a host
program would and checks every byte that comes back.

Waiting is always for bytes: replies are read with the port's timeout, "(idle)" polls `/` until
`N\\r\\n` with a pause between polls, and a pause is a read that must time out with nothing received
(which is also the check that the controller sent nothing meanwhile). Control-channel helpers (`now`,
`advance`, `scaled`) skip the test on a real port.

Every instant a test measures is on `Host.monotonic()`, the target's clock: device time in virtual
time (the default target: a wait costs no wall time and every instant is exact), the wall clock on a
daemon or a real port. `Host.slack` is a timing check's tolerance: none in virtual time, the given
one where the wall clock decides.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

import pytest
import serial

if TYPE_CHECKING:
    from tests.conformance.conftest import Target

#: one 8N1 character on the wire at 9600 baud: start + 8 data + stop bits
CHAR_S = 10 / 9600
#: "⇒ ∅" of the test vectors: no byte within 1 s
SILENCE_S = 1.0
#: the pause between two `/` polls of "(idle)" (device seconds), as host programs leave: a long move
#: costs ten polls a second, not one per reply time (a 10 s move: about 15 ms of wall time in
#: virtual time)
POLL_PAUSE_S = 0.1
#: float rounding of device instants, the only tolerance of a timing check in virtual time
EXACT_S = 1e-9
#: how much later than its tolerance a reply may come on a daemon's or a real port for the machine's
#: load alone: the smoke runs in the background of `make test`, beside its workers (and, in the
#: load proof, two busy loops). Exact instants are asserted in virtual time; load cannot make a
#: reply early, so only upper bounds get this.
LOAD_S = 1.0
VERSION = b":A Version: USB-9.2k \r\n"
ACK = b":A\r\n"
IDLE = "idle"
SILENT = "silent"
#: a step of a vector: bytes written and the exact bytes expected back, IDLE or SILENT
Step = tuple[bytes, bytes] | str


class Host:
    """A host program on the controller's main port."""

    def __init__(self, target: Target, port: serial.Serial) -> None:
        self.target = target
        self.port = port
        self.scale = 1.0

    # ---- serial -------------------------------------------------------------------------------

    def write(self, data: bytes) -> None:
        self.port.write(data)

    def expect(self, expected: bytes) -> None:
        """The next bytes from the controller are exactly `expected`."""
        assert self.port.read(len(expected)) == expected

    def ask(self, command: bytes, expected: bytes) -> None:
        """Write `command`; the reply is exactly `expected` (the next exchange shows any extra byte)."""
        self.write(command)
        self.expect(expected)

    def reply(self, command: bytes, end: bytes = b"\r\n") -> bytes:
        """Write `command` and return the reply up to and including `end`."""
        self.write(command)
        data = self.port.read_until(end)
        assert data.endswith(end), f"{command!r}: incomplete reply {data!r}"
        return data

    def run(self, steps: Sequence[Step]) -> None:
        for step in steps:
            if step == IDLE:
                self.idle()
            elif step == SILENT:
                self.silent()
            else:
                command, expected = step
                self.ask(command, expected)

    def idle(self, timeout: float = 60.0) -> None:
        """The vectors' "(idle)": poll `/` until `N\\r\\n`, a pause between polls (`poll_pause`);
        each poll must answer `B\\r\\n` or `N\\r\\n`."""
        deadline = self.monotonic() + timeout
        while True:
            self.write(b"/\r")
            answer = self.port.read(3)
            assert answer in (b"B\r\n", b"N\r\n")
            if answer == b"N\r\n":
                return
            assert self.monotonic() < deadline, f"still busy after {timeout} s"
            self.poll_pause()

    def poll_pause(self) -> None:
        """The silence a polling host leaves between two polls: `POLL_PAUSE_S` of device time."""
        self.silent(POLL_PAUSE_S / self.scale)

    def restart(self) -> None:
        """Bring a real controller to P0 of the vectors, as the emulator's factory reset does: the
        factory settings (RESET restores the saved ones, which must be the factory ones, MS-112),
        the settings remembered at once back at their defaults (MS-65, MS-68), and every axis at
        its power-up origin, found from the default upper soft limit (MS-49)."""
        cfg = self.target.profile.config
        axes = " ".join(cfg.motor_axes)
        flags = " ".join(f"{a}-" for a in cfg.motor_axes)
        # low-level mode off, a partial line ended, output and motion stopped, then RESET
        self.write(b"\xffA\r\\\rVB X=0\rTTL X=0 Y=0\r~\r")
        self.drain()
        for command in ("SL", "SU", "HM"):
            self.ask(f"{command} {flags}\r".encode(), ACK)
        upper = self.reply(f"SU {' '.join(f'{a}?' for a in cfg.motor_axes)}\r".encode())
        origin = {}
        for item in upper[3:-2].decode().split():
            letter, value = item.split("=")
            axis = cfg.axes[letter]
            origin[letter] = round((float(value) - axis.soft_upper_mm) * axis.unit_multiplier)
        self.ask(("M " + " ".join(f"{a}={v}" for a, v in origin.items()) + "\r").encode(), ACK)
        self.idle()
        self.ask(b"~\r", ACK)
        self.ask(f"W {axes}\r".encode(), (":A" + " 0" * len(cfg.motor_axes) + "\r\n").encode())

    def drain(self, quiet: float = 0.5) -> None:
        """Discard whatever arrives until the line has been quiet for `quiet` seconds (a read of one
        byte returns as it arrives; a longer one would wait out its timeout)."""
        with self._timeout(quiet):
            while self.port.read(1):
                self.port.read(self.port.in_waiting)

    def silent(self, seconds: float = SILENCE_S) -> None:
        """Nothing arrives for `seconds` (a read that times out; also how the suite waits)."""
        with self._timeout(seconds):
            data = self.port.read(1)
        assert data == b"", f"unexpected byte {data!r} during a {seconds} s silence"

    @contextlib.contextmanager
    def _timeout(self, seconds: float) -> Iterator[None]:
        previous = self.port.timeout
        self.port.timeout = seconds
        try:
            yield
        finally:
            self.port.timeout = previous

    def wait_until(self, deadline: float) -> None:
        """Wait, in silence, until `monotonic()` reaches `deadline`."""
        remaining = deadline - self.monotonic()
        if remaining > 0:
            self.silent(remaining)

    # ---- the test's clock -----------------------------------------------------------------------

    def monotonic(self) -> float:
        """The test's clock (s): device time in virtual time, the wall clock otherwise."""
        return self.target.monotonic()

    def slack(self, seconds: float) -> float:
        """The tolerance of a timing check: `seconds` where the wall clock decides (a daemon's or a
        real port: the host's scheduling and the machine's load), none in virtual time."""
        return EXACT_S if self.target.virtual else seconds

    def late(self, seconds: float) -> float:
        """The tolerance of an upper bound: `slack`, plus `LOAD_S` where the wall clock decides."""
        return EXACT_S if self.target.virtual else seconds + LOAD_S

    # ---- control channel ------------------------------------------------------------------------

    def input(self, input_name: str, /, **params: Any) -> Any:
        return self.target.input(input_name, **params)

    def get(self, name: str) -> Any:
        return self.target.get(name)

    def is_port_path(self, path: str) -> bool:
        """Whether `path`, a port as `get: ports` names it (MS-5), is the kind the emulator serves: a
        pseudo-terminal on a daemon, the device's in-process `stageemu://` URL in virtual time
        (which has no pseudo-terminal)."""
        if self.target.virtual:
            return path.startswith("stageemu://")
        return os.path.realpath(path).startswith("/dev/pts/")

    def axis(self, letter: str) -> dict[str, Any]:
        return self.get("axes")[letter]

    def now(self) -> float:
        """Device time (s), from the control channel."""
        return float(self.target.ctl().clock()["now"])

    def wait_device(self, instant: float) -> None:
        """Wait, in silence, until device time `instant` (in virtual time, exactly that instant)."""
        while (remaining := instant - self.now()) > 0:
            self.silent(remaining / self.scale)

    def advance(self, seconds: float, *inputs: tuple[str, dict[str, Any]]) -> None:
        """Apply control inputs and let exactly `seconds` of device time pass, on a paused clock.

        Only for stretches without serial traffic: bytes written while the clock is paused cross
        the wire only as it is stepped, at instants the test does not control.
        """
        ctl = self.target.ctl()
        ctl.pause()
        try:
            for name, params in inputs:
                self.input(name, **params)
            ctl.step(seconds)
        finally:
            ctl.resume()

    @contextlib.contextmanager
    def scaled(self, scale: float) -> Iterator[None]:
        """Run device time `scale` times faster than wall time (long moves, spins, homing).

        In virtual time waits cost nothing and the clock is left alone; the port's read timeout is
        stretched by `scale` instead, so a reply that takes device time (an autofocus run) is awaited
        as long, in device time, as on a daemon running `scale` times faster.
        """
        ctl = self.target.ctl()
        if self.target.virtual:
            previous = self.port.timeout
            self.port.timeout = None if previous is None else previous * scale
            try:
                yield
            finally:
                self.port.timeout = previous
            return
        ctl.clock(scale)
        self.scale = scale
        try:
            yield
        finally:
            ctl.clock(1.0)
            self.scale = 1.0


@pytest.fixture
def connect(open_target: Callable[..., Target]) -> Callable[..., Host]:
    """`connect(profile="ms2000", overrides=None) -> Host` on a factory-fresh controller (a real one
    is reset)."""

    def factory(
        profile: str = "ms2000", overrides: dict[str, Any] | None = None, **serial_kwargs: Any
    ) -> Host:
        target = open_target(profile, overrides)
        host = Host(target, target.open(**serial_kwargs))
        if target.real:
            host.restart()
        return host

    return factory


@pytest.fixture
def ms(connect: Callable[..., Host]) -> Host:
    """The default profile (P0 of the test vectors)."""
    return connect()
