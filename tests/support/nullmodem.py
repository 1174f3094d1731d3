"""A null-modem cable made of two pseudo-terminals, for testing the serial transport without
hardware.

The emulator opens one end (`device_link`, a stable symlink to the slave of one pty) as its serial
device; the host opens the other (`host_link`). A bridge thread copies bytes master to master. It
holds each slave open itself, so a master never sees its slave closed (no EIO, no POLLHUP), and a
host may open and close its end at will, as with a real port.

`unplug()` closes the emulator's pty and removes its link, as pulling a USB adapter removes its
device node: the emulator's open descriptor is hung up, and what the host sends meanwhile is lost.
`replug()` creates a new pty behind the same link.

Each direction is paced as a UART sends: a character reaches the other end one character time (at
the sender's settings) after the one before it, the bytes of one read back to back and the line idle
between reads, so replies take the wire time they take on a real cable (the emulator's serial
transport leaves the pacing to the line). When the two ends' settings differ (each end's termios,
read from its master: baud and stop bits; a pty shows no parity or data bits), the bridge garbles
what crosses as a real UART would, with the bit-level model of emulator/uart.py. A character
received with a framing error reaches its end as that end's termios say a POSIX port delivers it:
dropped with IGNPAR, 00 with INPCK, else as read. A pty cannot carry the PARMRK mark (the kernel
doubles an FF written to the master), so an end asking for marks gets the character as read.
"""

from __future__ import annotations

import contextlib
import os
import queue
import select
import termios
import threading
import time
import tty
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

from emulator.device import HostLine
from emulator.hosting.transports.pty import host_settings
from emulator.uart import Char, Framing, garble
from emulator.wire_time import char_time

#: read per wakeup from a master
CHUNK = 4096
#: stop reading an end while this much is waiting to be written to the other
BACKLOG = 65536


