"""The contract between a device model and the runner that hosts it (emulator/hosting/runner.py).

A device model is a sans-I/O state machine (the h11/wsproto idea). It never touches a file
descriptor, a socket, a thread or the wall clock: the runner feeds it bytes stamped with device time,
asks it when it next needs to act, lets it act, and drains an outbox of timed bytes. The same model
then runs under a PTY, over TCP, in-process and in a unit test on a manual clock, deterministically.

The `Device` base holds what every model shares, as template methods (public method here, the
model's part in the protected hook): `advance(now)` keeps `self.now`, the latest device time the
model has been brought to, then calls `_advance(now)`; `receive(data, now)` advances to `now` first,
then calls `_receive(data, now)`, so a model only ever receives with every earlier event processed.

Runner obligations (see emulator/hosting/runner.py):
- Times passed in are non-decreasing across all calls.
- Before a call stamped `now` other than `receive` (`line_changed`, `control_input`, `observe`,
  `snapshot`) the runner has called `advance(now)`.
- Whenever `next_deadline()` returns a time, the runner calls `advance()` no later than that time
  (with a real clock, possibly a little later: the model must stamp its outputs with the exact
  instant the event was due, never with the `now` it was called at).
- After every call the runner drains `take_output()`, `take_events()` and `take_rx_notes()`.

Model obligations:
- `Emission.due` is the device instant at which the bytes are handed to the device's transmitter;
  a `Pacer` (emulator/wire_time.py) then paces them at the character rate.
- Bad input never raises: it produces whatever the real device does with it.
- While `explain` is set (the runner keeps a traffic log, or someone watches the traffic) it says what
  it did with the bytes: an `RxNote` per unit of input (a command, a garbled character, bytes lost or
  stray) and a summary on each `Emission`. While it is clear nothing is formatted: the hot path
  pays one attribute test.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Protocol

from emulator.profiles.profile import Profile
from emulator.storage.nvstore import ReportingStore, StorageError

MAIN = "main"


@dataclass(frozen=True)
class HostLine:
    """What a host was seen to set on its end of the line. None means "not visible on this
    transport" (a PTY shows no parity or data bits): assumed to match the device."""

    baud: int | None = None
    data_bits: int | None = None
    parity: str | None = None  # "none" | "even" | "odd"
    stop_bits: float | None = None  # 1, 1.5 or 2
    rtscts: bool | None = None
    xonxoff: bool | None = None

    def filled(self, fallback: LineSettings) -> LineSettings:
        """The settings in effect: those not seen taken from `fallback`, the device's own. The one
        place unseen settings are filled in (pacing, mismatch checks and log lines use it)."""
        seen = {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}
        return replace(fallback, **seen)

    def describe(self) -> str:
        """Compact form used in log lines, `ctl list` and `stage-emu view`, e.g. `9600 8N1 rtscts`.
        A setting not visible is a `?` and named after it, so that a PTY host (no data bits, no
        parity) reads `9600 ??1 (data bits, parity not visible)`; a raw TCP host shows none."""
        shown = ("baud", "data_bits", "parity", "stop_bits")
        unseen = [name.replace("_", " ") for name in shown if getattr(self, name) is None]
        if len(unseen) == len(shown) and self.rtscts is None and self.xonxoff is None:
            return "line settings not visible"
        baud = "?" if self.baud is None else str(self.baud)
        bits = "?" if self.data_bits is None else str(self.data_bits)
        parity = "?" if self.parity is None else self.parity[0].upper()
        stop = "?" if self.stop_bits is None else f"{self.stop_bits:g}"
        text = f"{baud} {bits}{parity}{stop}"
        if self.rtscts:
            text += " rtscts"
        if self.xonxoff:
            text += " xonxoff"
        return f"{text} ({', '.join(unseen)} not visible)" if unseen else text


@dataclass(frozen=True)
class LineSettings(HostLine):
    """A device's complete line settings (`Device.line_settings`): every field is set.

    It is a `HostLine` too, a host seen in full, so it can stand in where a host is expected. Device
    models and their tests still build what a host set as `LineSettings` with None fields, so the
    fields stay optional until those build `HostLine` instead."""


@dataclass(frozen=True)
class ModemLines:
    """The modem-status lines a device drives, named as the host reads them at its end of a direct
    cable (a null-modem cable to a PC's serial port): CTS, DSR, CD, RI. Only transports that carry
    modem lines show them (a serial port, RFC 2217, the stageemu:// URL); a PTY and raw TCP carry none. With
    RTS/CTS flow control (`LineSettings.rtscts`) the transport drives CTS from the device's room for
    input instead of `cts`, and sends only while the host's RTS is on."""

    cts: bool = False
    dsr: bool = False
    cd: bool = False
    ri: bool = False


# Line errors a port's UART reports on a received character (`Device.receive_line_error`; a serial
# transport sees them, a PTY or a network port never does). A break reads as a framing error on 00.
FRAMING_ERROR = "framing"
PARITY_ERROR = "parity"

