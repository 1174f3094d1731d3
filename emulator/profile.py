"""Device profiles: YAML -> validated, frozen dataclasses.

A profile file:

    spec: 1                  # format version (only 1 exists)
    device: mp285            # model family: picks the schema everything else is checked against
    description: one line shown by `stage-emu profiles`
    extends: mp285           # optional: a bundled profile name or a path (relative to this file)
    line: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1, flow_control: none}
    ...                      # the family's own sections (device parameters, behaviour knobs)

`extends` chains are merged parent first (mappings key by key, other values replaced) and checked
for cycles. Every error names the file, line and key and says what is allowed.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path as FsPath
from typing import Any

from emulator import registry
from emulator.schema import Choice, Field, Int, SchemaError, Struct, describe_rows
from emulator.yamlsource import Located, SourceError, Where, load_located, merge

SPEC_VERSION = 1
TOP_LEVEL_KEYS = ("spec", "device", "description", "extends")


class ProfileError(SourceError):
    """A profile (or rig) that cannot be loaded; the message is ready for the user."""


@dataclass(frozen=True)
class Profile:
    """A resolved profile. `config` is the family's frozen dataclass (its `line` field included)."""

    name: str
    source: str
    family: str
    description: str
    chain: tuple[str, ...]
    config: Any

    @property
    def line(self) -> Any:
        return self.config.line

    def describe(self) -> list[Any]:
        fam = registry.family(self.family)
        assert fam is not None
        return describe_rows(fam.schema, self.config)


def line_struct(
    bauds: tuple[int, ...],
    default_baud: int,
    rule: str,
    parities: tuple[str, ...] = ("none", "even", "odd"),
    stop_bits: tuple[float, ...] = (1, 1.5, 2),
    data_bits: tuple[int, ...] = (8,),
    flow_controls: tuple[str, ...] = ("none",),
    default_flow: str = "none",
) -> Struct:
    """The `line` section shared by every family, restricted to what the device supports."""
    return Struct(
        "Line",
        (
            Field("baud", Int(choices=bauds), default_baud, rule, "device baud rate"),
            Field("data_bits", Choice(data_bits), data_bits[-1], rule, "data bits per character"),
            Field("parity", Choice(parities), "none", rule, "parity bit"),
            Field("stop_bits", Choice(stop_bits), 1, rule, "stop bits"),
            Field("flow_control", Choice(flow_controls), default_flow, rule, "flow control the device uses"),
        ),
    )


def bundled_dir() -> FsPath:
    return FsPath(str(resources.files("configs")))


def bundled_names() -> list[str]:
    return sorted(p.stem for p in bundled_dir().glob("*.yaml") if _is_profile_file(p))


def _is_profile_file(path: FsPath) -> bool:
    try:
        data = load_located(path.read_text(), str(path)).data
    except (OSError, SourceError):
        return False
    return isinstance(data, dict) and "device" in data


def resolve_reference(ref: str, relative_to: FsPath | None) -> FsPath:
    """A profile reference is a bundled name (`mp285`) or a path (anything with `/` or `.yaml`)."""
    if "/" in ref or ref.endswith((".yaml", ".yml")):
        path = FsPath(ref).expanduser()
        if not path.is_absolute() and relative_to is not None:
            path = relative_to / path
        return path
    return bundled_dir() / f"{ref}.yaml"


def _display(path: FsPath) -> str:
    try:
        return str(path.resolve().relative_to(FsPath.cwd()))
    except ValueError:
        return str(path)


def _read(path: FsPath) -> Located:
    try:
        text = path.read_text()
    except OSError as exc:
        raise ProfileError(f"{_display(path)}: cannot read profile: {exc.strerror or exc}") from None
    try:
        return load_located(text, _display(path))
    except SourceError as exc:
        raise ProfileError(str(exc)) from None


def _load_chain(
    ref: str, relative_to: FsPath | None, seen: tuple[str, ...], via: Located | None
) -> tuple[Located, tuple[str, ...]]:
    path = resolve_reference(ref, relative_to)
    key = str(path.resolve())
    if key in seen:
        cycle = " -> ".join([*(FsPath(s).stem for s in seen), path.stem])
        err = (
            via.error(("extends",), f"extends cycle: {cycle}")
            if via
            else ProfileError(f"extends cycle: {cycle}")
        )
        raise ProfileError(str(err))
    if not path.is_file():
        if via is not None:
            known = ", ".join(bundled_names()) or "none"
            raise ProfileError(
                str(via.error(("extends",), f"unknown profile {ref!r} (bundled profiles: {known})"))
            )
        raise ProfileError(
            f"{ref}: no such profile (bundled profiles: {', '.join(bundled_names()) or 'none'})"
        )
    located = _read(path)
    if not isinstance(located.data, dict):
        raise ProfileError(str(located.error((), "a profile must be a mapping")))
    parent_ref = located.data.get("extends")
    chain = (key,)
    if parent_ref is not None:
        if not isinstance(parent_ref, str):
            raise ProfileError(
                str(located.error(("extends",), f"{parent_ref!r} is not a profile name or path"))
            )
        parent, parent_chain = _load_chain(parent_ref, path.parent, (*seen, key), located)
        located = merge(parent, located)
        chain = parent_chain + chain
    return located, chain


def load_profile(
    ref: str, overrides: Located | dict[str, Any] | None = None, relative_to: FsPath | None = None
) -> Profile:
    """Load a bundled profile by name or a profile file by path, apply `overrides`, validate.

    `overrides` is merged last, like one more `extends` layer (a plain dict, e.g. from a test, or a
    located sub-tree of a rig file so that errors point into the rig)."""
    located, chain = _load_chain(ref, relative_to, (), None)
    if isinstance(overrides, dict):
        overrides = Located(overrides, {(): Where("<overrides>", 1)})
    if overrides is not None:
        located = merge(located, overrides)
    data = located.data
    name = FsPath(chain[-1]).stem
    _check_top(located)
    fam = registry.family(data["device"])
    body = {k: v for k, v in data.items() if k not in TOP_LEVEL_KEYS}
    try:
        config = fam.schema.check(body, ())
    except SchemaError as exc:
        raise ProfileError(str(located.error(exc.path, exc.message))) from None
    return Profile(
        name, located.places[()].source, fam.name, data.get("description") or "", tuple(chain), config
    )


def _check_top(located: Located) -> None:
    data = located.data
    spec = data.get("spec")
    if spec is None:
        raise ProfileError(str(located.error(("spec",), f"is required (spec: {SPEC_VERSION})")))
    if spec != SPEC_VERSION or isinstance(spec, bool):
        raise ProfileError(
            str(located.error(("spec",), f"{spec!r} is not a supported version (only {SPEC_VERSION})"))
        )
    device = data.get("device")
    known = sorted(registry.families())
    if device is None:
        raise ProfileError(
            str(located.error(("device",), f"is required; one of {', '.join(known) or 'none'}"))
        )
    if registry.family(device) is None if isinstance(device, str) else True:
        raise ProfileError(
            str(located.error(("device",), f"{device!r} is not one of {', '.join(known) or 'none'}"))
        )
    description = data.get("description")
    if description is not None and not isinstance(description, str):
        raise ProfileError(str(located.error(("description",), "must be a string")))
