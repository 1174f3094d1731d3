"""Modem lines on a port that carries them: an RFC 2217 port (transports/rfc2217.py) and the
in-process `stageemu://` URL (urlhandler/). A pseudo-terminal and raw TCP carry none; nothing here
applies to them.

The device drives CTS, DSR, CD and RI as it declares them (`PortSink.modem_lines`, named as the host
reads them). A device with RTS/CTS flow control (its own `LineSettings.rtscts`: the MP-285A's USB
port) drives CTS from its input instead, off while its input is full (`PortSink.room() == 0`) and on
once there is room, and sends only while the host's RTS is on: what it would send meanwhile waits in
the port, bounded like the port's output buffer, and goes out when RTS is on again.

The host drives RTS and DTR, both on from the moment it opens the port (a serial driver raises them
at open; pyserial's `rts = False` lowers RTS). With RTS/CTS set, its UART sends only while CTS is on.

Where the controllers' references say nothing, this module decides:
- DTR, and RTS towards a device without flow control, go nowhere: no emulated controller has an input
  for them (the MS2000 ignores them, MS-1; the MP-285's RS-232 port has three wires, MP-1).
- A host that set RTS/CTS on a port whose device never asserts CTS (the MS2000, the MP-285's RS-232
  port) cannot send, as with a real UART: its bytes wait in its transmit buffer until it turns RTS/CTS
  off. This is logged once per episode.
- Output held by the host's RTS goes out at once when RTS is on again, not paced a second time.
"""

from __future__ import annotations

import logging
from dataclasses import replace

from emulator.device import ModemLines
from emulator.hosting.transports.base import PortSink

log = logging.getLogger("stage_emu.modem")

#: Host bytes a network port keeps while the host's UART waits for CTS, as a serial driver's transmit
#: buffer holds them (the runner's input backlog is the same size); beyond it the port stops reading
HELD_INPUT_LIMIT = 4096


def on_off(value: bool) -> str:
    return "on" if value else "off"


class ModemLink:
    """One port's modem lines: the device's, read from its sink whenever asked, and the host's RTS,
    DTR and RTS/CTS setting. `where` names the port in log lines."""

    def __init__(self, sink: PortSink, where: str, logger: logging.Logger = log) -> None:
        self._sink = sink
        self.where = where
        self._log = logger
        self.rts = True
        self.dtr = True
        #: the host's UART sends only while CTS is on (its RTS/CTS setting)
        self.host_rtscts = False
        #: told in this episode: the host's bytes wait for CTS; output held by RTS overflowed
        self._told_waiting = False
        self._told_overflow = False

    def opened(self) -> None:
        """A host opened the port: RTS and DTR on, no RTS/CTS until it sets it."""
        self.rts = self.dtr = True
        self.host_rtscts = False
        self._told_waiting = self._told_overflow = False

    @property
    def flow(self) -> bool:
        """The device does RTS/CTS flow control."""
        return bool(self._sink.device_line().rtscts)

    def lines(self) -> ModemLines:
        """The device's lines as the host reads them now."""
        declared = self._sink.modem_lines()
        if self.flow:
            return replace(declared, cts=self._sink.room() > 0)
        return declared

    def output_held(self) -> bool:
        """The device may not send now: it does flow control and the host's RTS is off."""
        return not self.rts and self.flow

    def input_held(self) -> bool:
        """The host's UART may not send now: it uses RTS/CTS and CTS is off."""
        return self.host_rtscts and not self.lines().cts

    def set_rts(self, on: bool, released: int = 0) -> None:
        """The host set RTS; `released`: output held while it was off that goes out now."""
        if on == self.rts:
            return
        self.rts = on
        self._told_overflow = False
        if not self.flow:
            self._log.info(
                "%s: host set RTS %s (ignored: the device has no flow control)", self.where, on_off(on)
            )
        elif on:
            self._log.info(
                "%s: host set RTS on: the device sends again (%d bytes held meanwhile)", self.where, released
            )
        else:
            self._log.info("%s: host set RTS off: the device holds its output until RTS is on", self.where)

    def set_dtr(self, on: bool) -> None:
        if on != self.dtr:
            self.dtr = on
            self._log.info(
                "%s: host set DTR %s (ignored: the device has no DTR input)", self.where, on_off(on)
            )

    def hold_output(self, held: bytearray, data: bytes, limit: int) -> int:
        """Keep `data` in `held` (output held for the host's RTS) up to `limit` bytes in all; returns
        how many of the newest were dropped, said once per episode."""
        kept = max(min(len(data), limit - len(held)), 0)
        held += data[:kept]
        if kept < len(data):
            self.overflowed()
        return len(data) - kept

    def passable_input(self, held: bytearray, room: int) -> bytes:
        """Take from `held` (the host's bytes waiting for CTS) what may go to the device now, at most
        `room` bytes: nothing while the host's UART may not send."""
        if not held or self.input_held():
            return b""
        self.released(len(held))
        chunk = bytes(held[:room])
        del held[:room]
        return chunk

    def overflowed(self) -> None:
        """Output held for the host's RTS did not fit the port's buffer (the runner counts what is
        dropped; this says why, once per episode)."""
        if not self._told_overflow:
            self._told_overflow = True
            self._log.warning(
                "%s: the output held while the host's RTS is off fills the port's buffer; "
                "newer output is dropped",
                self.where,
            )

    def waiting(self, held: int) -> None:
        """The host's bytes wait for CTS (told once per episode)."""
        if not self._told_waiting:
            self._told_waiting = True
            self._log.warning(
                "%s: the host uses RTS/CTS flow control and the device does not assert CTS: its bytes "
                "wait in its transmit buffer (%d so far) until it turns RTS/CTS off",
                self.where,
                held,
            )

    def released(self, count: int) -> None:
        """The bytes that waited for CTS went to the device."""
        if self._told_waiting:
            self._told_waiting = False
            self._log.info("%s: %d bytes the host held back for CTS go to the device", self.where, count)
