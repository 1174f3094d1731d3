"""A traffic log (emulator/hosting/trafficlog.py) read back as exchanges, for `stage-emu trace`.

`Tracer` pairs each unit the device made of host bytes (a `frame`, or a `stray` one, which may get an
error reply) with the reply that followed on the same port, and turns the rest (units the device
garbled or never heard, unsolicited output, device events) into lines of their own; `Tracer.pair`
gives the same as items (an `Exchange`, or a record of its own), which `stage-emu view` draws from
the control channel's traffic records (emulator/tools/view.py). `LogFollower`
(emulator/tools/trace_reader.py) reads the file a complete line at a time, as `tail -f` does when asked to
follow, and `trace_lines` ties the two together. The CLI is emulator/cli/trace.py.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from emulator.device import GARBLED, LOST
from emulator.hosting.trafficlog import EV, LOG_ONLY, RX, TX
from emulator.tools.readers import Line, TooDeep, empty_error, json_value
from emulator.tools.trace_reader import WHAT, LogFollower, TraceError

#: units the device acted on or answered: they open an exchange
REQUEST_KINDS = frozenset({"frame", "stray"})
#: what ends an exchange: its reply, sent or lost on the way
REPLY_KINDS = frozenset({"reply", LOST})
#: `--events`: none, the state-changing ones (what control-channel subscribers see), or all of them
#: (with the per-leg `move` records and the lock-loop samples a model writes only to the log)
EVENT_CHOICES = ("none", "state", "all")
#: how often a followed log is checked for growth (seconds)
POLL_S = 0.2
#: while following, a request still unanswered after this much wall time is shown without its reply
#: (a late one then gets a line of its own), so the lines after it are not held back indefinitely
REPLY_WAIT_S = 2.0
#: record fields that are not an event's own
_RECORD_FIELDS = frozenset({"t", "wall", "device", "dir", "ev"})


@dataclass(frozen=True)
class Record:
    """One line of a traffic log. `port` is None for a device event, whose fields are `fields`."""

    t: float
    wall: float
    device: str
    direction: str
    port: str | None = None
    data: bytes = b""
    kind: str | None = None
    summary: str | None = None
    fields: dict[str, Any] = field(default_factory=dict)


def parse_record(text: str | bytes) -> Record:
    """A log line as a record; ValueError when it is not one (`TooDeep` when it nests too deep)."""
    return record_from(json_value(text.encode() if isinstance(text, str) else text))


def record_from(entry: Any) -> Record:
    """A decoded log line (or a control channel's `traffic` event) as a record; ValueError when it
    is not one."""
    if not isinstance(entry, dict):
        raise ValueError("not a JSON object")
    t, wall = _float(entry.get("t")), _float(entry.get("wall"))
    device, direction = entry.get("device"), entry.get("dir")
    if t is None or wall is None or not isinstance(device, str):
        raise ValueError("no t, wall and device")
    if direction == EV:
        if not isinstance(entry.get("ev"), str):
            raise ValueError("an event record without ev")
        return Record(t, wall, device, EV, fields=entry)
    port, hex_bytes = entry.get("port"), entry.get("hex")
    if direction not in (RX, TX) or not isinstance(port, str) or not isinstance(hex_bytes, str):
        raise ValueError("neither traffic nor an event")
    summary = entry.get("summary")
    return Record(
        t,
        wall,
        device,
        direction,
        port,
        bytes.fromhex(hex_bytes),
        entry.get("kind"),
        summary if isinstance(summary, str) else None,
    )


def _float(value: object) -> float | None:
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return None
    try:
        return float(value)
    except OverflowError:  # an integer of hundreds of digits
        return None


def readable(data: bytes) -> str:
    """Bytes as a quoted string: printable ASCII as is, others as \\r, \\n or \\xNN."""
    out = []
    for byte in data:
        if byte == 0x0D:
            out.append("\\r")
        elif byte == 0x0A:
            out.append("\\n")
        elif byte in (0x22, 0x5C):  # the quote and the escape itself, so the text reads back
            out.append("\\" + chr(byte))
        elif 0x20 <= byte < 0x7F:
            out.append(chr(byte))
        else:
            out.append(f"\\x{byte:02x}")
    return '"' + "".join(out) + '"'


def reply_gist(summary: str | None, request: str | None, shown: str) -> str:
    """What a reply's summary adds to the line: without the request it names (already on the line)
    and without the reply's own bytes when it starts with them (`shown`, unquoted)."""
    if not summary:
        return ""
    gist = summary
    if request:
        for said in (f" (reply to {request})", f"reply to {request}: ", f": reply to {request}"):
            gist = gist.replace(said, "")
        if gist == f"reply to {request}":
            return ""
    if gist.startswith(shown):
        gist = gist[len(shown) :]
    return gist.strip(" :")


def clock_time(wall: float) -> str:
    """The host's local time of day, to the millisecond."""
    return datetime.fromtimestamp(wall).strftime("%H:%M:%S.%f")[:-3]


def _where(record: Record) -> str:
    place = record.device if record.port is None else f"{record.device}/{record.port}"
    return f"{record.t:11.6f}  {clock_time(record.wall)}  {place}"


def _request(record: Record) -> str:
    shown = readable(record.data)
    if record.kind == "stray":
        return f"STRAY {shown} ({record.summary})" if record.summary else f"STRAY {shown}"
    return f"{record.summary}  {shown}" if record.summary else shown


def _reply(reply: Record, request: Record) -> str:
    shown = readable(reply.data)
    gist = reply_gist(reply.summary, request.summary, shown[1:-1])
    if reply.kind == LOST:
        return f"LOST {shown} ({gist})" if gist else f"LOST {shown}"
    return f"{shown} {gist}" if gist else shown


def exchange_line(request: Record, reply: Record | None, missing: str = "no reply") -> str:
    """A request and its reply; latency from the request's last byte to the reply's last byte."""
    head = f"{_where(request)}  {_request(request)}"
    if reply is None:
        return f"{head}  -> {missing}"
    latency_ms = (reply.t - request.t) * 1000
    return f"{head}  -> {_reply(reply, request)}  [{latency_ms:.1f} ms]"


def unit_line(record: Record) -> str:
    """Traffic outside an exchange: host bytes garbled or unheard, unsolicited or unpaired output."""
    kind = record.kind or "bytes"
    shown = readable(record.data)
    told = (record.summary or "").removeprefix(f"{kind}: ")  # `garbled: ...` after GARBLED
    if record.direction == RX:
        body = f"{kind.upper()} {shown}" if record.data else kind.upper()
        return f"{_where(record)}  {body} ({told})" if told else f"{_where(record)}  {body}"
    if told:
        told = f" ({told})" if kind in (GARBLED, LOST) else f" {told}"
    return f"{_where(record)}  -> {kind.upper()} {shown}{told}"


def event_line(record: Record) -> str:
    details = " ".join(
        f"{key}={value if isinstance(value, str) else json.dumps(value, ensure_ascii=False)}"
        for key, value in record.fields.items()
        if key not in _RECORD_FIELDS
    )
    return f"{_where(record)}  * {record.fields['ev']}{' ' + details if details else ''}"


@dataclass(frozen=True)
class Exchange:
    """A request and its reply; without one, `missing` says why."""

    request: Record
    reply: Record | None
    missing: str = "no reply"


#: what pairing makes of records: exchanges, and records of their own (traffic outside any
#: exchange, or a device event: a record without a port)
Item = Exchange | Record


def item_line(item: Item) -> str:
    if isinstance(item, Exchange):
        return exchange_line(item.request, item.reply, item.missing)
    return unit_line(item) if item.port is not None else event_line(item)


@dataclass(frozen=True)
class TraceOptions:
    device: str | None = None
    port: str | None = None
    events: str = "state"


class Tracer:
    """Pairs records into exchanges as they come. A request waits for its reply; the device's events
    wait behind its open requests, so lines stay in the order things began."""

    def __init__(self, options: TraceOptions) -> None:
        self.options = options
        #: every device in the log so far, with its ports (filters are checked against these)
        self.ports: dict[str, set[str]] = {}
        self._open: dict[tuple[str, str], Record] = {}
        self._held_events: dict[str, list[Record]] = {}

    def feed(self, record: Record) -> list[str]:
        return [item_line(item) for item in self.pair(record)]

    def pair(self, record: Record) -> list[Item]:
        """What `record` completes or stands for, in order (empty while a request awaits its reply)."""
        ports = self.ports.setdefault(record.device, set())
        if record.port is not None:
            ports.add(record.port)
        if not self._wanted(record):
            return []
        if record.port is None:
            if any(device == record.device for device, _ in self._open):
                self._held_events.setdefault(record.device, []).append(record)
                return []
            return [record]
        key = (record.device, record.port)
        request = self._open.pop(key, None)
        out: list[Item] = []
        if request is not None:
            answered = record.direction == TX and record.kind in REPLY_KINDS
            out.append(Exchange(request, record if answered else None))
            out.extend(self._release_events(record.device))
            if answered:
                return out
        if record.direction == RX and record.kind in REQUEST_KINDS:
            self._open[key] = record
        else:
            out.append(record)
        return out

    def finish(self) -> list[str]:
        """Requests still waiting for a reply (the log ends), and the events behind them."""
        return self.expire(math.inf)

    def expire(self, written_before: float, missing: str = "no reply") -> list[str]:
        return [item_line(item) for item in self.expire_items(written_before, missing)]

    def expire_items(self, written_before: float, missing: str = "no reply") -> list[Item]:
        """Requests written (wall clock) before `written_before` still waiting for a reply, without
        one, and the events held behind them."""
        out: list[Item] = []
        for key in sorted(self._open, key=lambda key: self._open[key].t):
            if self._open[key].wall < written_before:
                out.append(Exchange(self._open.pop(key), None, missing))
                out.extend(self._release_events(key[0]))
        return out

    def unmatched_filter(self) -> str | None:
        """Why the filters match nothing in the log so far, or None once they do."""
        device, port = self.options.device, self.options.port
        if device is not None and device not in self.ports:
            return f"no device {device!r} in this log (it has: {', '.join(sorted(self.ports))})"
        known = self.ports[device] if device is not None else set().union(set(), *self.ports.values())
        if port is not None and port not in known:
            return f"no port {port!r} in this log (it has: {', '.join(sorted(known)) or 'none'})"
        return None

    def _wanted(self, record: Record) -> bool:
        options = self.options
        if options.device is not None and record.device != options.device:
            return False
        if record.port is None:
            return options.events == "all" or (
                options.events == "state" and record.fields["ev"] not in LOG_ONLY
            )
        return options.port is None or record.port == options.port

    def _release_events(self, device: str) -> list[Record]:
        if any(open_device == device for open_device, _ in self._open):
            return []
        return self._held_events.pop(device, [])


@dataclass
class TraceNotes:
    """What `trace_lines` skipped, for the CLI to say on stderr."""

    malformed: int = 0
    incomplete_tail: bool = False


def trace_lines(
    path: Path,
    options: TraceOptions,
    *,
    follow: bool = False,
    stop: threading.Event | None = None,
    notes: TraceNotes | None = None,
    poll_s: float = POLL_S,
    reply_wait_s: float = REPLY_WAIT_S,
) -> Iterator[str]:
    """The log's exchanges as lines; with `follow`, also those written later, until `stop` is set.
    Raises ReadError (one line) for a file that cannot be read, is no traffic log or (without
    `follow`) holds no record, or filters that match nothing in it."""
    stop = stop or threading.Event()
    notes = notes or TraceNotes()
    tracer = Tracer(options)
    #: lines held until the filters are known to match something in the log (events pass a port
    #: filter, and a misspelt port must be one error line, not events and then an error)
    held: list[str] | None = [] if options.device or options.port else None
    with LogFollower(path) as reader:
        while True:
            while lines := reader.read_lines():
                for line in _traced(lines, tracer, notes, path):
                    if held is None:
                        yield line
                        continue
                    held.append(line)
                    if tracer.unmatched_filter() is None:
                        yield from held
                        held = None
            if held is not None and tracer.ports:  # the whole log so far is read
                problem = tracer.unmatched_filter()
                if problem is not None:
                    raise TraceError(f"{path}: {problem}")
                yield from held
                held = None
            if not follow:
                break
            yield from tracer.expire(time.time() - reply_wait_s, f"no reply within {reply_wait_s:g} s")
            if stop.wait(poll_s):
                break
        notes.incomplete_tail = reader.has_partial_line
    if not follow and not tracer.ports:  # nothing to show: not a log to trace (as plot and replay say)
        raise empty_error(path, WHAT)
    yield from tracer.finish()


def _traced(lines: list[Line], tracer: Tracer, notes: TraceNotes, path: Path) -> Iterator[str]:
    for number, data in lines:
        if not data.strip():
            continue
        try:
            record = parse_record(data)
        except TooDeep as exc:  # hostile, not torn: never skipped
            raise TraceError(f"{path}:{number}: not a {WHAT}: {exc}") from None
        except ValueError:
            if not tracer.ports:  # the first line decides whether this is a traffic log
                raise TraceError(
                    f"{path}:{number}: not a traffic log (its first line is no traffic record; "
                    "`stage-emu serve --log-traffic FILE` writes one)"
                ) from None
            notes.malformed += 1
            continue
        yield from tracer.feed(record)
