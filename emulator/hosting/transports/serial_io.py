"""Moving bytes through an open serial port (emulator/hosting/transports/serial.py), in one of two ways:

- `FdIo`, a serial device: its descriptor is watched by the event loop through an epoll of its own
  (level-triggered, like emulator/hosting/transports/tcp.py, so a hang-up is seen even while reading is
  paused), read and written non-blocking; line errors are decoded from the kernel's PARMRK marks.
- `ThreadIo`, a port without a descriptor to watch (an `rfc2217://` or `socket://` URL; a COM port,
  were the daemon to run on Windows): a reader thread and a writer thread hand bytes to and from
  the loop.

Flow control follows emulator/hosting/transports/base.py. Input: at most `room()` bytes, READ_CHUNK per
wakeup; at 0 the port is not read, so the driver's buffer fills and, with RTS/CTS, the driver
holds the host off. Output: written at once (the runner hands each byte over at the model's instant
and the UART paces the line from there: nothing here may hold bytes back and send them together);
what the driver does not take waits in a buffer of OUTPUT_LIMIT bytes, and what does not fit is
dropped and counted.

A port that fails (a read or write error, EOF, a hang-up) is reported to `gone` once, on the loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import select
import threading
from collections.abc import Callable

import serial

from emulator.hosting.transports.base import PortSink
from emulator.hosting.transports.pty import OUTPUT_LIMIT, READ_CHUNK, drop_overrun
from emulator.hosting.transports.serial_port import LineError, error_counts, error_kind, unmark

#: `gone(reason)`: the port failed (reason: a few words for the log)
Gone = Callable[[str], None]

_HANGUP = select.EPOLLHUP | select.EPOLLERR


class FdIo:
    """A serial device's descriptor, on the event loop."""

    def __init__(self, fd: int, loop: asyncio.AbstractEventLoop, sink: PortSink, gone: Gone) -> None:
        self._fd = fd
        self._loop = loop
        self._sink = sink
        self._gone = gone
        #: the port checks parity: a marked character may be a parity error (else it is a framing error)
        self.parity_on = False
        self._counts = error_counts(fd)
        self._held = b""
        self._pending = bytearray()
        self._stopped = False
        self._resume: asyncio.Handle | None = None
        os.set_blocking(fd, False)
        self._mask = select.EPOLLIN
        self._epoll = select.epoll()
        self._epoll.register(fd, self._mask)
        loop.add_reader(self._epoll.fileno(), self._on_ready)

    def stop(self) -> None:
        """Stop watching the descriptor (the port itself is closed by its owner)."""
        if self._stopped:
            return
        self._stopped = True
        if self._resume is not None:
            self._resume.cancel()
        self._loop.remove_reader(self._epoll.fileno())
        self._epoll.close()
        self._pending.clear()

    def _fail(self, reason: str) -> None:
        if not self._stopped:
            self.stop()
            self._gone(reason)

    def _set_mask(self, mask: int) -> None:
        if mask != self._mask and not self._stopped:
            self._mask = mask
            self._epoll.modify(self._fd, mask)

    def _on_ready(self) -> None:
        events = 0
        for _fd, mask in self._epoll.poll(0):
            events |= mask
        if events & _HANGUP:
            self._fail("hang-up")
            return
        if events & select.EPOLLOUT:
            self._flush()
        if events & select.EPOLLIN:
            self._read()

    def resume(self) -> None:
        # Later, not within the sink's own processing (base.py); the epoll is level-triggered, so
        # turning EPOLLIN back on is all it takes.
        if self._resume is None and not self._stopped:
            self._resume = self._loop.call_soon(self._resume_now)

    def _resume_now(self) -> None:
        self._resume = None
        self._set_mask(self._mask | select.EPOLLIN)

    def _read(self) -> None:
        """One slice: with bytes left, the level-triggered epoll reports the port again on the
        loop's next pass, after the other ports had their turn."""
        budget = READ_CHUNK
        while not self._stopped and budget > 0:
            room = self._sink.room()
            if room <= 0:
                self._set_mask(self._mask & ~select.EPOLLIN)  # the host's bytes wait in the driver
                return
            asked = min(room, budget)
            try:
                raw = os.read(self._fd, asked)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                self._fail(exc.strerror or str(exc))
                return
            if not raw:
                self._fail("end of file")
                return
            budget -= len(raw)
            self._deliver(raw)
            if len(raw) < asked:
                return

    def _deliver(self, raw: bytes) -> None:
        pieces, self._held = unmark(raw, self._held)
        for piece in pieces:
            if self._stopped:
                return
            if isinstance(piece, LineError):
                counts = error_counts(self._fd) if self.parity_on else None
                kind = error_kind(self.parity_on, self._counts, counts)
                self._counts = counts
                self._sink.line_error(piece.byte, kind)
            else:
                self._sink.host_data(piece)

    def write(self, data: bytes) -> int:
        if self._stopped:
            return 0
        waiting = bool(self._pending)  # then EPOLLOUT is armed and flushes once the driver takes more
        self._pending += data
        if not waiting:
            self._flush()
        return drop_overrun(self._pending)

    def _flush(self) -> None:
        while self._pending and not self._stopped:
            try:
                sent = os.write(self._fd, self._pending)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:
                # reported from the loop: a write comes from inside the runner's step
                self._pending.clear()
                self._loop.call_soon(self._fail, exc.strerror or str(exc))
                return
            del self._pending[:sent]
        if self._pending:
            self._set_mask(self._mask | select.EPOLLOUT)
        else:
            self._set_mask(self._mask & ~select.EPOLLOUT)


