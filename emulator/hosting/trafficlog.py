"""`--log-traffic FILE`: what crossed each port and what the device made of it, as JSON lines.

One record per line, in device-time order (per device):

    {"t": 0.012501, "wall": 1712345678.123456, "device": "stage", "port": "main", "dir": "rx",
     "hex": "57 20 58 0d", "kind": "frame", "summary": "W X [WHERE]"}

- `t`: device seconds when the unit was complete: the last byte received (`rx`), or the last byte
  through the port's wire time (`tx`); `wall`: the host's clock when the record was written.
- `dir`: `rx` host to device, `tx` device to host; `hex`: the bytes, space-separated.
- `kind` (emulator/device.py): `rx` units are what the model reports it made of the bytes it read
  (`Device.take_rx_notes`), never a re-parse: `frame` (a command it acted on), `garbled` (a character
  as the device read it off a mismatched line; that character then also takes part in the unit the
  device makes of it), `lost` (never acted on: deaf, busy, silenced, dropped by a reset, or by the
  host: a hung fault, bytes discarded when the host hung up), `stray` (outside any command: junk, a
  bad frame, a lone terminator). `tx` records are one per emission, written when its last byte
  leaves: `reply`, `unsolicited`, `garbled` (a character as the host reads it), or `lost` (not sent
  or not taken: detached, hung, disconnected, dropped by a fault, the host not reading).
- `summary`: the model's one-line account, e.g. `reply to c: position X=10 Y=0 Z=0 (µsteps)`.

Device events (the control channel's pushed events) are records with `dir` `ev` and no port:

    {"t": 1.25, "wall": 1712345678.2, "device": "stage", "dir": "ev", "ev": "ttl_out0", "level": 1}

- `t`: the event's own device time (its `t`), else the device time it was collected at; the other
  fields are the event's (`ttl_out0`, `array_arrival`, `scan_sync`, `move_complete`, ...).
- `move` is where the stage goes, so a reader (`stage-emu plot`) need not re-parse host commands. A
  model builds it only while explaining, and it goes only to the traffic log, not to control-channel
  subscribers, whose events are the same with or without a log:

      {"t": 2.0, ..., "dir": "ev", "ev": "move", "path": {"X": [[2.0, 0.0], [2.05, 25.0], [2.5, 1000.0]]}}

  `path` maps each axis it covers to knots `[device time, µm]`, positions in the device's user
  coordinates (what it reports, origin applied); the axis goes linearly from knot to knot and rests
  at the last one. `cruise` (`{"X": µm/s}`, optional) says the axis keeps going at that speed after
  its last knot (spin, VE, joystick). A record supersedes from its first knot on what earlier ones
  said about its axes: a re-planned move gives a new path, a halt a single knot. The MS2000 writes
  one per axis each time its planned path changes (each leg of a commanded move, SCAN leg, ARRAY
  cell move, MULTIAXIS stretch, G-code segment, correction; a motion cut short); the MP-285 one for
  all three axes per move (`m`, program vectors), halt, stop, or ROE turn (a halt's record is written
  when the halted run ends, after its settle time, stamped with the halt's instant: a reader sorts).
- `crisp_sample` (each CRISP lock-loop update: `error`, `surface_um`) and `af_sample` (each video
  frame of an AUTOFOCUS scan: `z_um`, `value`) are, like `move`, built only while a log is kept and
  go only to it (`LOG_ONLY`).

Control-channel traffic subscribers (`{"op": "subscribe", "device": ..., "traffic": true}`) get the
same `rx`/`tx` records as they are written, without device events (they have their own stream):
`DeviceTraffic.sink`. The runner keeps a `DeviceTraffic`, and the model explains, only while a log is
kept or a sink is set (`DeviceRunner.watch_traffic`); otherwise nothing is formatted.

The log is a side channel: a disk that fills up or a file that cannot be written must never stop a
device from answering. The first failure is logged once and traffic logging stops; SIGUSR1
(`reopen`, as after log rotation) starts it again on a fresh file at the same path.

The log is appended to, so it never lands in someone else's file: an existing regular file is taken
only when it is empty or begins with a record (the first SNIFF_BYTES are read, never the whole file).
Another file is refused untouched: one line at start-up, and at `reopen` one logged error, with
logging off until the next SIGUSR1 (devices keep answering, as on a full disk).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import stat
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from emulator.device import AF_SAMPLE, CRISP_SAMPLE, LOST, Emission, RxNote

log = logging.getLogger("stage_emu.traffic")

RX = "rx"
TX = "tx"
#: a device event (`DeviceTraffic.events`)
EV = "ev"
#: the event of a `move` record
MOVE = "move"
#: events a model builds only while explaining (a traffic log is kept): they go to the log alone, so
#: control-channel subscribers see the same events with or without a log, and few of them
LOG_ONLY = frozenset({MOVE, CRISP_SAMPLE, AF_SAMPLE})

#: takes each `rx`/`tx` record (the log's JSON object) as it is written
TrafficSink = Callable[[dict[str, Any]], None]

#: how much of an existing file is read to tell a traffic log from any other file
SNIFF_BYTES = 4096
#: how every record begins (`traffic_entry`, `TrafficLog.event`: json.dumps keeps the key order);
#: the first line may be longer than SNIFF_BYTES, so its head is what is checked
_RECORD_HEAD = re.compile(rb'\{"t": -?[0-9][0-9.eE+-]*, "wall": [0-9][0-9.eE+-]*, "device": "')


class NotATrafficLog(OSError):
    """The path holds a file that is not a traffic log. An OSError, so it is reported as a file
    that cannot be opened: one line at start-up, one logged error at `reopen`."""


def traffic_entry(
    t: float, device: str, port: str, direction: str, data: bytes, summary: str | None, kind: str | None
) -> dict[str, Any]:
    """One `rx`/`tx` record, as the log writes it and traffic subscribers get it."""
    entry = {
        "t": round(t, 6),
        "wall": round(time.time(), 6),
        "device": device,
        "port": port,
        "dir": direction,
        "hex": data.hex(" "),
    }
    if kind:
        entry["kind"] = kind
    if summary:
        entry["summary"] = summary
    return entry


class TrafficLog:
    def __init__(self, path: Path) -> None:
        self.path = path
        self._stream: TextIO | None = None
        self._open()

    @property
    def active(self) -> bool:
        return self._stream is not None

    def _open(self) -> None:
        # read-write, to look at what an existing file holds through the descriptor that will write
        fd = os.open(self.path, os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, 0o600)
        try:
            _check_appendable(fd)
        except OSError:
            os.close(fd)
            raise
        self._stream = os.fdopen(fd, "a", encoding="utf-8")

    def record(
        self,
        t: float,
        device: str,
        port: str,
        direction: str,
        data: bytes,
        summary: str | None,
        kind: str | None = None,
    ) -> None:
        if self._stream is not None:
            self.write(traffic_entry(t, device, port, direction, data, summary, kind))

    def write(self, entry: dict[str, Any]) -> None:
        stream = self._stream
        if stream is None:
            return
        try:
            stream.write(json.dumps(entry, ensure_ascii=False) + "\n")
            stream.flush()
        except OSError as exc:
            log.error(
                "traffic log %s: cannot write (%s); traffic logging stopped, devices keep serving "
                "(SIGUSR1 reopens it)",
                self.path,
                exc.strerror or exc,
            )
            self._discard()

    def event(self, t: float, device: str, event: dict[str, Any]) -> None:
        if self._stream is None:
            return
        entry = {"t": round(t, 6), "wall": round(time.time(), 6), "device": device, "dir": EV}
        entry.update((k, v) for k, v in event.items() if k != "t")
        self.write(entry)

    def reopen(self) -> None:
        """Close and reopen the file (after rotation, or to resume after a write failure)."""
        self._discard()
        try:
            self._open()
        except OSError as exc:
            log.error(
                "traffic log %s: cannot reopen: %s; traffic logging stays off, devices keep serving "
                "(SIGUSR1 tries again)",
                self.path,
                exc.strerror or exc,
            )
            return
        log.warning("traffic log %s reopened", self.path)

    def _discard(self) -> None:
        stream, self._stream = self._stream, None
        if stream is None:
            return
        # close() still closes the descriptor when its final flush fails (a full disk)
        with contextlib.suppress(OSError):
            stream.close()

    def close(self) -> None:
        self._discard()


def _check_appendable(fd: int) -> None:
    """Refuse a non-empty regular file that does not begin with a record. Devices, pipes and
    terminals (`/dev/null`, `/dev/stdout`) are written to unread."""
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_size == 0:
        return
    if not _RECORD_HEAD.match(os.read(fd, SNIFF_BYTES)):
        raise NotATrafficLog(
            "not a traffic log: its first line is no record, so nothing is appended to it (name a new "
            "file or an existing traffic log)"
        )


@dataclass
class _Sending:
    """An emission on its way out of a port: how many of its bytes have yet to leave, how many the
    host did not take."""

    data: bytes
    kind: str
    summary: str | None
    left: int
    dropped: int = 0


class DeviceTraffic:
    """One device's records for the log and the sink (emulator/hosting/runner.py feeds it). Records gathered
    during a pump are written by `flush`, sorted by device time: a pump may receive host bytes
    completed after a reply it sends.

    `on_wire` gives, per port, the bytes already on its wire when this starts (a sink attached while
    the device sends): they leave unrecorded, so the first record is the first whole emission."""

    def __init__(self, log: TrafficLog | None, device: str, on_wire: dict[str, int] | None = None) -> None:
        self._log = log
        self._device = device
        #: traffic subscribers' sink (DeviceRunner.watch_traffic)
        self.sink: TrafficSink | None = None
        self._records: list[tuple[float, str, str, bytes, str, str | None]] = []
        #: per port, the emissions queued on its wire, in order (the pacer keeps one run each)
        self._sending: dict[str, list[_Sending]] = {
            port: [_Sending(b"", "", None, count)] for port, count in (on_wire or {}).items() if count
        }
        #: device events gathered during a pump, with their device times
        self._events: list[tuple[float, dict[str, Any]]] = []

    @property
    def logs(self) -> bool:
        """Whether a traffic log takes the records (else only the sink does)."""
        return self._log is not None

    def events(self, now: float, events: list[dict[str, Any]]) -> None:
        """Device events drained at `now` (an event's own `t` when it has one), for the log only."""
        if self._log is None:
            return
        for event in events:
            t = event.get("t")
            self._events.append((t if isinstance(t, (int, float)) else now, event))

    def rx(self, note: RxNote) -> None:
        self._records.append((note.t, note.channel, RX, note.data, note.kind, note.summary))

    def lost_rx(self, t: float, port: str, data: bytes, why: str) -> None:
        """Host bytes the runner dropped before the device could hear them."""
        self._records.append((t, port, RX, data, LOST, why))

    def lost_tx(self, t: float, emission: Emission, why: str) -> None:
        """An emission the runner did not put on the wire."""
        summary = why if emission.summary is None else f"{why}: {emission.summary}"
        self._records.append((t, emission.channel, TX, emission.data, LOST, summary))

    def queued(self, emission: Emission, data: bytes, changed: int) -> None:
        """`data` (the emission after faults; `changed` bytes corrupted) is on the port's wire."""
        if not data:
            return  # a pacer takes no empty run
        summary = emission.summary
        if changed:
            summary = f"{summary or 'bytes'} ({changed} corrupted by the corrupt fault)"
        self._sending.setdefault(emission.channel, []).append(
            _Sending(data, emission.kind, summary, len(data))
        )

    def left(self, t: float, port: str, count: int, dropped: int) -> None:
        """`count` bytes of the oldest queued emission left the port at `t`, `dropped` of them not
        taken by the host; the emission is recorded with its last byte."""
        queue = self._sending.get(port)
        if not queue:
            return
        sending = queue[0]
        sending.left -= count
        sending.dropped += dropped
        if sending.left > 0:
            return
        queue.pop(0)
        if not sending.data:  # on the wire before this started (`on_wire`)
            return
        if sending.dropped:
            lost = f"host not reading: {sending.dropped} of {len(sending.data)} bytes dropped"
            summary = lost if sending.summary is None else f"{lost}: {sending.summary}"
            self._records.append((t, port, TX, sending.data, LOST, summary))
        else:
            self._records.append((t, port, TX, sending.data, sending.kind, sending.summary))

    def discard(self, t: float, port: str, why: str) -> None:
        """The port's wire was cleared: what had not left is lost."""
        for sending in self._sending.pop(port, []):
            unsent = sending.data[len(sending.data) - sending.left :]
            if not unsent:
                continue
            summary = why if sending.summary is None else f"{why}: {sending.summary}"
            self._records.append((t, port, TX, unsent, LOST, summary))

    def flush(self) -> None:
        if not self._records and not self._events:
            return
        records, self._records = self._records, []
        events, self._events = self._events, []
        log = self._log if self._log is not None and self._log.active else None
        sink = self.sink
        records.sort(key=lambda record: record[0])
        events.sort(key=lambda event: event[0])
        pending = iter(events)
        event = next(pending, None)
        for t, port, direction, data, kind, summary in records:
            # traffic first at an instant: the command before what it set off
            while event is not None and event[0] < t:
                self._event(event[0], event[1])
                event = next(pending, None)
            if log is None and sink is None:
                continue
            entry = traffic_entry(t, self._device, port, direction, data, summary, kind)
            if log is not None:
                log.write(entry)
            if sink is not None:
                sink(entry)
        while event is not None:
            self._event(event[0], event[1])
            event = next(pending, None)

    def _event(self, t: float, event: dict[str, Any]) -> None:
        if self._log is not None:
            self._log.event(t, self._device, event)
