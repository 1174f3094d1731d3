"""An RFC 2217 port (`rfc2217://HOST:PORT`): a serial port over telnet, with its line settings.

The telnet and COM-PORT-OPTION protocol is pyserial's own server side, `serial.rfc2217.PortManager`:
it filters what the client sends (`filter()` yields the data bytes and answers the options) and
sets what the client negotiates on a serial-like object, here `ComPortState`. Those settings reach
the device as a `HostLine`, exactly as a PTY host's termios settings do, so a host at the wrong baud
rate gets the same garbled bytes; parity and data bits, which a PTY cannot carry, are seen for real.
Settings the client never set stay None (the device's own are assumed), like on a PTY.

A client sets baud, data size, parity and stop size as separate messages, then the flow control.
They are applied as one change (one mismatch warning, not one per message) when the flow control
arrives, when the host next sends data, or once SETTLE_S passes with no further setting.

Modem lines follow emulator/hosting/transports/modem.py: the client reads the device's CTS, DSR, CD and RI
from NOTIFY-MODEMSTATE (sent when the client accepts RFC 2217, at each change, and when it asks);
with the device's RTS/CTS flow control, CTS goes off when the device's input is full (as the daemon
stops reading) and on once it has room again (when the daemon resumes), and SET-CONTROL RTS OFF holds
the device's output here until RTS is on. A client that set RTS/CTS while CTS is off has its data
bytes held here (the access server's transmit buffer) while its telnet options are still read and
answered. DTR and break are logged; a `HostLine` has no field for them (no model uses them).

Bad input ends the connection with a log line, never the daemon: a malformed option (pyserial's
parser raises on it; the line names the command and what was wrong, e.g. `SET-BAUDRATE with 2 value
bytes (expected 4)`), a subnegotiation longer than any RFC 2217 one, or a client that keeps
negotiating without reading the answers.
"""

from __future__ import annotations

import asyncio
import logging
import select
import struct
from collections.abc import Callable
from typing import Any, cast

import serial
from serial import rfc2217

from emulator.device import HostLine, ModemLines
from emulator.hosting.ratelimit import LogLimiter
from emulator.hosting.transports.modem import HELD_INPUT_LIMIT, ModemLink
from emulator.hosting.transports.pty import OUTPUT_LIMIT
from emulator.hosting.transports.tcp import DRAIN_CHUNK, NetworkTransport

log = logging.getLogger("stage_emu.rfc2217")

PARITIES = {serial.PARITY_NONE: "none", serial.PARITY_EVEN: "even", serial.PARITY_ODD: "odd"}
MAX_BAUD = 10_000_000
#: longest subnegotiation accepted: RFC 2217's longest is 6 bytes (option, command, a 4-byte baud rate)
MAX_SUBOPTION = 64
#: protocol answers a client may leave unread on top of the output buffer before it is dropped
CONTROL_SLACK = 16384
#: settings that arrive within this much of each other are applied as one change
SETTLE_S = 0.2

_SETTINGS: dict[str, Callable[[Any], bool]] = {
    "baudrate": lambda v: isinstance(v, int) and 0 < v <= MAX_BAUD,
    "bytesize": lambda v: v in (5, 6, 7, 8),
    "parity": lambda v: v in PARITIES,  # mark and space are refused: the line model has neither
    "stopbits": lambda v: v in (1, 1.5, 2),
    "rtscts": lambda v: isinstance(v, bool),
    "xonxoff": lambda v: isinstance(v, bool),
}
#: RFC 2217's client commands (COM-PORT-OPTION subnegotiations), for messages about bad ones
_COMMANDS: dict[bytes, str] = {
    rfc2217.SET_BAUDRATE: "SET-BAUDRATE",
    rfc2217.SET_DATASIZE: "SET-DATASIZE",
    rfc2217.SET_PARITY: "SET-PARITY",
    rfc2217.SET_STOPSIZE: "SET-STOPSIZE",
    rfc2217.SET_CONTROL: "SET-CONTROL",
    rfc2217.NOTIFY_LINESTATE: "NOTIFY-LINESTATE",
    rfc2217.NOTIFY_MODEMSTATE: "NOTIFY-MODEMSTATE",
    rfc2217.FLOWCONTROL_SUSPEND: "FLOWCONTROL-SUSPEND",
    rfc2217.FLOWCONTROL_RESUME: "FLOWCONTROL-RESUME",
    rfc2217.SET_LINESTATE_MASK: "SET-LINESTATE-MASK",
    rfc2217.SET_MODEMSTATE_MASK: "SET-MODEMSTATE-MASK",
    rfc2217.PURGE_DATA: "PURGE-DATA",
}
#: value bytes a command carries where pyserial reads them (a baud rate is 4, the others 1)
_VALUE_SIZE = {
    rfc2217.SET_BAUDRATE: 4,
    rfc2217.SET_DATASIZE: 1,
    rfc2217.SET_PARITY: 1,
    rfc2217.SET_STOPSIZE: 1,
    rfc2217.SET_LINESTATE_MASK: 1,
    rfc2217.SET_MODEMSTATE_MASK: 1,
}
#: the values RFC 2217 defines for a command (0 asks for the current one)
_VALUES = {
    rfc2217.SET_PARITY: (0, *rfc2217.RFC2217_REVERSE_PARITY_MAP),
    rfc2217.SET_STOPSIZE: (0, *rfc2217.RFC2217_REVERSE_STOPBIT_MAP),
}

