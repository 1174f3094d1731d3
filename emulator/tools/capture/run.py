"""A capture from start to end: open the port, read (family modules), keep what a profile can hold,
pick the bundled profile to extend, settle the keys to set, write and load the text.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import serial

from emulator.profiles.profile import Profile, ProfileError
from emulator.tools.capture import mp285, ms2000, ms2000_replies
from emulator.tools.capture.closest import Settled, checked, closest, settle
from emulator.tools.capture.readings import CaptureBug, Query, Reading, Transcript
from emulator.tools.capture.wire import LineOptions, Wire, open_port
from emulator.tools.capture.yamlout import body, description_of, load_text, render

#: a device_id the state directory can hold as a file name (emulator/storage/nvstore.py)
_UNSAFE_ID = re.compile(r"[^a-z0-9._-]+")
MAX_ID = 64


@dataclass(frozen=True)
class Family:
    """What a capture needs of a device family: line checks, the queries (`plan` for `--dry-run`)
    and their read-only check, the reader, the amendments once the parent is known, a one-line
    description of the captured profile."""

    name: str
    line_problem: Callable[[LineOptions], str | None]
    plan: Callable[[], list[Query]]
    dry_run_notes: tuple[str, ...]
    is_read_only: Callable[[Query], bool]
    read: Callable[[Wire, Transcript], list[Reading]]
    amend: Callable[[Profile[Any], list[Reading], Transcript], list[Reading]]
    caveats: Callable[[Profile[Any]], list[str]]
    summary: Callable[[Profile[Any]], str]
    show_hex: bool = False


def _ms2000_summary(profile: Profile[Any]) -> str:
    cfg = profile.config
    return f"ASI MS-2000 {cfg.build_name} ({cfg.version}, axes {' '.join(cfg.motor_axes)})"


def _mp285_summary(profile: Profile[Any]) -> str:
    controller = profile.config.controller
    version = controller.firmware_version
    return f"Sutter MP-285 firmware {version // 100}.{version % 100:02d} on {controller.interface}"


FAMILIES = {
    ms2000.NAME: Family(
        ms2000.NAME,
        ms2000.line_problem,
        ms2000.plan,
        ms2000.DRY_RUN_NOTES,
        ms2000.is_read_only,
        lambda wire, transcript: ms2000_replies.Ms2000Reader(wire, transcript).read(),
        ms2000.amend,
        ms2000.caveats,
        _ms2000_summary,
    ),
    mp285.NAME: Family(
        mp285.NAME,
        mp285.line_problem,
        mp285.plan,
        mp285.DRY_RUN_NOTES,
        mp285.is_read_only,
        lambda wire, transcript: mp285.Mp285Reader(wire, transcript).read(),
        lambda parent, readings, transcript: readings,
        mp285.caveats,
        _mp285_summary,
        show_hex=True,
    ),
}


def dry_run(device: str) -> list[str]:
    """What `--dry-run` prints: the notes as comments, then each query as sent."""
    family = FAMILIES[device]
    lines = [f"# {note}" for note in family.dry_run_notes]
    for query in family.plan():
        lines.append(f"{query.wire.hex(' ').upper():<8} {query.label}" if family.show_hex else query.label)
    return lines


@dataclass(frozen=True)
class Capture:
    """A finished capture: the profile's text, what it settled on and what was sent."""

    text: str
    settled: Settled
    sent: list[Query]
    notes: list[str]


def device_id_of(name: str) -> str:
    """`name` (the output file's stem, or the build) as a device_id: its own non-volatile memory."""
    slug = _UNSAFE_ID.sub("-", name.lower()).strip("-.")[:MAX_ID]
    return slug or "captured"


def capture(url: str, device: str, line: LineOptions, timeout: float, name: str | None = None) -> Capture:
    """Open `url` at `line`, read the controller of family `device` on it and compose its profile.
    `name` (the output file's stem) names the MS2000's non-volatile memory; without it the build
    name does."""
    port = open_port(url, line, timeout)
    try:
        return capture_from(port, device, line, timeout, name)
    finally:
        port.close()


def capture_from(
    port: serial.Serial, device: str, line: LineOptions, timeout: float, name: str | None = None
) -> Capture:
    """`capture` on a port already open at `line`."""
    family = FAMILIES[device]
    transcript = Transcript(family.is_read_only)
    readings = family.read(Wire(port, line, timeout, transcript), transcript)
    return compose(family, port.name or "", line, readings, transcript, name)


def compose(
    family: Family,
    url: str,
    line: LineOptions,
    readings: list[Reading],
    transcript: Transcript,
    name: str | None = None,
) -> Capture:
    """The profile text for `readings`, loaded and checked (CaptureBug when it does not validate)."""
    readings = checked(family.name, readings, transcript)
    parent = closest(family.name, readings)
    readings = family.amend(parent, readings, transcript)
    if family.name == ms2000.NAME:
        build = next((r.value for r in readings if r.path == ("build_name",)), parent.config.build_name)
        device_id = device_id_of(name or f"captured-{build}")
        readings.append(Reading(("device_id",), device_id, "the output's name", captured=False))
    settled = settle(parent, readings, transcript)
    header = [
        f"Captured by `stage-emu capture --device {family.name}` from {description_of(url)} at "
        f"{line.describe()}.",
        f"It extends {parent.name}, the closest bundled profile, and sets only what this controller",
        f"reported otherwise; what no read-only command reports is {parent.name}'s (docs/capture.md).",
        *family.caveats(parent),
    ]
    description = description_of(f"{family.summary(settled.profile)}, captured by stage-emu capture")
    text = render(body(settled, family.name, description), header, transcript.notes)
    try:
        load_text(text, parent, settled.readings)
    except ProfileError as exc:
        raise CaptureBug(f"the written profile does not validate: {exc}") from None
    return Capture(text, settled, transcript.sent, transcript.notes)
