"""Reading a traffic log for `stage-emu plot` in one pass and bounded memory.

`read_log` streams the log through the bounded reader (emulator/tools/readers.py) and hands each device's
records to its builders: the stage's path (emulator/tools/plot.py) and its focus story
(emulator/tools/plot_focus.py), each of which thins what it keeps past a bound. Which device to draw, and
whether as a path or a focus figure, is decided once the whole log is read (`session_from`,
`focus_of`, `focus_device`), from what each device's records held. A malformed event record of a
device is an error only when that device is drawn.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from emulator.hosting.trafficlog import MOVE
from emulator.tools.plot import LogError, PathBuilder, Session
from emulator.tools.plot_focus import FOCUS_EVENTS, Focus, FocusBuilder
from emulator.tools.readers import json_records
from emulator.tools.trace import record_from

#: a traffic log names at most this many devices (a rig's worth, many times over)
MAX_DEVICES = 1000
WHAT = "traffic log"
#: what a builder raises on a record whose fields have the wrong shape
_MALFORMED = (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError)


@dataclass
class DeviceScan:
    path: PathBuilder
    focus: FocusBuilder = field(default_factory=FocusBuilder)
    moves: bool = False
    focuses: bool = False
    #: the first malformed record of the device: (what kind, why)
    malformed: tuple[str, str] | None = None


@dataclass
class LogScan:
    """Every device of a log, with what it holds to draw."""

    devices: dict[str, DeviceScan] = field(default_factory=dict)

    def feed(self, record: dict[str, Any]) -> None:
        """One record (`record_from` has checked its form)."""
        name = record["device"]
        scan = self.devices.get(name)
        if scan is None:
            if len(self.devices) >= MAX_DEVICES:
                raise ValueError(f"more than {MAX_DEVICES} devices")
            scan = self.devices[name] = DeviceScan(PathBuilder(name))
        if scan.malformed is not None:
            return
        ev = record.get("ev") if record["dir"] == "ev" else None
        focus = ev in FOCUS_EVENTS
        try:
            scan.path.feed(record)
            if focus:
                scan.focus.feed(record)
        except _MALFORMED as exc:
            scan.malformed = ("focus" if focus else "event", str(exc))
        scan.moves = scan.moves or ev == MOVE
        scan.focuses = scan.focuses or focus


def scan_records(records: Iterable[dict[str, Any]]) -> LogScan:
    """A scan of records already read (tests; `read_log` reads a file)."""
    scan = LogScan()
    for record in records:
        scan.feed(record)
    return scan


def read_log(path: Path, on_line: Callable[[], None] | None = None) -> LogScan:
    """The log at `path` scanned; LogError (one line, `PATH:LINE: ...`) for what is no traffic log.
    A last line cut short (the daemon stopped mid-write) is left out."""
    scan = LogScan()
    for number, value in json_records(path, WHAT, on_line=on_line):
        try:
            record_from(value)  # the one check of a record's form, shared with `stage-emu trace`
            scan.feed(value)
        except ValueError as exc:
            raise LogError(f"{path}:{number}: not a traffic log record ({exc})") from None
    return scan


@dataclass(frozen=True)
class _Drawn:
    """What a figure needs of a device, and how its absence is told."""

    has: Callable[[DeviceScan], bool]
    #: no device has it (after "no ")
    missing: str
    #: several have it (before " of several devices")
    several: str


_PATH = _Drawn(
    lambda own: own.moves, "move records: was it written by `stage-emu serve --log-traffic`?", "moves"
)
_FOCUS = _Drawn(
    lambda own: own.focuses,
    "CRISP or AUTOFOCUS records: was the device served with either?",
    "focus records",
)


def _chosen(path: Path, scan: LogScan, device: str | None, drawn: _Drawn) -> DeviceScan:
    """`device`, or the only device that has what is drawn; LogError when there is none."""
    names = sorted(scan.devices)
    if device is not None and device not in scan.devices:
        raise LogError(f"{path}: no device {device!r} (the log holds: {', '.join(names)})")
    if device is None:
        holding = [name for name in names if drawn.has(scan.devices[name])]
        if not holding:
            raise LogError(f"{path}: no {drawn.missing}")
        if len(holding) > 1:
            several = ", ".join(holding)
            raise LogError(
                f"{path}: {drawn.several} of several devices ({several}): choose one with --device"
            )
        device = holding[0]
    own = scan.devices[device]
    if not drawn.has(own):
        raise LogError(f"{path}: no {drawn.missing.split(':')[0]} of device {device!r}")
    if own.malformed is not None:
        kind, why = own.malformed
        raise LogError(f"{path}: a malformed {device} {kind} record ({why})")
    return own


def session_from(path: Path, scan: LogScan, device: str | None = None) -> Session:
    """The path of `device` (default: the only device with `move` records)."""
    return _chosen(path, scan, device, _PATH).path.session()


def focus_of(path: Path, scan: LogScan, device: str | None = None) -> Focus:
    """The focus story of `device` (default: the only device with CRISP or AUTOFOCUS records)."""
    own = _chosen(path, scan, device, _FOCUS)
    return own.focus.focus(own.path.session())


def focus_device(scan: LogScan, device: str | None) -> str | None:
    """The device `stage-emu plot` draws a focus figure of without being told: `device` (else the
    log's only device with move or focus records) when it has CRISP or AUTOFOCUS records."""
    if device is None:
        drawn = [name for name, own in scan.devices.items() if own.moves or own.focuses]
        if len(drawn) != 1:
            return None
        device = drawn[0]
    own = scan.devices.get(device)
    return device if own is not None and own.focuses else None


def read_session(path: Path, device: str | None = None) -> Session:
    """The path of `device` (default: the only device with `move` records) in the log at `path`."""
    return session_from(path, read_log(path), device)


def read_focus(path: Path, device: str | None = None) -> Focus:
    """The focus story of `device` (default: the only device with focus records) in the log."""
    return focus_of(path, read_log(path), device)