# Kinds of traffic-log records (emulator/hosting/trafficlog.py). Received bytes:
FRAME = "frame"  # a complete command (or control sequence) the device acted on
GARBLED = "garbled"  # a character the line mismatch corrupted, as the receiving end read it
LOST = "lost"  # bytes the device never acted on: deaf, busy, silenced, hung, dropped at reset ...
STRAY = "stray"  # bytes outside any command: discarded junk, a bad frame, a lone terminator
# Sent bytes (and GARBLED, LOST):
REPLY = "reply"  # the answer to a command
UNSOLICITED = "unsolicited"  # sent on the device's own account (a report, a crash signature)
# Events a model builds only while explaining (emulator/hosting/trafficlog.py `LOG_ONLY`):
# CRISP's lock-loop samples and AUTOFOCUS's focus-value samples (docs/ms2000.md §12)
CRISP_SAMPLE, AF_SAMPLE = "crisp_sample", "af_sample"


@dataclass(frozen=True)
class Emission:
    """Bytes the device hands to its transmitter at device time `due`, on one of its channels.
    `kind` and `summary` say what they are for the traffic log; the summary is set only while the
    model explains (`Device.explain`), e.g. `reply to c: position X=10 Y=0 Z=0 (µsteps)`."""

    due: float
    data: bytes
    channel: str = MAIN
    kind: str = REPLY
    summary: str | None = None


@dataclass(frozen=True)
class RxNote:
    """What the device made of a unit of received bytes (`kind`: FRAME, GARBLED, LOST or STRAY),
    complete at device time `t`; `data` as the device's receiver read it."""

    t: float
    kind: str
    data: bytes
    summary: str
    channel: str = MAIN


class Notes:
    """A model's notes on its input for the traffic log. Collaborators of a model hold it and test
    `on` before they format anything."""

    def __init__(self) -> None:
        self.on = False
        self._rx: list[RxNote] = []

    def rx(self, t: float, kind: str, data: bytes, summary: str, channel: str = MAIN) -> None:
        """Note a unit of input. Lost bytes right after lost bytes for the same reason extend that
        note until the runner takes it, so a chunk dropped while deaf is one record, not one per
        byte (bytes paced in one by one across runner steps stay one record each)."""
        last = self._rx[-1] if self._rx else None
        if kind == LOST and last and (last.kind, last.summary, last.channel) == (kind, summary, channel):
            self._rx[-1] = RxNote(t, kind, last.data + data, summary, channel)
            return
        self._rx.append(RxNote(t, kind, bytes(data), summary, channel))

    def take(self) -> list[RxNote]:
        out, self._rx = self._rx, []
        return out


class Store(Protocol):
    """A device's non-volatile memory as the model sees it (emulator/storage/nvstore.py has the kinds).

    `load()` and `erase()` raise StorageError. `save()` never raises: the outcome goes to the report
    callback the store was opened with, either before `save` returns or later, on the runner's thread
    between two model calls, once the store has settled (its latest image is on disk, or failed)."""

    @property
    def persistent(self) -> bool:
        """Whether saves outlive the model (False: the in-memory copy is all there is)."""
        ...

    def load(self) -> dict[str, Any]: ...

    def save(self, data: dict[str, Any]) -> None: ...

    def erase(self) -> None: ...


#: the outcome of a store's saves: None once on disk, else the failure (already logged)
StoreReport = Callable[[StorageError | None], None]
#: opens the store of a device identity (a profile value), reporting its saves to the callback
StoreOpener = Callable[[str, StoreReport], Store]


@dataclass(frozen=True)
class DeviceServices:
    """What the hosting layer offers a model besides bytes and time (its stores)."""

    #: directory for non-volatile device memory, written synchronously by `open_store`'s default
    #: stores; None = nothing persists beyond the model (its store is in memory)
    state_dir: Path | None = None
    #: how the runner opens stores instead (the daemon's write on a worker thread, emulator/hosting/daemon.py)
    stores: StoreOpener | None = None

    def open_store(self, device_id: str, report: StoreReport) -> Store:
        """The store of `device_id`; every save's outcome goes to `report`."""
        if self.stores is not None:
            return self.stores(device_id, report)
        return ReportingStore(self.state_dir, device_id, report)


class ControlError(Exception):
    """A control-channel request the device cannot honour; the message goes back to the client."""


