"""An in-process port with modem lines (emulator/hosting/transports/modem.py): the host's RTS and DTR reach
it, the device's CTS, DSR, CD and RI are read from it, and each side's flow control holds bytes.

- Output: while the device does RTS/CTS flow control and the host's RTS is off, what the runner hands
  over waits here instead of in the host's receive buffer; both together stay within that buffer's
  size (the newest bytes beyond it are dropped, as on any full port). RTS on moves them across.
- Input: while the host set RTS/CTS and CTS is off, what it writes waits here, in its transmit
  buffer: `room` counts these bytes against the wire's backlog, so a write takes no more than a
  real driver would and then blocks (or times out) as on a real port. They cross once CTS is on or
  the host turns RTS/CTS off (`pass_held`, from each host call).
"""

from __future__ import annotations

from emulator.device import HostLine, ModemLines
from emulator.hosting.transports.base import PortSink
from emulator.hosting.transports.inprocess import InProcessTransport
from emulator.hosting.transports.modem import ModemLink


class ModemTransport(InProcessTransport):
    def __init__(self, url: str) -> None:
        super().__init__(url)
        self._modem: ModemLink | None = None
        #: the host's bytes its UART holds back while it waits for CTS
        self.held_in = bytearray()
        #: device output held while the host's RTS is off
        self.held_out = bytearray()

    def open(self, sink: PortSink) -> None:
        super().open(sink)
        self._modem = ModemLink(sink, self.path)

    def _link(self) -> ModemLink:
        if self._modem is None:
            raise RuntimeError("the transport is not attached to a runner yet")
        return self._modem

    # ---- the host's side ------------------------------------------------------------------------

    def attach(self, host: HostLine) -> None:
        link = self._link()
        link.opened()
        link.host_rtscts = bool(host.rtscts)
        super().attach(host)

    def detach(self) -> None:
        self._drop_held()
        super().detach()

    def change_line(self, host: HostLine) -> None:
        self._link().host_rtscts = bool(host.rtscts)
        super().change_line(host)
        self.pass_held()

    def set_rts(self, on: bool) -> None:
        released = len(self.held_out) if on else 0
        self._link().set_rts(on, released)
        if released:
            self.received += self.held_out  # they were kept within the receive buffer's size
            self.held_out.clear()

    def set_dtr(self, on: bool) -> None:
        self._link().set_dtr(on)

    def lines(self) -> ModemLines:
        return self._link().lines()

    def room(self) -> int:
        """Bytes a write hands over now: the wire's room, less what already waits for CTS."""
        room = super().room()
        if self.held_in or self._link().input_held():
            return max(room - len(self.held_in), 0)
        return room

    def send(self, data: bytes) -> None:
        link = self._link()
        if self.held_in or link.input_held():
            self.held_in += data
            link.waiting(len(self.held_in))
            self.pass_held()
        else:
            super().send(data)

    def pass_held(self) -> None:
        """Bytes held for CTS cross once the host's UART may send, as far as the wire has room."""
        chunk = self._link().passable_input(self.held_in, super().room())
        if chunk:
            super().send(chunk)

    def discard_held_input(self) -> None:
        """The host flushed its output (tcflush TCOFLUSH): what waits for CTS goes too."""
        self.held_in.clear()

    def _drop_held(self) -> None:
        if self.held_in and self._sink is not None:
            self._sink.input_discarded(len(self.held_in))
        self.held_in.clear()
        self.held_out.clear()

    # ---- the runner's side ----------------------------------------------------------------------

    def write(self, data: bytes) -> int:
        link = self._modem
        if link is None or not link.output_held():
            return super().write(data)
        return link.hold_output(self.held_out, data, self._limit - len(self.received))

    def close(self) -> None:
        self._drop_held()
        super().close()

    def vanish(self) -> None:
        self._drop_held()
        super().vanish()
