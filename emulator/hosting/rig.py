"""Rig files: which devices to run, with which profile, on which ports.

spec: 1
devices:
  - name: stage                 # unique; names the default link and the control-channel device
    profile: ms2000             # bundled name or path (relative to the rig file)
    overrides:                  # optional, merged onto the profile like one more `extends`
      knobs: {empty_line_reply: ignore}
    ports:                      # optional; every channel of the device gets a PTY regardless
      - channel: main           # the device's port (most devices have only `main`)
        transport: pty          # pty (default), tcp (socket://), rfc2217 (rfc2217://) or serial
        link: ~/dev/ttyStage    # pty only, optional; default <runtime dir>/<name> (<name>.<channel>)
        mode: 0600              # pty: pts permissions (octal)
        bind: 127.0.0.1         # tcp/rfc2217 only: the address to listen on (default 127.0.0.1)
        port: 7001              # tcp/rfc2217 only, required: TCP port (0: any free one, announced)
        device: /dev/ttyUSB0    # serial only, required: the port to open (a path, COM7, a pyserial URL)
        timing: realistic       # or fast

A rig file is read like a profile (`emulator.profiles.yamlsource.read_source`: regular file, 1 MiB, UTF-8,
node and depth limits); its `description` is one line like a profile's.

A device has one channel or more (`Device.channels`, known from its profile through the family:
a TTL REPORT build adds `aux`, MS-TTLREP-1). `ports` configures them; a channel it does not list
gets a default PTY, linked next to the main port's link when that is given (`<link>.<channel>`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path as FsPath
from typing import Any

from emulator.hosting.transports import DEVICE_KINDS, KINDS, NETWORK_KINDS
from emulator.profiles.profile import DESCRIPTION, Profile, ProfileError, load_profile
from emulator.profiles.registry import channels_of
from emulator.profiles.schema import (
    Choice,
    Int,
    ListOf,
    Nullable,
    Schema,
    SchemaError,
    Section,
    Str,
    Type,
    every_error,
    required,
    setting,
)
from emulator.profiles.yamlsource import Problem, SourceError, in_file_order, read_source
from emulator.wire_time import TIMINGS

NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}"
#: where a network port listens unless its `bind` says otherwise: this machine only
DEFAULT_BIND = "127.0.0.1"


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
    transport: str = setting(
        Choice(KINDS), "pty", doc="pty, tcp (raw socket), rfc2217 or serial (a real port)"
    )
    link: str | None = setting(Nullable(Str()), None, doc="stable path of the port (a symlink to the pts)")
    mode: int = setting(Int(0, 0o777), 0o600, doc="permissions of the pts device node (pty)")
    bind: str | None = setting(Nullable(Str()), None, doc=f"tcp/rfc2217: address (default {DEFAULT_BIND})")
    port: int | None = setting(Nullable(Int(0, 65535)), None, doc="tcp/rfc2217: TCP port (0: any free one)")
    timing: str | None = setting(
        Nullable(Choice(TIMINGS)), None, doc="realistic (paced at the baud rate) or fast"
    )
    device: str | None = setting(
        Nullable(Str()), None, doc="serial: the port to open (/dev/ttyUSB0, COM7 or a pyserial URL)"
    )

    def validate(self, path: tuple[str | int, ...]) -> None:
        allowed: tuple[str, ...]
        if self.transport in NETWORK_KINDS:
            if self.port is None:
                raise SchemaError((*path, "port"), f"a {self.transport} port needs a TCP port number")
            allowed = ("bind", "port")
        elif self.transport in DEVICE_KINDS:
            if not self.device:
                raise SchemaError(
                    (*path, "device"),
                    f"a {self.transport} port needs the device to open (/dev/ttyUSB0, COM7, a pyserial URL)",
                )
            allowed = ("device",)
        else:
            allowed = ("link",)
        wrong = next(
            (
                name
                for name in ("link", "bind", "port", "device")
                if name not in allowed and getattr(self, name) is not None
            ),
            None,
        )
        if wrong:
            raise SchemaError((*path, wrong), f"does not apply to a {self.transport} port")


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
    transport: str
    link: FsPath | None
    mode: int
    timing: str | None
    bind: str = DEFAULT_BIND
    port: int | None = None  # tcp/rfc2217 only
    device: str | None = None  # serial only

    def address(self) -> str:
        return f"{self.bind}:{self.port}"


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
    """Read and check a rig file and every profile it names; every problem found is raised
    together, in file order (a file that cannot be read at all is one)."""
    try:
        located = read_source(path)
    except SourceError as exc:
        raise ProfileError(str(exc)) from None
    problems: list[Problem] = []
    try:
        raw = Section(RigFile).check(located.data, ())
    except SchemaError as exc:
        problems += [located.problem(e.path, e.message) for e in every_error(exc)]
    profiles = []
    for index, entry in _entries(located.data):
        ref, overrides = entry.get("profile"), entry.get("overrides")
        if not isinstance(ref, str) or not isinstance(overrides, dict | None):
            continue  # the schema said so
        where = located.subtree(("devices", index, "overrides")) if overrides else None
        try:
            profiles.append(load_profile(ref, where, relative_to=path.parent))
        except ProfileError as exc:
            problems += exc.problems
    if problems:
        raise ProfileError(*in_file_order(problems, str(path)))
    devices = []
    for dev, profile in zip(raw.devices, profiles, strict=True):
        specs = tuple(
            PortSpec(
                p.channel,
                p.transport,
                _link(p.link, path.parent),
                p.mode,
                p.timing,
                p.bind or DEFAULT_BIND,
                p.port,
                p.device,
            )
            for p in dev.ports or ()
        )
        devices.append(DeviceSpec(dev.name, profile, with_every_channel(profile, specs)))
    rig = Rig(str(path), tuple(devices))
    crossed = [located.problem(("devices", i), message) for i, message in rig_problems(rig)]
    if crossed:
        raise ProfileError(*in_file_order(crossed, str(path)))
    return rig


def _entries(data: Any) -> list[tuple[int, dict[str, Any]]]:
    """The device entries of a rig file's data that are mappings, with their index (the schema
    reports the rest)."""
    devices = data.get("devices") if isinstance(data, dict) else None
    listed = devices if isinstance(devices, list) else []
    return [(index, entry) for index, entry in enumerate(listed) if isinstance(entry, dict)]


def _link(link: str | None, base: FsPath) -> FsPath | None:
    if link is None:
        return None
    path = FsPath(link).expanduser()
    return path if path.is_absolute() else base / path


def with_every_channel(profile: Profile, listed: tuple[PortSpec, ...]) -> tuple[PortSpec, ...]:
    """`listed`, then a default PTY for each channel of the device they leave out: `main` when
    nothing is listed, a TTL REPORT build's `aux` beside it (MS-5), linked next to the main link."""
    main = next((p for p in listed if p.channel == "main"), None)
    have = {p.channel for p in listed}
    added = tuple(
        PortSpec(channel, "pty", _beside(main.link if main else None, channel), 0o600, None)
        for channel in channels_of(profile)
        if channel not in have
    )
    return listed + added