class Device(ABC):
    """A sans-I/O device model. Subclasses register themselves per family (emulator/devices)."""

    #: channels (ports) the model talks on; most devices have just `main`
    channels: tuple[str, ...] = (MAIN,)
    #: False when the profile asks for unpaced output (MP-285 `pace_line: false`); the runner then
    #: delivers at once even on a `timing: realistic` port. Re-read on every pump, so a model may
    #: change it at runtime (the MP-285 clears it while its UART model times a mismatched line).
    pace_line: bool = True
    #: the last failure to keep non-volatile memory on disk (a one-line message), None while the
    #: last save worked; the model goes on working from its in-memory copy, so this flag (shown by
    #: `ctl list`, with a pushed `storage_error` event) is how a host learns its saves are lost
    storage_error: str | None = None

    def __init__(self, name: str, profile: Profile, now: float, services: DeviceServices) -> None:
        self.name = name
        self.profile = profile
        self.services = services
        self.log = logging.getLogger(f"stage_emu.device.{name}")
        #: the latest device time the model has been advanced to (for work the runner triggers
        #: between calls, such as a store's report); kept by `advance`
        self.now = now
        #: notes on received bytes, collected while `explain` is set
        self.notes = Notes()
        #: timed bytes for the runner and pushed control-channel events, drained by the take_* methods
        self._outbox: list[Emission] = []
        self._events: list[dict[str, Any]] = []

    # ---- the time skeleton: public template methods, the model's hooks -------------------------

    def receive(self, data: bytes, now: float, channel: str = MAIN) -> None:
        """Bytes completely received from the host at device time `now`: every internal event due
        by then is processed first."""
        self.advance(now)
        self._receive(data, now, channel)

    def receive_line_error(self, byte: int, kind: str, now: float, channel: str = MAIN) -> None:
        """A character received at device time `now` with a line error (`kind`: FRAMING_ERROR or
        PARITY_ERROR), in its place among the received bytes. What the firmware makes of it is the
        model's (`_receive_line_error`)."""
        self.advance(now)
        self._receive_line_error(byte, kind, now, channel)

    def _receive_line_error(self, byte: int, kind: str, now: float, channel: str) -> None:
        """By default the character is data, as a UART that hands over its data register regardless
        of the error flag would have it."""
        self._receive(bytes((byte,)), now, channel)

    def advance(self, now: float) -> None:
        """Process every internal event due at or before `now`."""
        if now > self.now:
            self.now = now
        self._advance(now)

    @abstractmethod
    def _receive(self, data: bytes, now: float, channel: str) -> None:
        """The model's part of `receive`, called with the model advanced to `now`."""

    @abstractmethod
    def _advance(self, now: float) -> None:
        """The model's part of `advance`."""

    @abstractmethod
    def next_deadline(self) -> float | None:
        """Device time of the next internal event, or None when nothing is scheduled."""

    # ---- what the runner drains --------------------------------------------------------------

    def take_output(self) -> list[Emission]:
        """Drain the outbox."""
        out, self._outbox = self._outbox, []
        return out

    def take_events(self) -> list[dict[str, Any]]:
        """Drain pushed control-channel events (`{"ev": name, ...}`)."""
        out, self._events = self._events, []
        return out

    @property
    def explain(self) -> bool:
        """Set by a host that logs traffic: the model then notes what it makes of its input and
        summarises its output."""
        return self.notes.on

    @explain.setter
    def explain(self, on: bool) -> None:
        self.notes.on = on

    def take_rx_notes(self) -> list[RxNote]:
        """Drain the notes on received bytes (empty unless `explain`)."""
        return self.notes.take()

    # ---- the line ----------------------------------------------------------------------------

    @abstractmethod
    def line_settings(self, channel: str = MAIN) -> LineSettings:
        """The device's own line settings on `channel` (what its UART is set to now)."""

    @abstractmethod
    def line_changed(self, host: HostLine | None, now: float, channel: str = MAIN) -> None:
        """The host's settings as the transport sees them; None when no host is attached."""

    def mismatch_effect(self, host: HostLine, channel: str = MAIN) -> str:
        """What a host with these (differing) settings will experience, for the one-line warning,
        e.g. `traffic will be garbled (line_mismatch=garble)`."""
        return ""

    def modem_lines(self, channel: str = MAIN) -> ModemLines:
        """The modem-status lines the device drives on `channel` (none unless its family says)."""
        return ModemLines()

    # ---- control channel ---------------------------------------------------------------------

    @abstractmethod
    def snapshot(self, now: float) -> dict[str, Any]:
        """Full observable state at device time `now` as plain JSON-able data (control channel
        `snapshot`)."""

    def observe(self, name: str, now: float) -> Any:
        """Control-channel read `{"get": name}`. Default: a top-level key of the snapshot."""
        state = self.snapshot(now)
        if name not in state:
            raise ControlError(f"{self.name}: no observable {name!r}; known: {', '.join(sorted(state))}")
        return state[name]

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        """Control-channel input `{"in": name, ...params}`."""
        raise ControlError(f"{self.name}: no input {name!r}")

    def control_names(self) -> dict[str, list[str]]:
        """The names `control_input` and `observe` accept (`ctl get DEVICE`, `ctl input --help`).
        Default: no inputs; the snapshot's top-level keys as observables."""
        return {"inputs": [], "observables": sorted(self.snapshot(self.now))}

    def shut_down(self, now: float) -> None:
        """The runner is stopping (the daemon exits): save now what the model would save a little
        later (positions it saves once at rest). Nothing by default."""
        return None

    def forget_nonvolatile(self) -> None:
        """Erase whatever the model keeps across power cycles (saved settings), before a factory
        reset from the control channel. Nothing by default. Raises ControlError when it cannot, and
        then leaves the model as it was (the runner keeps it)."""
        return None
