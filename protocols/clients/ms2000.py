"""Thin host library for the ASI MS2000 (pyserial only): works the same on a real port and on stage-emu.

    from protocols.clients.ms2000 import MS2000
    with MS2000("/dev/ttyUSB0") as stage:
        stage.move(X=10000, Y=-5000)          # units: 1/UM mm, 0.1 µm by default
        stage.wait_until_idle()
        print(stage.where("X", "Y"))           # {'X': 10000.0, 'Y': -5000.0}

Replies come in several shapes (`:A`, `:A X=1.5`, `:X=1.5 A`, `X=1 :A`, `:A 1 2`, bare text, `N`/`B`);
`parse_reply` reads them all. `:N-<code>` replies raise `MS2000Error` subclasses carrying the code.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field
from typing import Any

import serial

TERMINATOR = b"\r\n"

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_ITEM = re.compile(rf"^([A-Z][A-Z_]*)=({_NUMBER})$")


class MS2000Error(Exception):
    """The controller answered `:N-<code>`."""

    code = 0
    meaning = "error"

    def __init__(self, command: str, code: int | None = None) -> None:
        self.command = command
        if code is not None:
            self.code = code
        super().__init__(f"{command!r}: :N-{self.code} ({self.meaning})")


class UnknownCommand(MS2000Error):
    code, meaning = 1, "unknown command"


class UnknownAxis(MS2000Error):
    code, meaning = 2, "unrecognised axis parameter"


class MissingParameters(MS2000Error):
    code, meaning = 3, "missing parameters"


class OutOfRange(MS2000Error):
    code, meaning = 4, "parameter out of range"


class OperationFailed(MS2000Error):
    code, meaning = 5, "operation failed"


class UndefinedError(MS2000Error):
    code, meaning = 6, "undefined error"


class Halted(MS2000Error):
    code, meaning = 21, "serial command halted by HALT"


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


class NoReply(Exception):
    """Nothing (or no complete reply) arrived before the timeout."""


@dataclass(frozen=True)
class Reply:
    """A parsed reply: `values` for `L=v` items, `items` for positional values, `text` for bare text."""

    ack: bool
    values: dict[str, float] = field(default_factory=dict)
    items: tuple[str, ...] = ()
    text: str = ""


def parse_reply(text: str, command: str = "") -> Reply:
    """Parse one reply (terminator removed). Raises the `MS2000Error` subclass for `:N-<code>`."""
    stripped = text.strip()
    error = re.fullmatch(r":N-(\d+)", stripped)
    if error:
        code = int(error.group(1))
        raise ERRORS.get(code, MS2000Error)(command, code)
    if stripped.startswith(":A"):
        tokens = stripped[2:].split()
        values = _items(tokens)
        if values is not None:
            return Reply(True, values)
        return Reply(True, items=tuple(tokens))
    if stripped.startswith(":") and stripped.endswith(" A"):  # `:X=0.040000 A`
        values = _items(stripped[1:-2].split())
        if values is not None:
            return Reply(True, values)
    if stripped.endswith(":A"):  # `X=10 :A`
        values = _items(stripped[:-2].split())
        if values is not None:
            return Reply(True, values)
    return Reply(False, text=text)


def _items(tokens: list[str]) -> dict[str, float] | None:
    values = {}
    for token in tokens:
        match = _ITEM.match(token)
        if not match:
            return None
        values[match.group(1)] = float(match.group(2))
    return values if tokens else None


def format_value(value: float) -> str:
    """Numbers as the controller's own examples send them: integers bare, others to 6 decimals."""
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.6f}"


class MS2000:
    def __init__(self, port: str | serial.Serial, baudrate: int = 9600, timeout: float = 1.0) -> None:
        if isinstance(port, serial.Serial):
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
        self.port.write(command.encode("ascii") + b"\r")
        raw = self.port.read_until(TERMINATOR)
        if not raw.endswith(TERMINATOR):
            raise NoReply(f"{command!r}: no complete reply within {self.port.timeout} s (got {raw!r})")
        return raw[: -len(TERMINATOR)].decode("latin-1")

    def command(self, command: str) -> Reply:
        """Send a command and parse its reply; `:N-<code>` raises."""
        return parse_reply(self.exchange(command), command)

    def get(self, command: str, *letters: str) -> dict[str, float]:
        """Query settings (`get("S", "X", "Y")` -> {'X': 5.1456, 'Y': 5.1456}), any reply shape."""
        reply = self.command(f"{command} " + " ".join(f"{letter}?" for letter in letters))
        if reply.values:
            return reply.values
        return dict(zip(self._order(letters), (float(item) for item in reply.items), strict=False))

    def set(self, command: str, **values: float) -> None:
        """Set settings (`set("S", X=1.5)`); `:N-<code>` raises."""
        self.command(f"{command} " + " ".join(f"{k}={format_value(v)}" for k, v in values.items()))

    # ---- motion -------------------------------------------------------------------------------

    def axes(self) -> tuple[str, ...]:
        """Motor axes in hardware order (from `BU X`)."""
        if self._axes is None:
            line = next((ln for ln in self.build_info()["lines"] if ln.startswith("Motor Axes:")), "")
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
        reply = self.command("W " + " ".join(axes))
        return dict(zip(self._order(axes), (float(v) for v in reply.items), strict=True))

    def move(self, **targets: float) -> None:
        self.command("M " + " ".join(f"{a}={format_value(v)}" for a, v in targets.items()))

    def movrel(self, **deltas: float) -> None:
        self.command("R " + " ".join(f"{a}={format_value(v)}" for a, v in deltas.items()))

    def here(self, **positions: float) -> None:
        self.command("H " + " ".join(f"{a}={format_value(v)}" for a, v in positions.items()))

    def is_busy(self) -> bool:
        text = self.exchange("/")
        if text not in ("N", "B"):
            raise NoReply(f"'/': unexpected reply {text!r}")
        return text == "B"

    def wait_until_idle(self, timeout: float = 60.0, poll: float = 0.02) -> None:
        """Poll `/` until the controller reports `N`."""
        deadline = time.monotonic() + timeout
        while self.is_busy():
            if time.monotonic() > deadline:
                raise TimeoutError(f"still busy after {timeout} s")
            time.sleep(poll)

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
            if line.startswith("Motor Axes:"):
                info["axes"] = line.split(":", 1)[1].split()
            elif line.startswith("CMDs:"):
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
        """`INFO <axis>` as {label: value-with-units}; each line holds two items, the left 33 wide."""
        text = self.exchange(f"I {axis}")
        result: dict[str, str] = {}
        for line in text.split("\r"):
            for item in (line[:33], line[33:]):
                label, sep, value = item.partition(":")
                if sep and label.strip():
                    result[label.strip()] = value.strip()
        return result