def _beside(main_link: FsPath | None, channel: str) -> FsPath | None:
    if main_link is None or channel == "main":
        return None  # the daemon's default (<name> or <name>.<channel> in its link directory)
    return main_link.with_name(f"{main_link.name}.{channel}")


def rig_problems(rig: Rig) -> list[tuple[int, str]]:
    """Cross-device checks: unique names, one port per channel the device has, unique links and
    addresses. Each problem comes with the index of the device at fault (the later of two)."""
    problems: list[tuple[int, str]] = []
    names: set[str] = set()
    links: set[FsPath] = set()
    addresses: set[str] = set()
    serial_devices: set[str] = set()
    for index, dev in enumerate(rig.devices):
        if dev.name in names:
            problems.append((index, f"device name {dev.name!r} is used twice"))
        names.add(dev.name)
        channels = [p.channel for p in dev.ports]
        has = channels_of(dev.profile)
        for channel in dict.fromkeys(channels):
            if channels.count(channel) > 1:
                problems.append((index, f"device {dev.name!r} has two ports on channel {channel!r}"))
            if channel not in has:
                problems.append(
                    (index, f"device {dev.name!r} has no channel {channel!r} (it has: {', '.join(has)})")
                )
        for port in dev.ports:
            if port.link is not None:
                if port.link in links:
                    problems.append((index, f"link {port.link} is used by two ports"))
                links.add(port.link)
            if port.transport in NETWORK_KINDS and port.port:
                if port.address() in addresses:
                    problems.append((index, f"address {port.address()} is used by two ports"))
                addresses.add(port.address())
            if port.device is not None:
                if port.device in serial_devices:
                    problems.append((index, f"serial device {port.device} is used by two ports"))
                serial_devices.add(port.device)
    return problems


def parse_address(text: str) -> tuple[str, int]:
    """`HOST:PORT`, `[IPv6]:PORT` or a bare `PORT` (on DEFAULT_BIND); raises ValueError."""
    host, colon, number = text.rpartition(":")
    if not number.isdigit() or not 0 <= int(number) <= 65535:
        raise ValueError(f"{text!r} is not HOST:PORT with a port number 0-65535")
    host = host.removeprefix("[").removesuffix("]")
    if colon and not host:
        raise ValueError(f"{text!r} has no host before the ':'")
    return host or DEFAULT_BIND, int(number)


def rig_from_profiles(entries: list[str], network: tuple[str, str] | None = None) -> Rig:
    """`--profile NAME[:LINK]` options as a rig: the device is named after its profile, repeats
    of a profile get `-2`, `-3`... (`--profile mp285 --profile mp285` serves mp285 and mp285-2).
    `network` (kind, address) serves the main port of the one profile on tcp or rfc2217 instead, or
    (serial, device) on that serial device."""
    if network is not None and len(entries) != 1:
        raise ProfileError(f"--{network[0]} serves one --profile; for several devices write a rig file")
    devices = []
    counts: dict[str, int] = {}
    for entry in entries:
        ref, _, link = entry.partition(":")
        profile = load_profile(ref)
        index = counts.get(profile.name, 0)
        counts[profile.name] = index + 1
        if network is None:
            port = PortSpec(
                "main", "pty", FsPath(link).expanduser().absolute() if link else None, 0o600, None
            )
        elif link:
            raise ProfileError(f"--profile {entry}: a link does not apply to a {network[0]} port")
        elif network[0] in DEVICE_KINDS:
            port = PortSpec("main", network[0], None, 0o600, None, device=network[1])
        else:
            try:
                bind, number = parse_address(network[1])
            except ValueError as exc:
                raise ProfileError(f"--{network[0]}: {exc}") from None
            port = PortSpec("main", network[0], None, 0o600, None, bind, number)
        name = profile.name if index == 0 else f"{profile.name}-{index + 1}"
        devices.append(DeviceSpec(name, profile, with_every_channel(profile, (port,))))
    rig = Rig("--profile", tuple(devices))
    problems = rig_problems(rig)
    if problems:
        raise ProfileError(*(message for _, message in problems))
    return rig