@dataclass
class _End:
    """One pty of the cable: its master (the bridge's), a slave descriptor the bridge holds, and
    the link the far side opens."""

    link: Path
    master: int = -1
    slave: int = -1
    #: what the other end sent, each byte with the instant its last stop bit arrives here
    pending: deque[tuple[float, int]] = field(default_factory=deque)
    #: when the line into this end is next idle
    wire_free: float = 0.0

    def create(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no CR translation until its opener configures it
        os.set_blocking(self.master, False)
        pts = os.ttyname(self.slave)
        with contextlib.suppress(FileNotFoundError):
            self.link.unlink()
        self.link.symlink_to(pts)

    def destroy(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.link.unlink()
        for fd in (self.master, self.slave):
            if fd >= 0:
                os.close(fd)
        self.master = self.slave = -1
        self.pending.clear()

    @property
    def present(self) -> bool:
        return self.master >= 0

    def framing(self) -> Framing:
        seen = host_settings(self.master)
        return Framing(seen.baud or 9600, 8, "none", Fraction(seen.stop_bits or 1))

    def due_in(self, now: float) -> float | None:
        """Seconds until the next byte for this end has arrived (None: nothing on the way)."""
        return max(self.pending[0][0] - now, 0.0) if self.pending else None

    def iflag(self) -> int:
        return int(termios.tcgetattr(self.master)[0])


class NullModem:
    """Two ptys joined by a bridge thread (start with `start`, end with `close`)."""

    def __init__(self, directory: Path, name: str = "nullmodem") -> None:
        directory.mkdir(parents=True, exist_ok=True)
        self.device_link = directory / f"{name}-device"
        self.host_link = directory / f"{name}-host"
        self._device = _End(self.device_link)
        self._host = _End(self.host_link)
        self._wake_r, self._wake_w = os.pipe()
        self._calls: queue.Queue[tuple[Callable[[], object], threading.Event]] = queue.Queue()
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="null-modem bridge", daemon=True)

    def start(self) -> NullModem:
        self._device.create()
        self._host.create()
        self._thread.start()
        return self

    def close(self) -> None:
        if self._thread.is_alive():
            self._on_bridge(lambda: setattr(self, "_stop", True))
            self._thread.join(5)
        self._device.destroy()
        self._host.destroy()
        os.close(self._wake_r)
        os.close(self._wake_w)

    def __enter__(self) -> NullModem:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- what a test does with the cable ------------------------------------------------------

    def unplug(self) -> None:
        """The emulator's end goes away (its descriptor is hung up, its link removed)."""
        self._on_bridge(self._device.destroy)

    def replug(self) -> None:
        """A new emulator end behind the same link."""
        self._on_bridge(self._device.create)

    def device_settings(self) -> HostLine:
        """What the emulator set on its end (baud, stop bits, flow control)."""
        box: list[HostLine] = []
        self._on_bridge(lambda: box.append(host_settings(self._device.master)))
        return box[0]

    def _on_bridge(self, action: Callable[[], object]) -> None:
        """Run `action` on the bridge thread between two copies (never while it polls a descriptor
        the action closes), and wait until it has."""
        done = threading.Event()
        self._calls.put((action, done))
        os.write(self._wake_w, b"x")
        if not done.wait(5):
            raise TimeoutError("the null-modem bridge did not answer")

    # ---- the bridge ---------------------------------------------------------------------------

    def _run(self) -> None:
        while not self._stop:
            poller = select.poll()
            poller.register(self._wake_r, select.POLLIN)
            now = time.monotonic()
            waits = []
            for end, other in ((self._device, self._host), (self._host, self._device)):
                if not end.present:
                    continue
                due_in = end.due_in(now)
                mask = select.POLLOUT if due_in == 0 else 0
                if due_in:
                    waits.append(due_in)
                if len(other.pending) < BACKLOG:
                    mask |= select.POLLIN
                if mask:
                    poller.register(end.master, mask)
            timeout_ms = None if not waits else max(1, int(min(waits) * 1000 + 0.999))
            ready = poller.poll(timeout_ms)
            if not ready:
                for end in (self._device, self._host):
                    self._write(end)
            for fd, events in ready:
                if fd == self._wake_r:
                    os.read(self._wake_r, 64)
                    self._run_calls()
                    break  # descriptors may have changed: poll again
                end, other = (
                    (self._device, self._host) if fd == self._device.master else (self._host, self._device)
                )
                if events & select.POLLOUT:
                    self._write(end)
                if events & select.POLLIN:
                    self._copy(end, other)

    def _run_calls(self) -> None:
        while True:
            try:
                action, done = self._calls.get_nowait()
            except queue.Empty:
                return
            action()
            done.set()

    def _copy(self, source: _End, sink: _End) -> None:
        try:
            data = os.read(source.master, CHUNK)
        except (BlockingIOError, OSError):
            return
        if not data or not sink.present:
            return  # into a cable with nothing at the other end
        sender, receiver = source.framing(), sink.framing()
        if sender != receiver:
            data = self._as_received(garble(data, sender, receiver), sink.iflag())
        per_char = char_time(sender.baud, sender.data_bits, sender.parity, float(sender.stop_bits))
        start = max(time.monotonic(), sink.wire_free)
        sink.pending.extend((start + (k + 1) * per_char, byte) for k, byte in enumerate(data))
        sink.wire_free = start + len(data) * per_char
        self._write(sink)

    @staticmethod
    def _as_received(chars: list[Char], iflag: int) -> bytes:
        """What a POSIX port with input flags `iflag` delivers of the characters its UART decoded."""
        out = bytearray()
        for char in chars:
            if not (char.framing_error or char.parity_error):
                out.append(char.value)
            elif iflag & termios.INPCK and iflag & termios.IGNPAR:
                continue
            elif iflag & termios.INPCK and not iflag & termios.PARMRK:
                out.append(0)
            else:
                out.append(char.value)
        return bytes(out)

    @staticmethod
    def _write(end: _End) -> None:
        """Hand over what has arrived at `end` by now."""
        now = time.monotonic()
        pending = end.pending
        while pending and end.present:
            count = 0
            while count < len(pending) and pending[count][0] <= now:
                count += 1
            if not count:
                return
            try:
                sent = os.write(end.master, bytes(pending[i][1] for i in range(count)))
            except BlockingIOError:
                return
            for _ in range(sent):
                pending.popleft()
