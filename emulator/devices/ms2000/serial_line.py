"""The controller's serial port and the host on the other end (MS-1…MS-4).

The controller's own settings come from its DIP switches and `STOPBITS` (8N1 or 8N2 at the switch
baud); the host's are what the transport sees plus what the control channel declares of what it
cannot see (data bits, parity). At a mismatch of baud, data bits or parity each side reads garbage
of the other's bytes (`line_mismatch: garble`, MS-4). Both are asked for per byte and per reply, so
the derived values are computed once per change, not per call.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any, Protocol

from emulator.device import HostLine, LineSettings

if TYPE_CHECKING:
    from emulator.devices.ms2000.sections import Ms2000Knobs
    from emulator.devices.ms2000.settings import CardSettings

#: settings that garble the traffic when they differ (stop bits and flow control do not)
_GARBLING = ("baud", "data_bits", "parity")


def garble(data: bytes) -> bytes:
    """MS-4: each byte XOR 0x55, never CR nor 0xFF."""
    out = bytearray()
    for b in data:
        g = b ^ 0x55
        out.append({0x0D: 0x0E, 0xFF: 0xFE}.get(g, g))
    return bytes(out)


class LineOwner(Protocol):
    """All the serial line reads of its controller."""

    @property
    def baud(self) -> int:
        """The DIP switches' baud (MS-2)."""

    @property
    def card(self) -> CardSettings:
        """`STOPBITS` (MS-3)."""

    @property
    def knobs(self) -> Ms2000Knobs:
        """`line_mismatch` (MS-4)."""


class SerialLine:
    def __init__(self, controller: LineOwner) -> None:
        self.controller = controller
        self._seen: HostLine | None = None
        self._declared: dict[str, Any] = {}
        self._host: HostLine | None = None
        #: one object per (baud, stop bits): callers compare it cheaply
        self._own = LineSettings()
        self._own_key: tuple[int, float] | None = None
        self._garbling = False

    def own(self) -> LineSettings:
        key = (self.controller.baud, self.controller.card.stop_bits)
        if key != self._own_key:
            self._own_key = key
            self._own = LineSettings(key[0], 8, "none", key[1], False, False)
            self._garbling = self.garbles_for(self._host)
        return self._own

    def host(self) -> HostLine | None:
        """What the host uses: seen and declared settings merged (None: no host)."""
        return self._host

    def host_changed(self, host: HostLine | None) -> None:
        self._seen = host
        # the transport now reports what it can see; declarations of what it cannot see stay
        self._declared = (
            {} if host is None else {k: v for k, v in self._declared.items() if k in ("data_bits", "parity")}
        )
        self._merge()

    def declare(self, settings: dict[str, Any]) -> None:
        """Host settings the transport cannot see, declared on the control channel (MS-4)."""
        self._declared.update(settings)
        self._merge()

    def _merge(self) -> None:
        if self._seen is None and not self._declared:
            self._host = None
        else:
            self._host = replace(self._seen or HostLine(), **self._declared)
        self._garbling = self.garbles_for(self._host)

    def garbles(self) -> bool:
        """Whether the current host's bytes and the replies to it are garbled (MS-4)."""
        self.own()  # brings `_garbling` up to date if the controller's own line changed
        return self._garbling

    def garbles_for(self, host: HostLine | None) -> bool:
        if host is None or self.controller.knobs.line_mismatch != "garble":
            return False
        own = self.own()
        return any(getattr(host, n) is not None and getattr(host, n) != getattr(own, n) for n in _GARBLING)

    def mismatch_effect(self, host: HostLine) -> str:
        own = self.own()
        if self.garbles_for(host):
            return "traffic will be garbled (line_mismatch=garble)"
        if any(getattr(host, n) not in (None, getattr(own, n)) for n in _GARBLING):
            return "the mismatch is ignored (line_mismatch=ignore)"
        if host.stop_bits not in (None, own.stop_bits):
            return "harmless: the controller samples only the first stop bit"
        return "harmless: the controller ignores flow control"

    def describe_mismatch(self) -> str:
        """Both sides' settings, for the traffic log's notes on garbled bytes."""
        host = self._host
        seen = "?" if host is None else host.filled(self.own()).describe()
        return f"host at {seen}, device at {self.own().describe()}:"
