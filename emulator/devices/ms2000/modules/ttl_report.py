"""TTL REPORT: each IN0 edge in mode 6 latches every motor axis and sends one frame (§9.4).

With `TTL X=6` a rising edge on IN0 latches the encoder position of every motor axis and sends a
frame (protocols/ms2000/ttl_report.py has the format) on the auxiliary port, a second serial port
at the main port's baud rate (MS-TTLREP-1, MS-5). Timing (MS-TTLREP-2): the latch is `LATCH_S`
after the edge, the frame leaves `AXIS_READ_S` per axis later. A frame takes its wire time plus
0.11 ms of firmware work (MS-TTLREP-3); an edge meanwhile finds the transmitter busy: its frame is
dropped and code 87 logged.

Knobs: `ttl_report_port` (`aux` | `main`: the frames go out on the main port, between replies,
MS-18 g) and `ttl_report_format` (`binary` | `ascii`: the positions as `W` prints them, one line,
MS-TTLREP-4). The auxiliary port exists only with `aux` (`channels`). Each frame on it is also a
control-channel event `aux_tx` (Appendix B); observable `ttl_report`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000.modules import Module, register
from emulator.devices.ms2000.modules.capabilities import ControlChannel, TtlIn
from emulator.devices.ms2000.modules.events import Reset, on
from emulator.profiles.schema import Choice, Field
from protocols.ms2000 import frame as text_frame
from protocols.ms2000 import ttl_report as codec
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer

MODE = 6
AUX = "aux"
#: code 87 TTL_REPORT_BUFFER_OVERRUN (MS-TTLREP-3)
OVERRUN = 87
#: edge to latch: 3–10 µs on real hardware (MS-TTLREP-2); the middle of that range [choice]
LATCH_S = 6e-6
#: reading one axis after the latch, before the frame can leave (MS-TTLREP-2)
AXIS_READ_S = 12e-6
#: firmware time a frame costs besides its wire time (MS-TTLREP-3)
FRAME_OVERHEAD_S = 0.11e-3
#: the overrun rule counts 10 bits per character, whatever the stop bits (MS-TTLREP-3)
BITS_PER_CHAR = 10


@register
class TtlReport(Module, TtlIn, ControlChannel):
    name = "TTL REPORT"
    in0_modes = frozenset({MODE})
    observable = "ttl_report"
    knob_fields = (
        Field(
            "ttl_report_port",
            Choice((AUX, "main")),
            AUX,
            "MS-TTLREP-1",
            "port the TTL REPORT frames go out on (aux: a second port at the main port's baud)",
        ),
        Field(
            "ttl_report_format",
            Choice(("binary", "ascii")),
            "binary",
            "MS-TTLREP-4",
            "TTL REPORT frame: id byte + int32 counts per axis then CR, or a W-formatted line",
        ),
    )

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.frames = 0
        self.overruns = 0
        #: the edge whose frame is being latched or sent: until `_busy_until` a new edge overruns
        self._latch: Timer | None = None
        self._send: Timer | None = None
        self._busy_until = float("-inf")

    @classmethod
    def channels(cls, knobs: Any) -> tuple[str, ...]:
        return (AUX,) if knobs.ttl_report_port == AUX else ()

    @property
    def channel(self) -> str:
        return str(self.controller.knobs.ttl_report_port)

    def observe(self, now: float) -> Any:
        knobs = self.controller.knobs
        return {
            "port": knobs.ttl_report_port,
            "format": knobs.ttl_report_format,
            "frames": self.frames,
            "overruns": self.overruns,
            "sending": self._latch is not None or now < self._busy_until,
        }

    @on(Reset)
    def reset(self, event: Reset) -> None:
        for timer in (self._latch, self._send):
            if timer is not None:
                timer.cancel()
        self._latch = self._send = None
        self._busy_until = float("-inf")

    def in0_trigger(self, mode: int, now: float) -> None:
        if self._latch is not None or now < self._busy_until:
            self.overruns += 1
            self.controller.log_error(OVERRUN)
            return
        self._latch = self.controller.at(now + LATCH_S, lambda t: self._latch_positions(now, t))

    def _latch_positions(self, edge: float, now: float) -> None:
        self._latch = None
        axes = self.controller.axes
        binary = self.controller.knobs.ttl_report_format == "binary"
        data = self._binary(axes, now) if binary else self._ascii(axes, now)
        self._busy_until = edge + len(data) * BITS_PER_CHAR / self.controller.baud + FRAME_OVERHEAD_S
        self._send = self.controller.at(now + AXIS_READ_S * len(axes), lambda t: self._transmit(data, t))

    def _transmit(self, data: bytes, now: float) -> None:
        self._send = None
        self.frames += 1
        self.controller.send_raw(data, now, channel=self.channel)
        if self.channel == AUX:
            self.controller.push_event({"ev": "aux_tx", "t": now, "data": data.hex()})

    @staticmethod
    def _counts(axis: Axis, t: float) -> int:
        """The latched encoder position in counts relative to the current origin (MS-TTLREP-2)."""
        return round_half_away(axis.user_mm_of(axis.physical(t)) * axis.counts_per_mm)

    def _binary(self, axes: Sequence[Axis], t: float) -> bytes:
        return codec.encode([(axis.s.ll_id, self._counts(axis, t)) for axis in axes])

    def _ascii(self, axes: Sequence[Axis], t: float) -> bytes:
        """The latched positions as `W` prints them, one line with the current terminator (MS-TTLREP-4)."""
        units = (axis.user_mm_of(axis.physical(t)) * axis.s.unit_multiplier for axis in axes)
        text = " ".join(self.controller.where(u) for u in units)
        return text_frame([text.encode("ascii")], bool(self.controller.card.vb_flags & 8))