_FLOW = ("rtscts", "xonxoff")
_LINES = ("dtr", "rts", "break_condition")


def describe_bad_option(suboption: bytes | None) -> str:
    """What was wrong with a subnegotiation pyserial's parser refused (`suboption`: what came
    between IAC SB and IAC SE, None for an IAC SE with no IAC SB), in RFC 2217's terms."""
    if suboption is None:
        return "IAC SE with no subnegotiation begun (no IAC SB before it)"
    code = suboption[1:2]
    name = _COMMANDS.get(code)
    if suboption[:1] != rfc2217.COM_PORT_OPTION or name is None:
        return f"subnegotiation {suboption[:8].hex(' ')}"
    value = suboption[2:]
    size = _VALUE_SIZE.get(code, 1)
    if len(value) < size:
        return f"{name} with {len(value)} value byte{'' if len(value) == 1 else 's'} (expected {size})"
    allowed = _VALUES.get(code)
    if allowed is not None and value[0] not in allowed:
        return f"{name} with value {value[0]} (expected one of {', '.join(map(str, sorted(allowed)))})"
    return f"{name} with value bytes {value[:8].hex(' ')}"


class ComPortState:
    """The serial-like object PortManager drives: what the client set, and the device's modem lines
    it reports (`lines`). A refused value raises ValueError, which PortManager answers with the
    value in force. Until the client sets a value, the getters answer pyserial's defaults (9600 8N1,
    no flow control) to a client's query; RTS and DTR start on, as a host's open raises them."""

    def __init__(
        self,
        changed: Callable[[str], None],
        lines: Callable[[], ModemLines],
        purge_output: Callable[[], None],
        purge_input: Callable[[], None],
    ) -> None:
        self._changed = changed
        self._lines = lines
        self._purge_output = purge_output
        self._purge_input = purge_input
        self.baudrate = 9600
        self.bytesize = 8
        self.parity = serial.PARITY_NONE
        self.stopbits: float = 1
        self.rtscts = False
        self.xonxoff = False
        self.dtr = self.rts = True
        self.break_condition = False
        self.seen: set[str] = set()  # set last: the defaults above are not the client's

    def __setattr__(self, name: str, value: Any) -> None:
        check = _SETTINGS.get(name)
        if check is not None and not check(value):
            raise ValueError(f"unsupported {name} {value!r}")
        super().__setattr__(name, value)
        if "seen" in self.__dict__ and (check is not None or name in _LINES):
            if check is not None:
                self.seen.add(name)
            self._changed(name)

    @property
    def cts(self) -> bool:
        return self._lines().cts

    @property
    def dsr(self) -> bool:
        return self._lines().dsr

    @property
    def cd(self) -> bool:
        return self._lines().cd

    @property
    def ri(self) -> bool:
        return self._lines().ri

    def host_line(self) -> HostLine:
        """The settings the client set; those it has not set are unseen (None)."""

        def seen(name: str, value: Any) -> Any:
            return value if name in self.seen else None

        flow_seen = bool(self.seen & set(_FLOW))
        return HostLine(
            baud=seen("baudrate", self.baudrate),
            data_bits=seen("bytesize", self.bytesize),
            parity=seen("parity", PARITIES[self.parity]),
            stop_bits=seen("stopbits", self.stopbits),
            rtscts=self.rtscts if flow_seen else None,
            xonxoff=self.xonxoff if flow_seen else None,
        )

    def reset_input_buffer(self) -> None:
        """PURGE_DATA 1: drop device output the client has not been sent yet."""
        self._purge_output()

    def reset_output_buffer(self) -> None:
        """PURGE_DATA 2: host bytes not yet at the device. Those held here for CTS are dropped; those
        on the emulated wire already stay, as a real port's purge cannot recall them either."""
        self._purge_input()


