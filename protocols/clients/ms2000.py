"""Thin host library for the ASI MS2000 (pyserial only): works the same on a real port and on stage-emu.

    from protocols.clients.ms2000 import MS2000
    with MS2000("/dev/ttyUSB0") as stage:
        stage.move(X=10000, Y=-5000)          # units: 1/UM mm, 0.1 µm by default
        stage.wait_until_idle()
        print(stage.where("X", "Y"))           # {'X': 10000.0, 'Y': -5000.0}

A TTL REPORT build (MS-TTLREP-1) also sends a frame of every axis's encoder position on each IN0
edge, on a second port; `TtlReportPort` reads them:

    with TtlReportPort("/dev/ttyUSB1", baudrate=115200) as frames:   # the main port's baud (MS-5)
        print(frames.read().by_axis())         # {'X': 4540, 'Y': -2292, 'Z': 0} (encoder counts)

Replies come in several shapes (`:A`, `:A X=1.5`, `:X=1.5 A`, `X=1 :A`, `:A 1 2`, bare text, `N`/`B`);
`parse_reply` reads them all. `:N-<code>` replies raise `MS2000Error` subclasses carrying the code.
Command lines, reply shapes and error codes are those of the codec, `protocols.ms2000`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import serial

from protocols import ms2000 as proto
from protocols.clients.errors import NoReply
from protocols.ms2000 import ErrorCode, format_command
from protocols.ms2000 import ttl_report as frames
from protocols.ms2000.ttl_report import TtlReport

#: how numbers are written in command lines: integers bare, others to 6 decimals
format_value = proto.host_number


class MS2000Error(Exception):
    """The controller answered `:N-<code>`."""

    code: int = 0

    def __init__(self, command: str, code: int | None = None) -> None:
        self.command = command
        if code is not None:
            self.code = code
        super().__init__(f"{command!r}: {proto.error_reply(self.code)} ({self.meaning})")

    @property
    def meaning(self) -> str:
        return proto.error_text(self.code)


class UnknownCommand(MS2000Error):
    code = ErrorCode.UNKNOWN_COMMAND


class UnknownAxis(MS2000Error):
    code = ErrorCode.BAD_AXIS


class MissingParameters(MS2000Error):
    code = ErrorCode.MISSING_PARAMETERS


class OutOfRange(MS2000Error):
    code = ErrorCode.OUT_OF_RANGE


class OperationFailed(MS2000Error):
    code = ErrorCode.FAILED


class UndefinedError(MS2000Error):
    code = ErrorCode.UNDEFINED


class Halted(MS2000Error):
    code = ErrorCode.HALTED


ERRORS: dict[int, type[MS2000Error]] = {
    cls.code: cls
    for cls in (
        UnknownCommand,
        UnknownAxis,
        MissingParameters,
        OutOfRange,
        OperationFailed,
        UndefinedError,
        Halted,
    )
}


@dataclass(frozen=True)
class Reply:
    """A parsed reply: `values` for `L=v` items, `items` for positional values, `text` for bare text."""

    ack: bool
    values: dict[str, float] = field(default_factory=dict)
    items: tuple[str, ...] = ()
    text: str = ""


def parse_reply(text: str, command: str = "") -> Reply:
    """Parse one reply (terminator removed). Raises the `MS2000Error` subclass for `:N-<code>`."""
    parsed = proto.parse_reply(text)
    if parsed.code is not None:
        raise ERRORS.get(parsed.code, MS2000Error)(command, parsed.code)
    if parsed.kind is proto.ReplyKind.ACK:
        return Reply(True)
    if parsed.kind is proto.ReplyKind.VALUES:
        if parsed.values:
            return Reply(True, {name: float(value) for name, value in parsed.values})
        return Reply(True, items=parsed.numbers)
    return Reply(False, text=text)


class MS2000:
    def __init__(self, port: str | serial.SerialBase, baudrate: int = 9600, timeout: float = 1.0) -> None:
        if isinstance(port, serial.SerialBase):  # a URL's port (serial_for_url) is no serial.Serial
            self.port = port
        else:
            self.port = serial.Serial(port, baudrate, timeout=timeout)
        self._axes: tuple[str, ...] | None = None

    def close(self) -> None:
        self.port.close()

    def __enter__(self) -> MS2000:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- raw exchange -------------------------------------------------------------------------

    def exchange(self, command: str) -> str:
        """Send one command line, return the reply text without its CR LF (multi-line: CR-separated)."""
        self.port.write(command.encode("ascii") + proto.CR)
        raw = self.port.read_until(proto.CRLF)
        if not raw.endswith(proto.CRLF):
            raise NoReply(f"{command!r}: no complete reply within {self.port.timeout} s (got {raw!r})")
        return raw[: -len(proto.CRLF)].decode("latin-1")

    def command(self, command: str) -> Reply:
        """Send a command and parse its reply; `:N-<code>` raises."""
        return parse_reply(self.exchange(command), command)

    def get(self, command: str, *letters: str) -> dict[str, float]:
        """Query settings (`get("S", "X", "Y")` -> {'X': 5.1456, 'Y': 5.1456}), any reply shape."""
        reply = self.command(format_command(command, [f"{letter}?" for letter in letters]))
        if reply.values:
            return reply.values
        return dict(zip(self._order(letters), (float(item) for item in reply.items), strict=False))

    def set(self, command: str, **values: float) -> None:
        """Set settings (`set("S", X=1.5)`); `:N-<code>` raises."""
        self.command(format_command(command, values))

    def set_speed(self, **mm_per_s: float) -> None:
        """`S X=1.000000`: speeds always with six decimals, as the controller reads them back (MS-54);
        values above an axis's maximum are clamped by the controller."""
        self.command(format_command("S", [f"{axis}={value:.6f}" for axis, value in mm_per_s.items()]))

    # ---- motion -------------------------------------------------------------------------------

    def axes(self) -> tuple[str, ...]:
        """Motor axes in hardware order (from `BU X`)."""
        if self._axes is None:
            line = next((ln for ln in self.build_info()["lines"] if ln.startswith(proto.BU_MOTOR_AXES)), "")
            self._axes = tuple(line.split(":", 1)[1].split()) if line else ("X", "Y", "Z")
        return self._axes

    def _order(self, letters: tuple[str, ...] | list[str]) -> list[str]:
        """Replies list values in hardware order whatever the query order."""
        order = self.axes()
        wanted = [letter.upper() for letter in letters]
        return sorted(dict.fromkeys(wanted), key=lambda a: order.index(a) if a in order else len(order))

    def where(self, *axes: str) -> dict[str, float]:
        """Positions in units (1/UM mm)."""
        axes = axes or self.axes()
        reply = self.command(format_command("W", axes))
        return dict(zip(self._order(axes), (float(v) for v in reply.items), strict=True))

    def move(self, **targets: float) -> None:
        self.command(format_command("M", targets))

    def movrel(self, **deltas: float) -> None:
        self.command(format_command("R", deltas))

    def here(self, **positions: float) -> None:
        self.command(format_command("H", positions))

    def is_busy(self) -> bool:
        text = self.exchange("/")
        if text not in ("N", "B"):
            raise NoReply(f"'/': unexpected reply {text!r}")
        return text == "B"

    def wait_until_idle(
        self,
        timeout: float = 60.0,
        poll: float = 0.02,
        *,
        sleep: Callable[[float], None] = time.sleep,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """Poll `/` until the controller reports `N`, pausing `poll` s between polls with `sleep`
        and timing out on `clock` (an emulator in virtual time passes its pauses in device time:
        `sleep=port.advance`, `clock=lambda: port.device_time`)."""
        deadline = clock() + timeout
        while self.is_busy():
            if clock() > deadline:
                raise TimeoutError(f"still busy after {timeout} s")
            sleep(poll)

    def halt(self) -> bool:
        """Stop all motion; True if a commanded move was running (`:N-21`)."""
        try:
            self.command("\\")
        except Halted:
            return True
        return False

    def status_byte(self, axis: str) -> int:
        return int(self.command(f"RS {axis}").items[0])

    # ---- identity -----------------------------------------------------------------------------

    def version(self) -> str:
        """The firmware version string, e.g. `USB-9.2k`."""
        reply = self.command("V")
        return reply.items[-1] if reply.items else reply.text

    def build(self) -> str:
        return self.command("BU").text

    def build_info(self) -> dict[str, Any]:
        """`BU X`: build name, motor axes, command letters and module lines."""
        lines = self.command("BU X").text.split("\r")
        info: dict[str, Any] = {"build": lines[0], "lines": lines, "modules": []}
        for line in lines[1:]:
            if line.startswith(proto.BU_MOTOR_AXES):
                info["axes"] = line.split(":", 1)[1].split()
            elif line.startswith(proto.BU_CMDS):
                info["cmd_letters"] = line.split(":", 1)[1].strip()
            elif not line.startswith(("BootLdr", "Hdwr")):
                info["modules"].append(line)
        return info

    def who(self) -> str:
        reply = self.command("N")
        return " ".join(reply.items) if reply.ack else reply.text

    def compile_date(self) -> str:
        return self.command("CD").text

    def info(self, axis: str) -> dict[str, str]:
        """`INFO <axis>` as {label: value-with-units}."""
        return proto.parse_info(self.exchange(format_command("I", [axis])))


class TtlReportPort:
    """The auxiliary port of a TTL REPORT build, read-only (MS-TTLREP-1). Frames are binary unless
    the controller was ordered with ASCII reports (`read_line`). A binary frame is `axes` × 5 bytes
    plus CR, recognised by its length: open the port before the first edge so reading starts at a
    frame's first byte."""

    def __init__(
        self, port: str | serial.SerialBase, baudrate: int = 115200, axes: int = 3, timeout: float = 1.0
    ) -> None:
        self.port = (
            port if isinstance(port, serial.SerialBase) else serial.Serial(port, baudrate, timeout=timeout)
        )
        self.frame_length = frames.frame_length(axes)

    def close(self) -> None:
        self.port.close()

    def __enter__(self) -> TtlReportPort:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def read(self) -> TtlReport:
        """The next binary frame. Raises NoReply when none is complete within the port's timeout,
        TtlReportError when the bytes are not a frame (another axis count, or ASCII reports)."""
        data = self.port.read(self.frame_length)
        if len(data) < self.frame_length:
            raise NoReply(f"TTL REPORT: no complete frame within {self.port.timeout} s (got {data!r})")
        return frames.decode(data)

    def read_line(self) -> tuple[float, ...]:
        """The next ASCII report: positions in units (1/UM mm), as `W` prints them (a line's LF, if
        any, is read with the next one)."""
        raw = self.port.read_until(proto.CR)
        if not raw.endswith(proto.CR):
            raise NoReply(f"TTL REPORT: no complete line within {self.port.timeout} s (got {raw!r})")
        return frames.parse_line(raw.decode("latin-1"))
