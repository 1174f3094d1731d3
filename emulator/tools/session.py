"""Session files: what crossed a serial line between a host and a controller, with its timing.

`stage-emu proxy` writes one while it forwards a host's traffic to a real controller; `stage-emu
replay` plays its host side again and compares the replies. JSON lines, one record per line
(wrapped here), in this order:

    {"session": "stage-emu", "version": 1, "device": "mp285", "profile": "mp285",
     "real": "/dev/ttyUSB0", "started": "2024-05-01T14:02:17.912+02:00",
     "line": {"baud": 9600, "data_bits": 8, "parity": "none", "stop_bits": 1,
              "rtscts": false, "xonxoff": false}}
    {"t": 0.512, "dir": "line", "baud": 9600, "data_bits": null, "parity": null,
     "stop_bits": 1, "rtscts": false, "xonxoff": false}
    {"t": 1.203, "dir": "rx", "hex": "63 0d"}
    {"t": 1.219, "dir": "tx", "hex": "00 00 00 00 00 00 00 00 00 00 00 00 0d"}
    {"t": 1.203, "dir": "exchange", "request": "63 0d", "reply": "00 00 ... 0d",
     "summary": "c -> ...", "latency": 0.016}
    {"t": 9.871, "dir": "end"}

- The header names the device family (which codec decodes the traffic), the profile the recording
  was made for, the real port and the device's line settings (the profile's, or `--baud`).
- `t`: seconds since the proxy started, on a monotonic clock, when the proxy had the bytes: read
  from the host (`rx`, host to device, as in the traffic log) or from the controller (`tx`). One
  record per read, so a host that writes a byte per millisecond shows as such. `line`: the host
  opened the port or changed its settings (the values it set; null: a pseudo-terminal does not show
  it); the proxy set the same on the real port. `rx`, `tx` and `line` records come in time order.
- `exchange` records pair each request with its reply (emulator/tools/session_decode.py says how), written
  when the exchange is over, so after the chunks they decode: `t` is the request's end, `latency`
  the reply's last byte after it (null: no reply), `request` null for unsolicited output. They are
  for reading; the chunks are the evidence. A reader decodes the chunks again and ignores them.
- `end`: the proxy stopped cleanly. A file without it was cut short (the proxy was killed); what it
  holds is still usable.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, fields
from datetime import datetime
from pathlib import Path
from typing import IO, Any

from emulator.device import HostLine, LineSettings
from emulator.tools.readers import ReadError, json_records
from emulator.tools.session_decode import Exchange, ExchangeDecoder

FORMAT = "stage-emu"
VERSION = 1
FAMILIES = ("mp285", "ms2000")
RX, TX, LINE, EXCHANGE, END = "rx", "tx", "line", "exchange", "end"
WHAT = "session file"


class SessionError(ReadError):
    """A session file that cannot be read or written; the message is one line naming it."""


@dataclass(frozen=True)
class Header:
    device: str
    profile: str
    line: LineSettings
    real: str = ""
    started: str = ""


@dataclass(frozen=True)
class Chunk:
    """Bytes read in one go: `direction` RX (from the host) or TX (from the device)."""

    t: float
    direction: str
    data: bytes


@dataclass(frozen=True)
class LineChange:
    """The host set these line settings (None: not seen) at `t`."""

    t: float
    host: HostLine


Event = Chunk | LineChange


@dataclass(frozen=True)
class Session:
    header: Header
    #: in time order; each iteration reads them again (`load_session`: from the file)
    events: Iterable[Event]
    #: the file ends with an `end` record
    complete: bool = True

    def exchanges(self) -> list[Exchange]:
        return decode(self.header.device, self.events)


def decode(family: str, events: Iterable[Event]) -> list[Exchange]:
    return list(iter_decode(family, events))


def iter_decode(family: str, events: Iterable[Event]) -> Iterator[Exchange]:
    """The exchanges of `events` as they close, in constant memory for any number of them."""
    decoder = ExchangeDecoder(family)
    for event in events:
        if isinstance(event, Chunk):
            yield from (
                decoder.rx(event.t, event.data) if event.direction == RX else decoder.tx(event.t, event.data)
            )
    yield from decoder.finish()


def now_iso() -> str:
    return datetime.now().astimezone().isoformat(timespec="milliseconds")


def _line_fields(line: HostLine) -> dict[str, Any]:
    return {f.name: getattr(line, f.name) for f in fields(HostLine)}


def _hex(data: bytes) -> str:
    return data.hex(" ")


# ---- writing ------------------------------------------------------------------------------------


class SessionWriter:
    """Writes a session as it happens: a record per line, flushed, so a killed proxy leaves all but
    the exchanges still open. Times are made non-decreasing (two threads stamp them)."""

    def __init__(self, path: Path, header: Header, *, overwrite: bool = False) -> None:
        try:
            self._file: IO[str] = path.open("w" if overwrite else "x", encoding="utf-8")
        except FileExistsError:
            raise SessionError(f"{path}: already exists; remove it or choose another file") from None
        except OSError as exc:
            raise SessionError(f"{path}: cannot create it ({exc.strerror or exc})") from None
        self.path = path
        self.family = header.device
        self._decoder = ExchangeDecoder(header.device)
        self._last = 0.0
        self.exchanges = 0
        self._write(
            {
                "session": FORMAT,
                "version": VERSION,
                "device": header.device,
                "profile": header.profile,
                "real": header.real,
                "started": header.started or now_iso(),
                "line": _line_fields(header.line),
            }
        )

    def _write(self, record: dict[str, Any]) -> None:
        self._file.write(json.dumps(record, ensure_ascii=False) + "\n")
        self._file.flush()

    def _stamp(self, t: float) -> float:
        self._last = max(self._last, round(t, 6))
        return self._last

    def chunk(self, t: float, direction: str, data: bytes) -> None:
        t = self._stamp(t)
        self._write({"t": t, "dir": direction, "hex": _hex(data)})
        self._exchanges(self._decoder.rx(t, data) if direction == RX else self._decoder.tx(t, data))

    def line(self, t: float, host: HostLine) -> None:
        self._write({"t": self._stamp(t), "dir": LINE, **_line_fields(host)})

    def event(self, event: Event) -> None:
        if isinstance(event, Chunk):
            self.chunk(event.t, event.direction, event.data)
        else:
            self.line(event.t, event.host)

    def close(self, t: float | None = None) -> None:
        """Write what is still open and the `end` record (at `t`, default the last record's)."""
        if self._file.closed:
            return
        self._exchanges(self._decoder.finish())
        self._write({"t": self._stamp(self._last if t is None else t), "dir": END})
        self._file.close()

    def _exchanges(self, exchanges: list[Exchange]) -> None:
        for exchange in exchanges:
            latency = exchange.latency
            request = exchange.request
            self._write(
                {
                    "t": exchange.t,
                    "dir": EXCHANGE,
                    "request": None if request is None else _hex(request.data),
                    "reply": _hex(exchange.reply),
                    "summary": exchange.describe(self.family),
                    "latency": None if latency is None else round(latency, 6),
                }
            )
            self.exchanges += 1


def save_session(session: Session, path: Path) -> int:
    """Write `session` to a new file `path` (exchanges decoded afresh); returns how many."""
    writer = SessionWriter(path, session.header)
    for event in session.events:
        writer.event(event)
    writer.close()
    return writer.exchanges


# ---- reading ------------------------------------------------------------------------------------


def load_session(path: Path, on_line: Callable[[], None] | None = None) -> Session:
    """Check a session file; SessionError (one line, `PATH:LINE: problem`) when it is not one. The
    file is read once to check it, a line at a time, and its events are read from it again on each
    iteration of `Session.events`, so memory does not grow with it. A last line cut off by a killed
    proxy is left out. `on_line` hears of each line read (progress)."""
    records = _records(path, on_line)
    header = next(records, None)
    assert isinstance(header, Header)  # `_records` starts with it or raises
    complete = False
    for record in records:
        complete = record is END
    return Session(header, SessionEvents(path), complete)


@dataclass(frozen=True)
class SessionEvents:
    """The events of the session file at `path` (checked by `load_session`), read anew each time."""

    path: Path

    def __iter__(self) -> Iterator[Event]:
        for record in _records(self.path):
            if isinstance(record, (Chunk, LineChange)):
                yield record


def _records(path: Path, on_line: Callable[[], None] | None = None) -> Iterator[Header | Event | str]:
    """The header, then each event, and END for an `end` record (exchanges are left out)."""
    lines = json_records(path, WHAT, constants=False, on_line=on_line)
    try:
        number, value = next(lines)
        yield _header(f"{path}:{number}", value)
        last_t = 0.0
        for number, value in lines:
            where = f"{path}:{number}"
            record = _object(where, value)
            t = _time(where, record)
            kind = record.get("dir")
            if kind in (RX, TX, LINE):
                if t < last_t:
                    raise SessionError(f"{where}: t goes backwards ({t} after {last_t})")
                last_t = t
                yield _line_change(where, t, record) if kind == LINE else _chunk(where, t, kind, record)
            elif kind == END:
                yield END
            elif kind != EXCHANGE:
                raise SessionError(f"{where}: unknown record dir {kind!r} (rx, tx, line, exchange or end)")
    except ReadError as exc:
        raise SessionError(str(exc)) from None


def _object(where: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise SessionError(f"{where}: not a JSON object")
    return value


def _header(where: str, value: Any) -> Header:
    if not isinstance(value, dict):
        raise SessionError(f"{where}: not a JSON object; not a session file")
    record: dict[str, Any] = value
    if record.get("session") != FORMAT:
        raise SessionError(
            f'{where}: not a stage-emu session (no "session": "{FORMAT}" header; '
            "`stage-emu proxy --record` writes one)"
        )
    if record.get("version") != VERSION:
        raise SessionError(
            f"{where}: session format version {record.get('version')!r} (this reads {VERSION})"
        )
    device = record.get("device")
    if device not in FAMILIES:
        raise SessionError(f"{where}: device must be one of {', '.join(FAMILIES)}, got {device!r}")
    profile = record.get("profile", device)
    if not isinstance(profile, str) or not profile:
        raise SessionError(f"{where}: profile must be a profile name")
    host = _host_line(where, record.get("line"))
    if None in (host.baud, host.data_bits, host.parity, host.stop_bits):
        raise SessionError(f"{where}: line needs baud, data_bits, parity and stop_bits")
    line = LineSettings(**_line_fields(host))
    real, started = record.get("real", ""), record.get("started", "")
    return Header(device, profile, line, real if isinstance(real, str) else "", str(started))


def _host_line(where: str, value: object) -> HostLine:
    if not isinstance(value, dict):
        raise SessionError(f"{where}: line must be an object of line settings")
    checks = {
        "baud": lambda v: isinstance(v, int) and not isinstance(v, bool) and 0 < v < 2**32,
        "data_bits": lambda v: v in (5, 6, 7, 8),
        "parity": lambda v: v in ("none", "even", "odd"),
        "stop_bits": lambda v: v in (1, 1.5, 2),
        "rtscts": lambda v: isinstance(v, bool),
        "xonxoff": lambda v: isinstance(v, bool),
    }
    for name, check in checks.items():
        given = value.get(name)
        if given is not None and not check(given):
            raise SessionError(f"{where}: {name} {given!r} is not a valid setting")
    return HostLine(**{name: value.get(name) for name in checks})


def _time(where: str, record: dict[str, Any]) -> float:
    t = record.get("t")
    if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) or t < 0:
        raise SessionError(f"{where}: t must be seconds since the start (a number >= 0), got {t!r}")
    return float(t)


def _chunk(where: str, t: float, direction: str, record: dict[str, Any]) -> Chunk:
    text = record.get("hex")
    try:
        if not isinstance(text, str):
            raise ValueError
        data = bytes.fromhex(text)
    except ValueError:
        raise SessionError(
            f'{where}: hex must be bytes as hex digits ("57 20 58 0d"), got {text!r}'
        ) from None
    if not data:
        raise SessionError(f"{where}: a {direction} record without bytes")
    return Chunk(t, direction, data)


def _line_change(where: str, t: float, record: dict[str, Any]) -> LineChange:
    return LineChange(t, _host_line(where, record))
