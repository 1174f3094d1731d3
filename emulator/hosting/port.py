"""One port of a hosted device as the runner keeps it (emulator/hosting/runner.py): its transport, the host
seen on it, pacing in both directions, injected faults, and the bounds on what waits in it.

Flow control (emulator/hosting/transports/base.py): a port reads only while `room` says the emulated wire
takes more, stops at INPUT_BACKLOG of input or OUTPUT_BACKLOG of output waiting for their wire time,
and is told to read again (`resume_reading`) once both are down to half. Output a host does not
take is counted and logged once per episode (`count_drops`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

from emulator.device import HostLine
from emulator.hosting.transports.base import Transport
from emulator.wire_time import REALISTIC, Pacer

log = logging.getLogger("stage_emu.runner")

#: Host input a port has taken but the device has not yet received (its wire time has not ended),
#: per port, in bytes. At this backlog the port stops reading, so a host writing faster than its
#: baud rate blocks as on a real serial port. It is a real serial driver's transmit buffer (one
#: page), so a host's single write of any frame or command batch is taken whole at once: the largest
#: is an MP-285 program download of 99 vectors, 1588 bytes. 4 KiB is 4.3 s of wire at 9600 8N1.
INPUT_BACKLOG = 4096
#: Device output not yet through its wire time, per port, in bytes: at this backlog the port stops
#: reading too (the device is busy sending), so a host sending commands faster than their replies
#: can go out does not queue replies without limit.
OUTPUT_BACKLOG = 4096


@dataclass
class Faults:
    """Injected port faults (control channel `fault`; emulator/hosting/port_faults.py injects and expires
    them)."""

    hung: bool = False
    drop_replies: int = 0
    corrupt_bytes: int = 0
    latency_s: float = 0.0
    vanished: bool = False

    def describe(self) -> dict[str, Any]:
        return {
            "hung": self.hung,
            "drop_replies": self.drop_replies,
            "corrupt_bytes": self.corrupt_bytes,
            "latency_ms": self.latency_s * 1000,
            "disconnected": self.vanished,
        }


@dataclass
class PortStats:
    """What one port lost because its host did not keep up (counted since the daemon started)."""

    #: device output the host's full receive buffer could not take (an overrun)
    output_dropped: int = 0
    #: host input discarded before the device received it: left in the port, or still on the
    #: emulated wire, when the host hung up
    input_discarded: int = 0
    #: output is being dropped now (the warning is logged once, when this starts)
    dropping: bool = False

    def describe(self) -> dict[str, Any]:
        return {"output_dropped": self.output_dropped, "input_discarded": self.input_discarded}


@dataclass
class Port:
    """One port of the device: its transport, host state, pacing in both directions and faults."""

    name: str
    timing: str = REALISTIC
    transport: Transport | None = None
    attached: bool = False
    host: HostLine | None = None
    to_host: Pacer = field(default_factory=Pacer)
    from_host: Pacer = field(default_factory=Pacer)
    faults: Faults = field(default_factory=Faults)
    stats: PortStats = field(default_factory=PortStats)
    #: the line mismatch last warned about, and one not yet warned about because no byte has
    #: crossed the line since the settings began to differ (emulator/hosting/mismatch.py)
    reported_mismatch: tuple[Any, ...] = ()
    pending_mismatch: tuple[Any, ...] = ()
    #: what the pacing was last computed from (paced, device settings, host settings; pacing.py)
    paced_for: tuple[Any, ...] = ()
    #: the (host, device) settings last checked for a mismatch
    checked_for: tuple[Any, ...] = ()
    #: the port was told it had no room (`room`) and has stopped reading
    throttled: bool = False
    #: the runner's direct step may take this port's bytes: unpaced, no traffic records, no hang
    #: (`DeviceRunner.host_data`; recomputed whenever one of those changes)
    express: bool = False

    def room(self) -> int:
        """Host bytes the port may take now (`PortSink.room`): 0 while either direction is backed
        up, and then the port stops reading until `resume_reading` says so."""
        room = 0 if len(self.to_host) >= OUTPUT_BACKLOG else max(INPUT_BACKLOG - len(self.from_host), 0)
        if room == 0:
            self.throttled = True
        return room


def resume_reading(channels: dict[str, Port]) -> None:
    """Let ports read again once their backlogs are down to half (not at every byte: a port then
    reads in batches, not one syscall per character). Only a port told there was no room has
    stopped (emulator/hosting/transports/base.py)."""
    for ch in channels.values():
        if (
            ch.throttled
            and ch.transport is not None
            and len(ch.from_host) <= INPUT_BACKLOG // 2
            and len(ch.to_host) <= OUTPUT_BACKLOG // 2
        ):
            ch.throttled = False
            ch.transport.resume_reading()


def count_drops(ch: Port, device: str, dropped: int) -> None:
    """After a write to the port: `dropped` bytes of it the host's buffer did not take. Logged once
    per episode of dropping, and once more when the host takes output again."""
    stats = ch.stats
    if dropped:
        stats.output_dropped += dropped
        if not stats.dropping:
            stats.dropping = True
            log.warning(
                "%s/%s: host is not reading; output that does not fit its buffer is dropped "
                "(%d bytes dropped on this port so far)",
                device,
                ch.name,
                stats.output_dropped,
            )
    elif stats.dropping:
        stats.dropping = False
        log.info("%s/%s: host takes output again", device, ch.name)
