"""Traffic explanation for a hosted device: while a traffic log is kept or a control-channel
subscriber watches the traffic (`DeviceRunner.watch_traffic`), the runner holds an `Explainer` and
the model explains (`Device.explain`); otherwise the runner holds None and nothing is formatted (its
hot path tests one attribute). The records are what the model reports: its notes on received bytes,
each emission's summary when its last byte leaves the port and, for the log only, its pushed events,
`move` records and the other `LOG_ONLY` ones among them (a model builds those only while explaining;
they are never published to event subscribers). emulator/hosting/trafficlog.py has the record format.

Owns: whether records are kept (`watch`), and the records of what the runner itself does with the
bytes, besides the model's notes and summaries: input a hung port or a cleared wire never delivers,
input the transport discarded when the host hung up, output never sent (no host, a fault) or cleared
from the wire, and the note on a character a serial port received with a line error.

Asks of the runner: to keep the model's `explain` equal to `tap is not None`; to hand it, while it
has one, the model's notes (`take_notes`) and events, every emission it queues (`queued`; those the
port's faults withhold come from emulator/hosting/port_faults.py) and every byte that leaves (`left`); and
to `flush` after each step.
"""

from __future__ import annotations

from collections.abc import Callable

from emulator.device import GARBLED, Device, Emission, RxNote
from emulator.hosting.line_errors import UNSEEN_HOST
from emulator.hosting.port import Port
from emulator.hosting.trafficlog import DeviceTraffic, TrafficSink


class Explainer(DeviceTraffic):
    """One device's traffic records, with those the runner adds."""

    def take_notes(self, device: Device) -> None:
        """The model's notes on what it made of its input."""
        for note in device.take_rx_notes():
            self.rx(note)

    def withheld(self, emission: Emission, why: str) -> None:
        self.lost_tx(emission.due, emission, f"not sent: {why}")

    def unheard(self, t: float, port: str, data: bytes) -> None:
        """Host bytes a hung port took and nobody heard."""
        self.lost_rx(t, port, data, "hang fault: the device hears nothing")

    def line_error(self, t: float, port: str, byte: int, kind: str) -> None:
        note = f"garbled: the UART received {byte:02X} with a {kind} error ({UNSEEN_HOST})"
        self.rx(RxNote(t, GARBLED, bytes((byte,)), note, port))

    def hung_up(self, t: float, port: str, count: int) -> None:
        """The transport discarded `count` host bytes it had not handed over."""
        self.lost_rx(t, port, b"", f"the host hung up: {count} bytes left in the port discarded")
        self.flush()

    def cleared(self, t: float, ch: Port, why: str, input_too: bool) -> None:
        """The port's wire is about to be cleared: what is on it is lost (the host's bytes too, with
        `input_too`)."""
        self.discard(t, ch.name, f"not sent: {why}")
        if input_too:
            unheard = b"".join(data for _, data in ch.from_host.take_due(ch.from_host.wire_free))
            if unheard:
                self.lost_rx(t, ch.name, unheard, f"still on the wire when {why}")
        self.flush()


def watch(
    tap: Explainer | None, device: str, sink: TrafficSink | None, on_wire: Callable[[], dict[str, int]]
) -> Explainer | None:
    """The runner's tap once the subscribers' `sink` is set (None: removed): a sink without a log
    gets a tap of its own (the bytes `on_wire()` says are on each port's wire leave unrecorded), and
    a tap that neither logs nor has a sink is dropped."""
    if tap is None and sink is not None:
        tap = Explainer(None, device, on_wire())
    if tap is not None:
        tap.sink = sink
        if sink is None and not tap.logs:
            return None
    return tap
