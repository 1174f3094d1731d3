"""Rig files: which devices to run, with which profile, on which ports.

spec: 1
devices:
  - name: stage                 # unique; names the default link and the control-channel device
    profile: ms2000             # bundled name or path (relative to the rig file)
    overrides:                  # optional, merged onto the profile like one more `extends`
      knobs: {empty_line_reply: ignore}
    ports:                      # optional; default: one PTY on the main channel
      - channel: main           # the device's port (most devices have only `main`)
        type: pty
        link: ~/dev/ttyStage    # optional; default <runtime dir>/<name>
        mode: 0600              # pts permissions (octal)
        timing: realistic       # or fast

A rig file is read like a profile (`emulator.yamlsource.read_source`: regular file, 1 MiB, UTF-8,
node and depth limits); its `description` is one line like a profile's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path as FsPath
from typing import Any

from emulator.line import TIMINGS
from emulator.profile import DESCRIPTION, Profile, ProfileError, load_profile
from emulator.schema import (
    Choice,
    Int,
    ListOf,
    Nullable,
    Schema,
    SchemaError,
    Section,
    Str,
    Type,
    required,
    setting,
)
from emulator.yamlsource import SourceError, read_source

NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}"


@dataclass(frozen=True)
class Anything(Type):
    """Free-form mapping checked later (profile overrides are validated against the profile)."""

    def check(self, value: Any, path: tuple[str | int, ...]) -> Any:
        if not isinstance(value, dict):
            raise SchemaError(path, f"{value!r} is not a mapping")
        return value

    def describe(self) -> str:
        return "mapping"


@dataclass(frozen=True)
class RigPort(Schema):
    channel: str = setting(Str(), "main", doc="device channel this port carries")
    type: str = setting(Choice(("pty",)), "pty", doc="transport")
    link: str | None = setting(Nullable(Str()), None, doc="stable path of the port (a symlink to the pts)")
    mode: int = setting(Int(0, 0o777), 0o600, doc="permissions of the pts device node")
    timing: str | None = setting(
        Nullable(Choice(TIMINGS)), None, doc="realistic (paced at the baud rate) or fast"
    )


@dataclass(frozen=True)
class RigDevice(Schema):
    name: str = required(Str(pattern=NAME_PATTERN, pattern_text="letters, digits, '_', '.', '-'"))
    profile: str = required(Str(), doc="bundled profile name or path")
    overrides: dict[str, Any] | None = setting(Nullable(Anything()), None, doc="profile keys to override")
    ports: tuple[RigPort, ...] | None = setting(
        Nullable(ListOf(Section(RigPort), min_length=1)), None, doc="ports (default: one PTY)"
    )


@dataclass(frozen=True)
class RigFile(Schema):
    spec: int = required(Int(choices=(1,)))
    description: str | None = setting(Nullable(DESCRIPTION), None)
    devices: tuple[RigDevice, ...] = required(ListOf(Section(RigDevice), min_length=1))


@dataclass(frozen=True)
class PortSpec:
    channel: str
    type: str
    link: FsPath | None
    mode: int
    timing: str | None


@dataclass(frozen=True)
class DeviceSpec:
    name: str
    profile: Profile
    ports: tuple[PortSpec, ...]


@dataclass(frozen=True)
class Rig:
    source: str
    devices: tuple[DeviceSpec, ...]


def load_rig(path: FsPath) -> Rig:
    try:
        located = read_source(path)
    except SourceError as exc:
        raise ProfileError(str(exc)) from None
    try:
        raw = Section(RigFile).check(located.data, ())
    except SchemaError as exc:
        raise ProfileError(str(located.error(exc.path, exc.message))) from None
    devices = []
    for index, dev in enumerate(raw.devices):
        overrides = located.subtree(("devices", index, "overrides")) if dev.overrides else None
        profile = load_profile(dev.profile, overrides, relative_to=path.parent)
        ports = dev.ports or (Section(RigPort).check({}, ()),)
        specs = tuple(
            PortSpec(p.channel, p.type, _link(p.link, path.parent), p.mode, p.timing) for p in ports
        )
        devices.append(DeviceSpec(dev.name, profile, specs))
    rig = Rig(str(path), tuple(devices))
    problem = check_rig(rig)
    if problem:
        raise ProfileError(f"{path}: {problem}")
    return rig


def _link(link: str | None, base: FsPath) -> FsPath | None:
    if link is None:
        return None
    path = FsPath(link).expanduser()
    return path if path.is_absolute() else base / path


def check_rig(rig: Rig) -> str:
    """Cross-device checks: unique names, one port per channel, unique links."""
    names = [d.name for d in rig.devices]
    duplicate = next((n for n in names if names.count(n) > 1), None)
    if duplicate:
        return f"device name {duplicate!r} is used twice"
    links: list[FsPath] = []
    for dev in rig.devices:
        channels = [p.channel for p in dev.ports]
        again = next((c for c in channels if channels.count(c) > 1), None)
        if again:
            return f"device {dev.name!r} has two ports on channel {again!r}"
        links.extend(p.link for p in dev.ports if p.link is not None)
    twice = next((link for link in links if links.count(link) > 1), None)
    return f"link {twice} is used by two ports" if twice else ""


def rig_from_profiles(entries: list[str]) -> Rig:
    """`--profile NAME[:LINK]` options as a rig: the device is named after its profile, repeats
    of a profile get `-2`, `-3`... (`--profile mp285 --profile mp285` serves mp285 and mp285-2)."""
    devices = []
    counts: dict[str, int] = {}
    for entry in entries:
        ref, _, link = entry.partition(":")
        profile = load_profile(ref)
        index = counts.get(profile.name, 0)
        counts[profile.name] = index + 1
        port = PortSpec("main", "pty", FsPath(link).expanduser().absolute() if link else None, 0o600, None)
        name = profile.name if index == 0 else f"{profile.name}-{index + 1}"
        devices.append(DeviceSpec(name, profile, (port,)))
    rig = Rig("--profile", tuple(devices))
    problem = check_rig(rig)
    if problem:
        raise ProfileError(problem)
    return rig
