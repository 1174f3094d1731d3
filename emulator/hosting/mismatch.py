"""Line-setting mismatches between a host and the device on one channel. A mismatch is noticed when
either side's settings change and warned about once a byte crosses the line at those settings: a
host program that opens the port at its default speed and sets its own before writing is no
mismatch. The state lives on the channel (emulator/hosting/port.py)."""

from __future__ import annotations

import logging

from emulator.device import Device, LineSettings
from emulator.hosting.port import Port
from emulator.wire_time import mismatches

log = logging.getLogger("stage_emu.runner")


def check(ch: Port, own: LineSettings) -> None:
    """Compare the host's settings with the device's `own` (only when either changed) and keep
    a differing pair pending until a byte crosses (`report`)."""
    if ch.host is None or (ch.host, own) == ch.checked_for:
        return  # nothing changed since the last check (the common case, every step)
    ch.checked_for = (ch.host, own)
    differing = mismatches(own, ch.host)
    key = (tuple(differing), ch.host, own) if differing else ()
    if not differing:
        ch.reported_mismatch = ()
    ch.pending_mismatch = key if key != ch.reported_mismatch else ()


def report(ch: Port, device: Device) -> None:
    """Log the pending mismatch: a byte crossed the line while the settings differ."""
    key, ch.pending_mismatch = ch.pending_mismatch, ()
    ch.reported_mismatch = key
    _, host, own = key
    effect = device.mismatch_effect(host, ch.name)
    log.warning(
        "%s/%s: host uses %s, device expects %s%s",
        device.name,
        ch.name,
        host.filled(own).describe(),
        own.describe(),
        f"; {effect}" if effect else "",
    )


def forget(ch: Port) -> None:
    """A new host or a new device: nothing checked or warned about yet."""
    ch.reported_mismatch = ch.pending_mismatch = ()
    ch.checked_for = ()
