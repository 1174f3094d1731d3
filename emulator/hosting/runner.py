"""Hosts one sans-I/O device model: feeds it the host's bytes, runs its timers on the clock and puts
its output on its ports. This file is the step and the timer; the other jobs are parts of their own,
each with its contract at the top: pacing.py (the pacers and the line settings of both ends),
port_faults.py (injected faults and their expiry), explain.py (traffic explanation), port.py (a
port's state and flow control), mismatch.py (line mismatches) and lag.py (the device's own clock
and the work budget of a step).

A step (`pump`) runs the fault expiries due, hands the model the input due and brings it to the
device time, routes its output through the port's faults onto the pacers, writes what is due, then
follows what the step changed (settings, backlogs) and plans the timer. The direct step
(`host_data`) is that step with nothing to do but hand the bytes over, taken when the port's
`express` flag holds (recomputed when its pacing, the traffic tap or its hang fault change), nothing
is queued ahead of the bytes, and it is before `_quiet_until`, the instant the runner next has a
job of its own (recomputed whenever the timer is planned).

Transport- and clock-agnostic: with a real or scaled clock and an asyncio loop it arms one timer for
the next thing due (no polling); with a manual clock it runs whenever the test moves the clock.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import Callable
from functools import partial
from typing import Any

from emulator.device import Device, Emission, HostLine, LineSettings, ModemLines
from emulator.hosting import mismatch
from emulator.hosting.clock import Clock
from emulator.hosting.explain import Explainer, watch
from emulator.hosting.lag import DeviceTime, WorkBudget
from emulator.hosting.pacing import Pacing
from emulator.hosting.port import Port, count_drops, resume_reading
from emulator.hosting.port_faults import PortFaults, outgoing
from emulator.hosting.trafficlog import LOG_ONLY, TrafficLog
from emulator.hosting.transports.base import Transport
from emulator.hosting.walltimer import LOOP_TIMER_EARLY_S, WallTimer, make_timer
from emulator.wire_time import REALISTIC

log = logging.getLogger("stage_emu.runner")

#: Paced output is released up to this much wall time before its instant when the runner has no
#: timer of its own (in-process hosting pumps on the host's reads): as with the loop's millisecond
#: timers (emulator/hosting/walltimer.py), half a millisecond early centres each byte on its instant.
RELEASE_EARLY_S = LOOP_TIMER_EARLY_S


class _PortSink:
    """Transport callbacks bound to the runner for one port (partials: a port's every read and
    every byte of input pass here, and a bound C-level call costs no Python frame)."""

    def __init__(self, runner: DeviceRunner, channel: Port) -> None:
        self.host_attached: Callable[[HostLine | None], None] = partial(runner.host_attached, channel)
        self.host_detached: Callable[[], None] = partial(runner.host_detached, channel)
        self.host_line: Callable[[HostLine], None] = partial(runner.host_line, channel)
        self.host_data: Callable[[bytes], None] = partial(runner.host_data, channel)
        self.room: Callable[[], int] = channel.room
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
        #: the traffic records while someone takes them (explain.py), else None
        self._tap = None if traffic is None else Explainer(traffic, self.device.name)
        self.device.explain = self._tap is not None
        self.channels: dict[str, Port] = {name: Port(name) for name in self.device.channels}
        self._pacing = Pacing(self.channels)
        self._faults = PortFaults(self.clock, self._clear_wire, self.host_detached, self._recheck_express)
        self._on_event = on_event
        self.device_timer: WallTimer | None = None if loop is None else make_timer(loop, self._on_timer)
        #: wall seconds output may leave early, given how late the timer wakes, and that span in
        #: device seconds (it changes only with the clock's scale)
        self._early = RELEASE_EARLY_S if self.device_timer is None else self.device_timer.early
        self._early_span = self.clock.device_span(self._early)
        #: the device time the timer is armed for (None: not armed)
        self.device_timer_due: float | None = None
        #: before this device time the runner has nothing due of its own (no fault expiry, no timer
        #: due, not behind the clock): host bytes may take the direct step
        self._quiet_until = math.inf
        #: a host's settings, the model or a port changed since the last step (pacing follows first)
        self._stale = True
        clock.on_change(self._on_clock_change)

    def _on_clock_change(self) -> None:
        self.device_timer_due = None  # the same device time is now another wall delay: re-arm
        self._early_span = self.clock.device_span(self._early)
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
        self._follow_settings()  # before any step: `host_data` relies on it
        transport.open(_PortSink(self, ch))

    def watch_traffic(self, sink: Callable[[dict[str, Any]], None] | None) -> None:
        """Hand each traffic record (as the log writes it) to `sink` as well; None stops that. The
        model explains while a log or a sink takes the records, and formats nothing otherwise."""
        channels = self.channels.values()
        self._tap = watch(self._tap, self.name, sink, lambda: {ch.name: len(ch.to_host) for ch in channels})
        self.device.explain = self._tap is not None
        self._recheck_express()

    def close(self) -> None:
        self.device.shut_down(self.pump())
        if self.device_timer is not None:
            self.device_timer.close()
        for ch in self.channels.values():
            if ch.transport is not None:
                ch.transport.close()

    # ---- transport events ---------------------------------------------------------------------

    def host_attached(self, ch: Port, host: HostLine | None) -> None:
        ch.attached = True
        self._clear_wire(ch, "a new host attached")
        log.info("%s/%s: host attached", self.name, ch.name)
        self.host_line(ch, host)

    def host_detached(self, ch: Port) -> None:
        ch.attached = False
        unheard = len(ch.from_host)
        ch.stats.input_discarded += unheard
        ch.stats.dropping = False
        self._clear_wire(ch, "the host hung up")
        mismatch.forget(ch)
        lost = f"; {unheard} bytes still on the wire discarded" if unheard else ""
        log.info("%s/%s: host detached%s", self.name, ch.name, lost)
        self.host_line(ch, None)

    def host_line(self, ch: Port, host: HostLine | None) -> None:
        """The host's settings as the port sees them (None: no host)."""
        now = self.device_time.run(self.device, self.clock.shared.now(), None)
        ch.host = host
        self._stale = True
        self.device.line_changed(host, now, ch.name)
        self.pump()

    def host_data(self, ch: Port, data: bytes) -> None:
        # logged by the model once received (or by pacing.py if a hung device hears nothing)
        now = self.clock.now()
        if ch.pending_mismatch:
            mismatch.report(ch, self.device)
        if ch.express and now < self._quiet_until and not ch.from_host:
            # the step with nothing to do but hand the bytes over (see the module's docstring)
            self.device.receive(data, now, ch.name)
            self._finish_step(now)
            return
        ch.from_host.push(now, data)  # even when hung: the bytes take their wire time
        self.pump()

    def host_line_error(self, ch: Port, byte: int, kind: str) -> None:
        """A character the port's UART received with a line error, after the bytes handed over so
        far (emulator/hosting/line_errors.py)."""
        self._pacing.line_error(ch, byte, kind, self.clock.now())
        self.pump()

    def input_discarded(self, ch: Port, count: int) -> None:
        """The transport discarded input it had not handed over (the host hung up)."""
        ch.stats.input_discarded += count
        if self._tap is not None:
            self._tap.hung_up(self.clock.now(), ch.name, count)

    def _clear_wire(self, ch: Port, why: str, to_host_only: bool = False) -> None:
        """Forget what is on the wire in both directions (or only the device's output)."""
        if self._tap is not None:
            self._tap.cleared(self.clock.now(), ch, why, not to_host_only)
        ch.to_host.clear()
        if not to_host_only:
            self._pacing.clear(ch)

    # ---- the step -----------------------------------------------------------------------------

    def call(self, action: Callable[[float], Any]) -> Any:
        """Run `action(now)` on the device at the current device time, then let its effects flow."""
        now = self.pump()
        self._stale = True  # the action may change the device's settings (even if it then fails)
        result = action(now)
        self.pump(at_least=now)
        return result

    def pump(self, at_least: float | None = None) -> float:
        """Bring the device and the ports up to the current device time, then re-arm the timer.
        Returns the device time it brought them to: the clock's, unless the device fell behind it."""
        now = self.clock.shared.now()  # a device behind the clock works towards it
        if at_least is not None and at_least > now:
            now = at_least
        if self._faults.due <= now:
            self._faults.run_due(now)
        if self._stale:  # a host's or a reset's new settings pace what this step sends
            self._follow_settings()
        now = self.device_time.run(self.device, now, self._deliver_input)
        self._finish_step(now)
        return now

    def _deliver_input(self, now: float) -> None:
        """Hand the device the host bytes due by `now`."""
        for t, channel, data, error in self._pacing.due_input(now, self._tap):
            if error is None:
                self.device.receive(data, t, channel)
            else:
                if self._tap is not None:
                    self._tap.line_error(t, channel, data[0], error)
                self.device.receive_line_error(data[0], error, t, channel)

    def _finish_step(self, now: float) -> None:
        """The rest of a step once the device has its input: it runs to `now`, what is due leaves,
        and the runner follows what the step changed (pacing, mismatches, reading, the timer)."""
        self.device.advance(now)
        release = now + self._early_span
        self._collect_output(release)
        self._write_due(release)
        # what follows the write is off the round trip's path: the host is reading the reply by now
        if self._tap is not None:
            self._tap.flush()
        if self._pacing.follow(self.device):  # the model's own changes pace the next step
            self._recheck_express()
        resume_reading(self.channels)
        self._arm_timer()

    def _follow_settings(self) -> None:
        """Pacing follows a change made between steps (no mismatch check: that follows the step)."""
        self._stale = False
        if self._pacing.follow(self.device, check=False):
            self._recheck_express()

    def _recheck_express(self) -> None:
        """Which ports the direct step may take: after a change of pacing, traffic tap or faults."""
        explaining = self._tap is not None
        for ch in self.channels.values():
            ch.express = not (ch.to_host.per_char > 0 or explaining or ch.faults.hung)

    def _collect_output(self, release: float) -> None:
        tap = self._tap
        if tap is not None:
            tap.take_notes(self.device)
        emissions = self.device.take_output()
        if len(emissions) > 1:
            emissions.sort(key=lambda e: e.due)
        for emission in emissions:
            self._route(emission, release)
        events = self.device.take_events()
        if events:
            if tap is not None:
                tap.events(self.device.now, events)
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
        out = outgoing(ch, emission, self._tap)
        if out is None:
            return
        data, due, count = out
        if ch.express and due <= release and not ch.to_host:
            # what `_write_due` would send in this very step, without a round through the pacer
            self._send(ch, data)
            return
        ch.to_host.push(due, data)
        if self._tap is not None:
            self._tap.queued(emission, data, count)

    def _write_due(self, now: float) -> None:
        for ch in self.channels.values():
            for t, data in ch.to_host.take_due(now):
                dropped = self._send(ch, data)
                if self._tap is not None:
                    self._tap.left(t, ch.name, len(data), dropped)

    def _send(self, ch: Port, data: bytes) -> int:
        """Hand bytes whose wire time is over to the port; returns how many of them were dropped."""
        if ch.transport is None or not ch.attached:
            return len(data)
        dropped = ch.transport.write(data)
        if ch.pending_mismatch:
            mismatch.report(ch, self.device)
        if dropped or ch.stats.dropping:
            count_drops(ch, self.name, dropped)
        return dropped

    # ---- the timer ----------------------------------------------------------------------------

    def next_due(self) -> float | None:
        """The device instant the runner next has something to do (None: nothing is scheduled): the
        device's next event, a port's next paced byte (output released early), the next fault
        expiry. The timer is armed for it; a host without a loop pumps the runner then itself."""
        due = self.device.next_deadline()
        expiry = self._faults.due
        if expiry < math.inf and (due is None or expiry < due):
            due = expiry
        early = self._early_span
        for ch in self.channels.values():
            out = ch.to_host.next_due()
            if out is not None and (due is None or out - early < due):
                due = out - early
            into = ch.from_host.next_due()
            if into is not None and (due is None or into < due):
                due = into
        return due

    def wall_until_due(self) -> float | None:
        """Wall seconds until `next_due` (None: nothing is scheduled, or time stands still)."""
        due = self.next_due()
        return None if due is None else self.clock.wall_delay(due)

    def _arm_timer(self) -> None:
        """Plan the timer for the next thing due, and with it the direct step's `_quiet_until`."""
        timer = self.device_timer
        if self.clock.behind:
            self._quiet_until = -math.inf
            if timer is not None:  # a device behind the clock works on at the loop's next turn
                self.device_timer_due = None
                timer.arm(0.0)
            return
        if timer is not None and (due := self.next_due()) != self.device_timer_due:
            delay = None if due is None else self.clock.wall_delay(due)
            self.device_timer_due = None if delay is None else due
            if delay is None:  # nothing due, or time stands still
                timer.cancel()
            else:
                timer.arm(delay)
        expiry, armed = self._faults.due, self.device_timer_due
        self._quiet_until = expiry if armed is None or expiry < armed else armed

    def _on_timer(self) -> None:
        due, self.device_timer_due = self.device_timer_due, None
        self.pump(at_least=due)

    # ---- control operations -------------------------------------------------------------------

    def reset(self) -> None:
        """Factory reset: a fresh model from the profile, still attached to the same hosts."""
        now = self.clock.now()
        self.device.forget_nonvolatile()
        self.device = self._make_device(now)
        self.device.explain = self._tap is not None
        for ch in self.channels.values():
            self._clear_wire(ch, "a factory reset")
            mismatch.forget(ch)
            if ch.attached:
                self.device.line_changed(ch.host, now, ch.name)
        self._stale = True
        self.pump()

    def inject(self, channel: str, fault: str, params: dict[str, Any]) -> dict[str, Any]:
        """Apply a port fault (port_faults.py); returns the channel's fault state. Raises ValueError
        for bad input."""
        ch = self.channels.get(channel)
        if ch is None:
            raise ValueError(
                f"{self.name}: no port {channel!r} (this device has: {', '.join(self.channels)})"
            )
        self._faults.inject(ch, fault, params)
        self.pump()
        return ch.faults.describe()

    def after(self, seconds: float, action: Callable[[], None]) -> None:
        """Run `action` once `seconds` of device time have passed (a fault's expiry)."""
        self._faults.after(seconds, action)
        self._arm_timer()
