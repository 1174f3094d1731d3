"""Hosts one sans-I/O device model: feeds it paced host bytes, runs its timers on the clock, paces its
output onto its ports, applies injected faults, logs traffic and line mismatches.

With a traffic log, or a control-channel traffic subscriber (`watch_traffic`), the runner sets the
model's `explain` and records what the model reports: its notes on received bytes, each emission's
summary when its last byte leaves the port, and (for the log) its pushed events, `move` records and
the other `LOG_ONLY` ones among them (a model builds them only while explaining; they are not
published). It adds what it drops itself (emulator/trafficlog.py has the record format).

The runner is transport-agnostic and clock-agnostic. With a real or scaled clock and an asyncio loop
it arms one timer for the next thing due (no polling); with a manual clock it runs whenever the test
moves the clock.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from functools import partial
from typing import Any

from emulator import mismatch
from emulator.clock import Clock
from emulator.device import GARBLED, Device, Emission, HostLine, LineSettings, ModemLines, RxNote
from emulator.lag import DeviceTime, WorkBudget
from emulator.line import REALISTIC, settings_char_time
from emulator.line_errors import UNSEEN_HOST, LineErrors
from emulator.port import CORRUPT_MASK, Channel, Faults, fault_params, unsent
from emulator.trafficlog import LOG_ONLY, DeviceTraffic, TrafficLog
from emulator.transports.base import Transport
from emulator.walltimer import LOOP_TIMER_EARLY_S, WallTimer, make_timer

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
#: Paced output is released up to this much wall time before its instant when the runner has no
#: timer of its own (in-process hosting pumps on the host's reads): as with the loop's millisecond
#: timers (emulator/walltimer.py), half a millisecond early centres each byte on its instant.
RELEASE_EARLY_S = LOOP_TIMER_EARLY_S


class _ChannelSink:
    """Transport callbacks bound to the runner for one channel (partials: a port's every read and
    every byte of input pass here, and a bound C-level call costs no Python frame)."""

    def __init__(self, runner: DeviceRunner, channel: Channel) -> None:
        self.host_attached: Callable[[HostLine | None], None] = partial(runner.host_attached, channel)
        self.host_detached: Callable[[], None] = partial(runner.host_detached, channel)
        self.host_line: Callable[[HostLine], None] = partial(runner.host_line, channel)
        self.host_data: Callable[[bytes], None] = partial(runner.host_data, channel)
        self.room: Callable[[], int] = partial(runner.input_room, channel)
        self.input_discarded: Callable[[int], None] = partial(runner.input_discarded, channel)
        self.line_error: Callable[[int, str], None] = partial(runner.host_line_error, channel)
        # the runner's current model: a factory reset replaces it
        self.device_line: Callable[[], LineSettings] = lambda: runner.device.line_settings(channel.name)
        self.modem_lines: Callable[[], ModemLines] = lambda: runner.device.modem_lines(channel.name)


class DeviceRunner:
    def __init__(
        self,
        make_device: Callable[[float], Device],
        clock: Clock,
        *,
        loop: asyncio.AbstractEventLoop | None = None,
        traffic: TrafficLog | None = None,
        on_event: Callable[[str, dict[str, Any]], None] | None = None,
        budget: WorkBudget | None = None,
    ) -> None:
        self._make_device = make_device
        self.device = make_device(clock.now())
        #: the device's own clock and the work budget of a step (lag.py)
        self.device_time = DeviceTime(self.device.name, clock, budget)
        #: the device's own time: `clock`, or behind it once the device could not keep up (lag.py)
        self.clock = self.device_time.clock
        self.lag = self.device_time.lag
        self.device.explain = traffic is not None
        self._traffic = None if traffic is None else DeviceTraffic(traffic, self.device.name)
        self.channels: dict[str, Channel] = {name: Channel(name) for name in self.device.channels}
        self._loop = loop
        self._on_event = on_event
        self.device_timer: WallTimer | None = None if loop is None else make_timer(loop, self._on_timer)
        #: wall seconds output may leave early, given how late the timer wakes
        self._early = RELEASE_EARLY_S if self.device_timer is None else self.device_timer.early
        #: the device time the timer is armed for (None: not armed)
        self.device_timer_due: float | None = None
        self._actions: list[tuple[float, Callable[[], None]]] = []
        #: per channel, the characters with line errors among its queued input (a serial port's)
        self._line_errors: dict[str, LineErrors] = {}
        clock.on_change(self._on_clock_change)

    def _on_clock_change(self) -> None:
        self.device_timer_due = None  # the same device time is now another wall delay: re-arm
        self.pump()

    @property
    def name(self) -> str:
        return self.device.name

    # ---- wiring -------------------------------------------------------------------------------

    def attach_transport(self, channel: str, transport: Transport, timing: str = REALISTIC) -> None:
        if channel not in self.channels:
            known = ", ".join(self.channels)
            raise ValueError(f"{self.name}: no channel {channel!r} (this device has: {known})")
        ch = self.channels[channel]
        if ch.transport is not None:
            raise ValueError(f"{self.name}: channel {channel!r} already has a port")
        ch.transport = transport
        ch.timing = timing
        self._refresh_pacing()  # before any step: `host_data` relies on it
        transport.open(_ChannelSink(self, ch))

    def watch_traffic(self, sink: Callable[[dict[str, Any]], None] | None) -> None:
        """Hand each traffic record (as the log writes it) to `sink` as well; None stops that. The
        model explains while a log or a sink takes the records, and formats nothing otherwise."""
        traffic = self._traffic
        if traffic is None and sink is not None:
            on_wire = {ch.name: len(ch.to_host) for ch in self.channels.values()}
            traffic = self._traffic = DeviceTraffic(None, self.device.name, on_wire)
        if traffic is not None:
            traffic.sink = sink
            if sink is None and not traffic.logs:
                self._traffic = None
        self.device.explain = self._traffic is not None

    def close(self) -> None:
        self.device.shut_down(self.pump())
        if self.device_timer is not None:
            self.device_timer.close()
        for ch in self.channels.values():
            if ch.transport is not None:
                ch.transport.close()

    # ---- transport events ---------------------------------------------------------------------

    def host_attached(self, ch: Channel, host: HostLine | None) -> None:
        ch.attached = True
        self._clear_wire(ch, "a new host attached")
        log.info("%s/%s: host attached", self.name, ch.name)
        self._set_host(ch, host)

    def host_detached(self, ch: Channel) -> None:
        ch.attached = False
        unheard = len(ch.from_host)
        ch.stats.input_discarded += unheard
        ch.stats.dropping = False
        self._clear_wire(ch, "the host hung up")
        mismatch.forget(ch)
        lost = f"; {unheard} bytes still on the wire discarded" if unheard else ""
        log.info("%s/%s: host detached%s", self.name, ch.name, lost)
        self._set_host(ch, None)

    def host_line(self, ch: Channel, host: HostLine) -> None:
        self._set_host(ch, host)

    def _set_host(self, ch: Channel, host: HostLine | None) -> None:
        now = self.device_time.run(self.device, self.clock.shared.now(), None)
        ch.host = host
        self.device.line_changed(host, now, ch.name)
        self.pump()

    def host_data(self, ch: Channel, data: bytes) -> None:
        # logged by the model once received (or by `_due_input` if a hung device hears nothing)
        now = self.clock.now()
        if ch.pending_mismatch:
            mismatch.report(ch, self.device)
        if (
            ch.from_host.per_char == 0
            and not ch.from_host
            and self._traffic is None
            and not ch.faults.hung
            and not (self._actions and self._actions[0][0] <= now)
            and not self.clock.behind
            and (self.device_timer_due is None or self.device_timer_due > now)
        ):
            # What `pump` would do with these bytes, without their round through the input pacer
            # and the step's checks before the model: unpaced (pacing is current, every step ends
            # by updating it), with nothing queued ahead of them, nothing to log, no fault expiry
            # and nothing the timer waits for overdue (a backlog is worked off in budgeted steps),
            # they reach the device at once (the common case with fast timing).
            self.device.receive(data, now, ch.name)
            self._finish_step(now)
            return
        ch.from_host.push(now, data)  # even when hung: the bytes take their wire time
        self.pump()

    def host_line_error(self, ch: Channel, byte: int, kind: str) -> None:
        """A character the port's UART received with a line error, after the bytes handed over so
        far: it takes its wire time and its place in the input like any byte (emulator/line_errors.py)."""
        self._line_errors.setdefault(ch.name, LineErrors()).add(len(ch.from_host), kind)
        ch.from_host.push(self.clock.now(), bytes((byte,)))
        self.pump()

    def input_discarded(self, ch: Channel, count: int) -> None:
        """The transport discarded input it had not handed over (the host hung up)."""
        ch.stats.input_discarded += count
        if self._traffic is not None:
            why = f"the host hung up: {count} bytes left in the port discarded"
            self._traffic.lost_rx(self.clock.now(), ch.name, b"", why)
            self._traffic.flush()

    def _clear_wire(self, ch: Channel, why: str, to_host_only: bool = False) -> None:
        """Forget what is on the wire in both directions (or only the device's output)."""
        traffic = self._traffic
        if traffic is not None:
            now = self.clock.now()
            traffic.discard(now, ch.name, f"not sent: {why}")
            if not to_host_only:
                unheard = b"".join(data for _, data in ch.from_host.take_due(ch.from_host.wire_free))
                if unheard:
                    traffic.lost_rx(now, ch.name, unheard, f"still on the wire when {why}")
            traffic.flush()
        ch.to_host.clear()
        if not to_host_only:
            ch.from_host.clear()
            self._line_errors.pop(ch.name, None)

    def input_room(self, ch: Channel) -> int:
        """Host bytes `ch` may take now (PortSink.room): 0 while either direction is backed up, and
        then the port stops reading until `_resume_reading` says so."""
        room = 0 if len(ch.to_host) >= OUTPUT_BACKLOG else max(INPUT_BACKLOG - len(ch.from_host), 0)
        if room == 0:
            ch.throttled = True
        return room

    # ---- the step -----------------------------------------------------------------------------

    def call(self, action: Callable[[float], Any]) -> Any:
        """Run `action(now)` on the device at the current device time, then let its effects flow."""
        now = self.pump()
        result = action(now)
        self.pump(at_least=now)
        return result

    def pump(self, at_least: float | None = None) -> float:
        """Bring the device and the ports up to the current device time, then re-arm the timer.
        Returns the device time it brought them to: the clock's, unless the device fell behind it."""
        now = self.clock.shared.now()  # a device behind the clock works towards it
        if at_least is not None and at_least > now:
            now = at_least
        if self._actions:
            self._run_actions(now)
        self._refresh_pacing()  # a host's or a reset's new settings pace what this step sends
        now = self.device_time.run(self.device, now, self._deliver_input)
        self._finish_step(now)
        return now

    def _deliver_input(self, now: float) -> None:
        """Hand the device the host bytes due by `now`."""
        for t, channel, data, error in self._due_input(now):
            if error is None:
                self.device.receive(data, t, channel)
            else:
                self._receive_line_error(t, channel, data[0], error)

    def _receive_line_error(self, t: float, channel: str, byte: int, kind: str) -> None:
        if self._traffic is not None:
            note = f"garbled: the UART received {byte:02X} with a {kind} error ({UNSEEN_HOST})"
            self._traffic.rx(RxNote(t, GARBLED, bytes((byte,)), note, channel))
        self.device.receive_line_error(byte, kind, t, channel)

    def _finish_step(self, now: float) -> None:
        """The rest of a step once the device has its input: it runs to `now`, what is due leaves,
        and the runner's state follows what the step changed (pacing, mismatches, reading, the
        timer)."""
        self.device.advance(now)
        early = self.clock.device_span(self._early)
        self._collect_output(now + early)
        self._write_due(now + early)
        # what follows the write is off the round trip's path: the host is reading the reply by now
        if self._traffic is not None:
            self._traffic.flush()
        self._refresh_pacing()  # the model's own changes pace the next step
        self._check_mismatch()
        self._resume_reading()
        self._arm_timer(early)

    def _due_input(self, now: float) -> list[tuple[float, str, bytes, str | None]]:
        """Host bytes whose wire time has ended, merged across channels in time order; bytes that
        complete at the same instant (fast timing) stay together. A character received with a line
        error comes alone, with its kind."""
        due: list[tuple[float, str, bytes, str | None]] = []
        for ch in self.channels.values():
            if ch.from_host.per_char > 0:
                arrived = [(t, bytes([b])) for t, b in ch.from_host.take_each_due(now)]
            else:
                arrived = ch.from_host.take_due(now)
            if not arrived:
                continue
            errors = self._line_errors.get(ch.name)
            if ch.faults.hung:  # a hung device hears nothing that arrives
                if errors:
                    for _, data in arrived:
                        errors.split(data)  # their marks go with them
                if self._traffic is not None:
                    data = b"".join(data for _, data in arrived)
                    self._traffic.lost_rx(
                        arrived[-1][0], ch.name, data, "hang fault: the device hears nothing"
                    )
                continue
            if errors:
                due += [
                    (t, ch.name, piece, kind) for t, data in arrived for piece, kind in errors.split(data)
                ]
            else:
                for t, data in arrived:
                    due.append((t, ch.name, data, None))
        if len(self.channels) > 1:
            due.sort(key=lambda item: item[0])
        return due

    def _refresh_pacing(self) -> None:
        """Character times from the current settings; recomputed only when one of them changed."""
        for ch in self.channels.values():
            paced_by_wire = ch.transport is not None and ch.transport.wire_paces
            realistic = ch.timing == REALISTIC and self.device.pace_line and not paced_by_wire
            own = self.device.line_settings(ch.name)
            key = (realistic, own, ch.host)
            if key == ch.paced_for:
                continue
            if ch.paced_for and ch.paced_for[1] != own and ch.transport is not None:
                ch.transport.device_line_changed()  # a serial port follows the device's settings
            ch.paced_for = key
            ch.to_host.per_char = settings_char_time(own, own) if realistic else 0.0
            host = ch.host or own
            ch.from_host.per_char = settings_char_time(host, own) if realistic else 0.0

    def _collect_output(self, release: float) -> None:
        if self._traffic is not None:
            for note in self.device.take_rx_notes():
                self._traffic.rx(note)
        emissions = self.device.take_output()
        if len(emissions) > 1:
            emissions.sort(key=lambda e: e.due)
        for emission in emissions:
            self._route(emission, release)
        events = self.device.take_events()
        if events:
            if self._traffic is not None:
                self._traffic.events(self.device.now, events)
            if self._on_event is not None:
                for event in events:
                    if event["ev"] not in LOG_ONLY:  # subscribers see the same with or without a log
                        self._on_event(self.name, event)

    def _route(self, emission: Emission, release: float) -> None:
        """Apply the port's faults to an emission and put it on the port's wire; bytes released by
        `release` with nothing ahead of them and nothing to pace go out at once."""
        ch = self.channels.get(emission.channel)
        if ch is None:
            return
        why = unsent(ch)
        if why is not None:  # no output while detached: a real UART would send into the void
            if self._traffic is not None:
                self._traffic.lost_tx(emission.due, emission, f"not sent: {why}")
            return
        if ch.faults.drop_replies > 0:
            ch.faults.drop_replies -= 1
            if self._traffic is not None:
                self._traffic.lost_tx(emission.due, emission, "not sent: drop fault")
            return
        data = emission.data
        count = 0
        if ch.faults.corrupt_bytes > 0:
            count = min(ch.faults.corrupt_bytes, len(data))
            data = bytes(b ^ CORRUPT_MASK for b in data[:count]) + data[count:]
            ch.faults.corrupt_bytes -= count
        due = emission.due + ch.faults.latency_s
        if self._traffic is None and ch.to_host.per_char == 0 and due <= release and not ch.to_host:
            # what `_write_due` would send in this very pump, without a round through the pacer
            self._send(ch, data)
            return
        ch.to_host.push(due, data)
        if self._traffic is not None:
            self._traffic.queued(emission, data, count)

    def _write_due(self, now: float) -> None:
        for ch in self.channels.values():
            for t, data in ch.to_host.take_due(now):
                dropped = self._send(ch, data)
                if self._traffic is not None:
                    self._traffic.left(t, ch.name, len(data), dropped)

    def _send(self, ch: Channel, data: bytes) -> int:
        """Hand bytes whose wire time is over to the port; returns how many of them were dropped."""
        if ch.transport is None or not ch.attached:
            return len(data)
        dropped = ch.transport.write(data)
        if ch.pending_mismatch:
            mismatch.report(ch, self.device)
        if dropped:
            self._output_dropped(ch, dropped)
        elif ch.stats.dropping:
            ch.stats.dropping = False
            log.info("%s/%s: host takes output again", self.name, ch.name)
        return dropped

    def _output_dropped(self, ch: Channel, count: int) -> None:
        ch.stats.output_dropped += count
        if not ch.stats.dropping:
            ch.stats.dropping = True
            log.warning(
                "%s/%s: host is not reading; output that does not fit its buffer is dropped "
                "(%d bytes dropped on this port so far)",
                self.name,
                ch.name,
                ch.stats.output_dropped,
            )

    def _resume_reading(self) -> None:
        """Let ports read again once their backlogs are down to half (not at every byte: a port
        then reads in batches, not one syscall per character). Only a port told there was no room
        has stopped (emulator/transports/base.py)."""
        for ch in self.channels.values():
            if (
                ch.throttled
                and ch.transport is not None
                and len(ch.from_host) <= INPUT_BACKLOG // 2
                and len(ch.to_host) <= OUTPUT_BACKLOG // 2
            ):
                ch.throttled = False
                ch.transport.resume_reading()

    def _check_mismatch(self) -> None:
        for ch in self.channels.values():
            mismatch.check(ch, self.device.line_settings(ch.name))

    def _next_due(self, early: float) -> float | None:
        """The earliest of: the device's next event, a port's next paced byte (output released
        `early`), the next fault expiry."""
        due = self.device.next_deadline()
        if self._actions and (due is None or self._actions[0][0] < due):
            due = self._actions[0][0]
        for ch in self.channels.values():
            out = ch.to_host.next_due()
            if out is not None and (due is None or out - early < due):
                due = out - early
            into = ch.from_host.next_due()
            if into is not None and (due is None or into < due):
                due = into
        return due

    def next_due(self) -> float | None:
        """The device instant the runner next has something to do (None: nothing is scheduled), for
        a host that pumps it itself instead of giving it a loop."""
        return self._next_due(self.clock.device_span(self._early))

    def wall_until_due(self) -> float | None:
        """Wall seconds until `next_due` (None: nothing is scheduled, or time stands still)."""
        due = self.next_due()
        return None if due is None else self.clock.wall_delay(due)

    def _arm_timer(self, early: float | None = None) -> None:
        timer = self.device_timer
        if timer is None:
            return
        if early is None:
            early = self.clock.device_span(self._early)
        if self.clock.behind:  # a device behind the clock works on at the loop's next turn
            self.device_timer_due = None
            timer.arm(0.0)
            return
        due = self._next_due(early)
        if due == self.device_timer_due:
            return
        delay = None if due is None else self.clock.wall_delay(due)
        if delay is None:  # nothing due, or time stands still
            self.device_timer_due = None
            timer.cancel()
        else:
            self.device_timer_due = due
            timer.arm(delay)

    def _on_timer(self) -> None:
        due, self.device_timer_due = self.device_timer_due, None
        self.pump(at_least=due)

    # ---- control operations -------------------------------------------------------------------

    def reset(self) -> None:
        """Factory reset: a fresh model from the profile, still attached to the same hosts."""
        now = self.clock.now()
        self.device.forget_nonvolatile()
        self.device = self._make_device(now)
        self.device.explain = self._traffic is not None
        for ch in self.channels.values():
            self._clear_wire(ch, "a factory reset")
            mismatch.forget(ch)
            if ch.attached:
                self.device.line_changed(ch.host, now, ch.name)
        self.pump()

    def inject(self, channel: str, fault: str, params: dict[str, Any]) -> dict[str, Any]:
        """Apply a port fault; returns the channel's fault state. Raises ValueError for bad input."""
        ch = self.channels.get(channel)
        if ch is None:
            raise ValueError(
                f"{self.name}: no port {channel!r} (this device has: {', '.join(self.channels)})"
            )
        values = fault_params(fault, params)
        seconds = values.get("seconds")
        if fault == "disconnect":
            self._disconnect(ch, seconds)
        elif fault == "hang":
            ch.faults.hung = True
            self._clear_wire(ch, "hang fault", to_host_only=True)
            if seconds is not None:
                self.after(seconds, lambda: setattr(ch.faults, "hung", False))
        elif fault == "drop":
            ch.faults.drop_replies += int(values.get("count", 1))
        elif fault == "corrupt":
            ch.faults.corrupt_bytes += int(values.get("count", 1))
        elif fault == "latency":
            if "ms" not in values:
                raise ValueError("latency needs ms=M, the delay added to every reply (0 to 60000 ms)")
            ch.faults.latency_s = values["ms"] / 1000
        else:  # clear
            if ch.faults.vanished and ch.transport is not None:
                ch.transport.reappear()
            ch.faults = Faults()
        self.pump()
        return ch.faults.describe()

    def _disconnect(self, ch: Channel, seconds: float | None) -> None:
        if ch.transport is None or ch.faults.vanished:
            return
        ch.faults.vanished = True
        ch.transport.vanish()
        if ch.attached:
            self.host_detached(ch)

        def back() -> None:
            if ch.faults.vanished and ch.transport is not None:
                ch.faults.vanished = False
                ch.transport.reappear()

        if seconds is not None:
            self.after(seconds, back)

    # ---- device-time actions (fault expiry) ---------------------------------------------------

    def after(self, seconds: float, action: Callable[[], None]) -> None:
        self._actions.append((self.clock.now() + seconds, action))
        self._actions.sort(key=lambda item: item[0])
        self._arm_timer()

    def _run_actions(self, now: float) -> None:
        while self._actions and self._actions[0][0] <= now:
            _, action = self._actions.pop(0)
            action()
