"""The port a capture reads from: opened with pyserial (any device path or URL, `stageemu://`
included) at the line settings asked for, and one exchange per query.

Every query first drops what is still unread (a late reply to the query before must not pass for
this one's), then waits for its reply up to the timeout plus the reply's own wire time.
"""

from __future__ import annotations

from dataclasses import dataclass

import serial

from emulator.tools.capture.readings import CaptureError, Query, Transcript

PARITIES = {"none": serial.PARITY_NONE, "even": serial.PARITY_EVEN, "odd": serial.PARITY_ODD}
DATA_BITS = 8


@dataclass(frozen=True)
class LineOptions:
    """How the port is opened (`--baud`, `--parity`, `--stop-bits`, `--rtscts`)."""

    baud: int = 9600
    parity: str = "none"
    stop_bits: float = 1
    rtscts: bool = False

    def describe(self) -> str:
        stop = f"{self.stop_bits:g}"
        text = f"{self.baud} {DATA_BITS}{self.parity[0].upper()}{stop}"
        return text + (" RTS/CTS" if self.rtscts else "")

    def char_time(self) -> float:
        """Seconds one character takes on the wire at these settings."""
        bits = 1 + DATA_BITS + (0 if self.parity == "none" else 1) + self.stop_bits
        return bits / self.baud


def open_port(url: str, line: LineOptions, timeout: float) -> serial.Serial:
    """`url` opened at `line`; CaptureError with pyserial's reason when it cannot be."""
    import emulator.urlhandler  # noqa: F401  (a stageemu:// URL may stand for the controller)

    try:
        return serial.serial_for_url(
            url,
            baudrate=line.baud,
            bytesize=DATA_BITS,
            parity=PARITIES[line.parity],
            stopbits=line.stop_bits,
            rtscts=line.rtscts,
            timeout=timeout,
        )
    except (serial.SerialException, ValueError, OSError) as exc:
        raise CaptureError(f"{url}: cannot open the port: {exc}") from None


class Wire:
    """Queries on an open port. Every query goes through the transcript's read-only check first."""

    def __init__(
        self, port: serial.Serial, line: LineOptions, timeout: float, transcript: Transcript
    ) -> None:
        self.port = port
        self.line = line
        self.timeout = timeout
        self.transcript = transcript

    def wait_for(self, query: Query) -> float:
        """How long `query`'s reply may take: the timeout plus the wire time of its longest reply."""
        return self.timeout + query.reply_chars * self.line.char_time()

    def _send(self, query: Query) -> None:
        self.transcript.check(query)
        wait = self.wait_for(query)
        try:
            if self.port.timeout != wait:  # a serial port reconfigures at every change
                self.port.timeout = wait
            self.port.reset_input_buffer()
            self.port.write(query.wire)
        except (serial.SerialException, OSError) as exc:
            raise CaptureError(f"{self.port.name}: {exc}") from None

    def until(self, query: Query, terminator: bytes) -> tuple[bytes, bool]:
        """Send `query`; its reply up to and including `terminator`, and whether it came complete
        (False: what arrived before the wait ran out, possibly nothing)."""
        self._send(query)
        try:
            data = bytes(self.port.read_until(terminator))
        except (serial.SerialException, OSError) as exc:
            raise CaptureError(f"{self.port.name}: {exc}") from None
        return data, data.endswith(terminator)

    def count(self, query: Query, size: int) -> bytes:
        """Send `query`; up to `size` reply bytes (fewer if the wait ran out)."""
        self._send(query)
        try:
            return bytes(self.port.read(size))
        except (serial.SerialException, OSError) as exc:
            raise CaptureError(f"{self.port.name}: {exc}") from None