class ThreadIo:
    """A port read and written by threads of its own, each handing over to the loop. The reader
    reads only as much as the loop has granted (the sink's room), so a full device leaves the host's
    bytes with the port; the writer sends what the loop queued, as soon as it is queued."""

    def __init__(
        self, port: serial.SerialBase, loop: asyncio.AbstractEventLoop, sink: PortSink, gone: Gone
    ) -> None:
        self._port = port
        self._loop = loop
        self._sink = sink
        self._gone = gone
        self._cond = threading.Condition()
        #: bytes the reader may read now (set on the loop from the sink's room, 0 while paused)
        self._grant = 0
        self._paused = False
        self._stopped = False
        self._out = bytearray()
        self._threads = [
            threading.Thread(target=self._read_loop, name=f"serial reader {port.name}", daemon=True),
            threading.Thread(target=self._write_loop, name=f"serial writer {port.name}", daemon=True),
        ]
        self._regrant()
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        """Tell both threads to end, without waiting for them: a thread in the middle of a read or
        write fails once its owner closes the port (or its read times out), and ends quietly."""
        with self._cond:
            if self._stopped:
                return
            self._stopped = True
            self._out.clear()
            self._cond.notify_all()
        for cancel in ("cancel_read", "cancel_write"):
            with contextlib.suppress(Exception):  # not every port type has them
                getattr(self._port, cancel)()

    # ---- on the loop --------------------------------------------------------------------------

    def _regrant(self) -> None:
        room = self._sink.room()
        if room <= 0:
            self._paused = True
            return
        with self._cond:
            self._grant = min(room, READ_CHUNK)
            self._cond.notify_all()

    def resume(self) -> None:
        if self._paused:
            self._paused = False
            self._loop.call_soon(self._regrant_unless_stopped)

    def _regrant_unless_stopped(self) -> None:
        if not self._stopped:
            self._regrant()

    def _deliver(self, data: bytes) -> None:
        if self._stopped:
            return
        self._sink.host_data(data)
        if not self._stopped:
            self._regrant()

    def _fail(self, reason: str) -> None:
        if not self._stopped:
            self.stop()
            self._gone(reason)

    def write(self, data: bytes) -> int:
        with self._cond:
            if self._stopped:
                return 0
            kept = max(min(len(data), OUTPUT_LIMIT - len(self._out)), 0)
            self._out += data[:kept]
            self._cond.notify_all()
        return len(data) - kept

    # ---- on the threads -----------------------------------------------------------------------

    def _post_failure(self, exc: BaseException) -> None:
        with contextlib.suppress(RuntimeError):  # the loop is closed: the daemon is gone anyway
            self._loop.call_soon_threadsafe(self._fail, str(exc) or type(exc).__name__)

    def _read_loop(self) -> None:
        port = self._port
        while True:
            with self._cond:
                while self._grant <= 0 and not self._stopped:
                    self._cond.wait()
                if self._stopped:
                    return
                grant = self._grant
            try:
                data = port.read(1)  # until a byte arrives or the port's timeout passes
                waiting = port.in_waiting if data else 0  # type: ignore[attr-defined]  # every port type has it
                if waiting and grant > 1:
                    data += port.read(min(waiting, grant - 1))
            except Exception as exc:  # any port type's failure: a hang-up
                if not self._stopped:
                    self._post_failure(exc)
                return
            if not data:
                continue  # timed out: look at the stop flag again
            with self._cond:
                self._grant = 0  # the loop grants again once it has passed these on
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(self._deliver, data)

    def _write_loop(self) -> None:
        port = self._port
        while True:
            with self._cond:
                while not self._out and not self._stopped:
                    self._cond.wait()
                if self._stopped:
                    return
                chunk = bytes(self._out)
                self._out.clear()
            try:
                port.write(chunk)
            except Exception as exc:  # any port type's failure: a hang-up
                if not self._stopped:
                    self._post_failure(exc)
                return