class _Answers:
    """PortManager's `connection`: its protocol answers go out unescaped, ahead of nothing."""

    def __init__(self, send: Callable[[bytes], None]) -> None:
        self.write = send


class Rfc2217Transport(NetworkTransport):
    kind = "rfc2217"
    scheme = "rfc2217"

    def __init__(
        self,
        bind: str,
        port: int,
        loop: asyncio.AbstractEventLoop | None = None,
        limiter: LogLimiter | None = None,
    ) -> None:
        super().__init__(bind, port, loop, limiter)
        self._state: ComPortState | None = None
        self._manager: rfc2217.PortManager | None = None
        self._host = HostLine()
        self._dirty = False  # a setting changed since the device was last told
        self._flow_set = False  # ... and it included the flow control, a client's last setting
        self._settle: asyncio.TimerHandle | None = None
        self._modem: ModemLink | None = None
        #: the client's data bytes its UART holds back while it waits for CTS
        self._held_in = bytearray()
        #: device output held while the client's RTS is off (the device does flow control)
        self._held_out = bytearray()

    def _connected(self) -> None:
        self._host = HostLine()
        self._dirty = self._flow_set = False
        assert self._sink is not None
        self._modem = ModemLink(self._sink, self.path, log)
        self._state = ComPortState(
            self._on_setting, self._modem.lines, self._purge_output, self._held_in.clear
        )
        # Its constructor sends the server's opening offers (WILL COM-PORT-OPTION ...).
        # duck-typed as PortManager documents (its stubs ask for `Serial` objects)
        self._manager = rfc2217.PortManager(cast(Any, self._state), cast(Any, _Answers(self._send_raw)))

    def _disconnected(self) -> None:
        if self._settle is not None:
            self._settle.cancel()
            self._settle = None
        self._manager = self._state = self._modem = None
        self._held_out.clear()
        if self._held_in:  # the connection ended otherwise than by a hang-up (`_hang_up` counts)
            assert self._sink is not None
            log.info("%s: %d bytes held back for CTS were discarded", self.path, len(self._held_in))
            self._sink.input_discarded(len(self._held_in))
            self._held_in.clear()

    def _on_setting(self, name: str) -> None:
        assert self._state is not None and self._modem is not None
        if name == "rts":
            released = bytes(self._held_out) if self._state.rts else b""
            self._held_out.clear()
            self._modem.set_rts(self._state.rts, len(released))
            if released:
                self._send_raw(self._encode(released))
            return
        if name == "dtr":
            self._modem.set_dtr(self._state.dtr)
            return
        if name == "break_condition":
            log.info("%s: host set break %s", self.path, "on" if self._state.break_condition else "off")
            return
        if name == "rtscts":
            self._modem.host_rtscts = self._state.rtscts
        self._dirty = True
        self._flow_set = self._flow_set or name in _FLOW

    def _purge_output(self) -> None:
        self._pending.clear()
        self._held_out.clear()

    def _decode(self, raw: bytes) -> bytes | None:
        manager = self._manager
        assert manager is not None
        try:
            data = b"".join(manager.filter(raw))
        except (ValueError, KeyError, IndexError, TypeError, struct.error):
            # the parser raised inside the subnegotiation it was given: it still holds it
            suboption = None if manager.suboption is None else bytes(manager.suboption)
            log.warning(
                "%s: %s sent a malformed telnet option: %s; disconnecting",
                self.path,
                self._peer,
                describe_bad_option(suboption),
            )
            return None
        if manager.suboption is not None and len(manager.suboption) > MAX_SUBOPTION:
            log.warning(
                "%s: %s sent a telnet subnegotiation over %d bytes; disconnecting",
                self.path,
                self._peer,
                MAX_SUBOPTION,
            )
            return None
        if len(self._pending) > OUTPUT_LIMIT + CONTROL_SLACK:
            log.warning("%s: %s negotiates without reading the answers; disconnecting", self.path, self._peer)
            return None
        return data

    def _received(self, raw: bytes) -> None:
        data = self._decode(raw)
        if data is None:
            self._drop_connection(discarded=0)
            return
        if self._dirty:
            if data or self._flow_set:
                self._apply_settings()  # data the host sends is sent at its new settings
            else:
                if self._settle is not None:
                    self._settle.cancel()
                assert self._loop is not None
                self._settle = self._loop.call_later(SETTLE_S, self._apply_settings)
        assert self._sink is not None and self._modem is not None
        if data:
            if self._held_in or self._modem.input_held():
                self._held_in += data
            else:
                self._sink.host_data(data)
        if self._held_in:
            self._pass_held()
        self._check_lines()

    def _pass_held(self) -> None:
        """Hand held client bytes to the device once its UART may send, as far as there is room; while
        it may not, stop reading once the held bytes fill the transmit buffer (telnet options that
        arrive meanwhile wait in the kernel with the data)."""
        assert self._sink is not None and self._modem is not None
        if self._modem.input_held():
            self._modem.waiting(len(self._held_in))
            if len(self._held_in) >= HELD_INPUT_LIMIT:
                self._set_mask(self._mask & ~select.EPOLLIN)
            return
        chunk = self._modem.passable_input(self._held_in, max(self._sink.room(), 0))
        if chunk:
            self._sink.host_data(chunk)
        if len(self._held_in) < HELD_INPUT_LIMIT:
            super().resume_reading()

    def _check_lines(self) -> None:
        """Tell the client the device's lines if they changed (CTS follows the device's room)."""
        if self._manager is not None:
            self._manager.check_modem_lines()

    def resume_reading(self) -> None:
        if not (len(self._held_in) >= HELD_INPUT_LIMIT and self._modem and self._modem.input_held()):
            super().resume_reading()
        assert self._loop is not None
        self._loop.call_soon(self._room_back)  # not within the runner's call

    def _room_back(self) -> None:
        if self._manager is None:
            return
        if self._held_in:
            self._pass_held()
        self._check_lines()

    def _hang_up(self) -> None:
        """As a network port's hang-up, except that what the client's UART still held back for CTS
        never reaches the device, nor anything it sent after that."""
        if self._held_in:
            self._pass_held()
        if not self._held_in and not (self._modem is not None and self._modem.input_held()):
            super()._hang_up()
            return
        discarded = len(self._held_in)
        self._held_in.clear()
        while self._conn is not None:
            try:
                raw = self._conn.recv(DRAIN_CHUNK)
            except OSError:
                break
            data = self._decode(raw) if raw else None
            if data is None:
                break
            discarded += len(data)
        self._drop_connection(discarded)

    def write(self, data: bytes) -> int:
        modem = self._modem
        if modem is None or not modem.output_held():
            return super().write(data)
        return modem.hold_output(self._held_out, data, OUTPUT_LIMIT)

    def _apply_settings(self) -> None:
        if self._settle is not None:
            self._settle.cancel()
            self._settle = None
        self._dirty = self._flow_set = False
        if self._state is None or self._sink is None:
            return
        host = self._state.host_line()
        if host != self._host:
            self._host = host
            log.info("%s: host set %s", self.path, host.describe())
            self._sink.host_line(host)

    def _encode(self, data: bytes) -> bytes:
        # what PortManager.escape() yields byte by byte, at C speed (pyserial's client does the same)
        return data.replace(rfc2217.IAC, rfc2217.IAC_DOUBLED)

    def _fit(self, data: bytes, room: int) -> int:
        kept = max(min(len(data), room), 0)
        escaped = data.count(rfc2217.IAC, 0, kept)
        if kept + escaped > room:
            kept = max(room - escaped, 0)  # a shorter prefix escapes no more bytes: it fits
        return kept
