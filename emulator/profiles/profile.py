"""Device profiles: YAML -> validated, frozen dataclasses.

A profile file:

    spec: 1                  # format version (only 1 exists)
    device: mp285            # model family: picks the schema everything else is checked against
    description: one line shown by `stage-emu profiles`
    extends: mp285           # optional: a bundled profile name or a path (relative to this file)
    line: {baud: 9600, data_bits: 8, parity: none, stop_bits: 1, flow_control: none}
    ...                      # the family's own sections (device parameters, behaviour knobs)

`extends` chains are merged parent first (mappings key by key, other values replaced) and checked
for cycles. Every error names the file, line and key and says what is allowed, on one line. A file
that cannot be read, or whose `extends` chain cannot be resolved, is one error; once read, every
problem of its keys and values is reported, in file order (`ProfileError.problems`).

Limits (besides those of `emulator.profiles.yamlsource` on each file):
- `MAX_CHAIN` (16): profiles in one extends chain (the bundled ones use at most 3);
- a reference names a bundled profile or a `.yaml`/`.yml` file; a file reached through `extends`
  that is not a mapping with `spec:` or `device:` is refused without quoting any of it;
- a profile extends one of its own family (the child's `device:` line is blamed);
- `MAX_DESCRIPTION` (200): `description` is one line of printable text;
- `MAX_PROBLEMS` (50): problems listed one per line; a file with more is reported as its first
  problem and their count, on one line (10 000 unknown keys are not a profile with typos).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path as FsPath
from typing import Any, Generic, TypeVar

from emulator.profiles import registry
from emulator.profiles.describe import KnobRow, describe_rows
from emulator.profiles.schema import (
    Choice,
    Int,
    Schema,
    SchemaError,
    Section,
    Text,
    every_error,
    setting,
)
from emulator.profiles.yamlsource import (
    FileProblem,
    Located,
    Problem,
    SourceError,
    Where,
    in_file_order,
    merge,
    read_source,
)

SPEC_VERSION = 1
TOP_LEVEL_KEYS = ("spec", "device", "description", "extends")
PROFILE_SUFFIXES = (".yaml", ".yml")
MAX_CHAIN = 16
MAX_DESCRIPTION = 200
MAX_REFERENCE = 4096  # PATH_MAX
MAX_PROBLEMS = 50
DESCRIPTION = Text(MAX_DESCRIPTION)
NOT_A_PROFILE = "is not a profile (a profile is a YAML mapping with spec: and device:)"


class ProfileError(SourceError):
    """A profile (or rig) that cannot be loaded. Its message is its first problem, one line ready
    for the user; `problems` holds every problem found, in file order (`report()` lists them)."""

    def __init__(self, *problems: str | Problem) -> None:
        self.problems = tuple(p if isinstance(p, Problem) else Problem(p) for p in problems)
        super().__init__(self.problems[0].text)

    def report(self) -> list[str]:
        """One line per problem; past MAX_PROBLEMS the file is hardly a profile with a few slips,
        and the first problem stands for all of them, on one line."""
        if len(self.problems) <= MAX_PROBLEMS:
            return [p.text for p in self.problems]
        return [f"{self.problems[0].text} (and {len(self.problems) - 1} more problems)"]


class Line(Schema):
    """The `line` section of every family; `line_section` makes a family's, with its own choices."""

    baud: int
    data_bits: int
    parity: str
    stop_bits: float
    flow_control: str


class Config(Schema):
    """Base of a family's profile dataclass: every family has a `line` section."""

    line: Line


C = TypeVar("C", bound=Config)


@dataclass(frozen=True)
class Profile(Generic[C]):
    """A resolved profile. `config` is the family's frozen dataclass (its `line` section included),
    so a model that takes a `Profile[Mp285Config]` reads typed values."""

    name: str
    source: str
    family: str
    description: str
    chain: tuple[str, ...]
    config: C

    @property
    def line(self) -> Line:
        return self.config.line

    def describe(self) -> list[KnobRow]:
        return describe_rows(self.config)


def line_section(
    name: str,
    bauds: tuple[int, ...],
    default_baud: int,
    rule: str,
    parities: tuple[str, ...] = ("none", "even", "odd"),
    stop_bits: tuple[float, ...] = (1, 1.5, 2),
    data_bits: tuple[int, ...] = (8,),
    flow_controls: tuple[str, ...] = ("none",),
    default_flow: str = "none",
) -> type[Line]:
    """A family's `line` section, restricted to what the device supports: one class per family
    because the choices live in its fields (the same five fields for every family)."""
    fields = (
        ("baud", int, setting(Int(choices=bauds), default_baud, rule, "device baud rate")),
        ("data_bits", int, setting(Choice(data_bits), data_bits[-1], rule, "data bits per character")),
        ("parity", str, setting(Choice(parities), "none", rule, "parity bit")),
        ("stop_bits", float, setting(Choice(stop_bits), 1, rule, "stop bits")),
        (
            "flow_control",
            str,
            setting(Choice(flow_controls), default_flow, rule, "flow control the device uses"),
        ),
    )
    cls: type[Line] = dataclasses.make_dataclass(name, fields, bases=(Line,), frozen=True)
    return cls


def bundled_dir() -> FsPath:
    """The bundled profiles' directory: the `configs` package's own (a directory on disk, as the
    readers need; importlib.resources would add its imports to every daemon's start-up)."""
    import configs

    return FsPath(configs.__file__).parent


def bundled_names() -> list[str]:
    return sorted(p.stem for p in bundled_dir().glob("*.yaml") if _is_profile_file(p))


def _is_profile_file(path: FsPath) -> bool:
    try:
        data = read_source(path).data
    except SourceError:
        return False
    return isinstance(data, dict) and "device" in data


def resolve_reference(ref: str, relative_to: FsPath | None) -> FsPath:
    """A profile reference is a bundled name (`mp285`) or a path (anything with `/` or `.yaml`)."""
    if "/" in ref or ref.endswith(PROFILE_SUFFIXES):
        path = FsPath(ref).expanduser()
        if not path.is_absolute() and relative_to is not None:
            path = relative_to / path
        return path
    return bundled_dir() / f"{ref}.yaml"


def display_path(path: FsPath) -> str:
    """`path` as messages show it: relative to the working directory when it is below it."""
    try:
        return str(path.resolve().relative_to(FsPath.cwd()))
    except (OSError, ValueError, RuntimeError):
        return str(path)


def is_rig(data: Any) -> bool:
    """A rig file (a mapping of `devices`) rather than a profile."""
    return isinstance(data, dict) and "devices" in data and "device" not in data


def _refuse(via: Located | None, ref: str, path: FsPath, message: str) -> ProfileError:
    """`message` about the profile `ref`, blamed on the `extends:` line that named it if any."""
    if via is not None:
        return ProfileError(via.problem(("extends",), f"{_quoted(ref)} {message}"))
    return ProfileError(f"{display_path(path)}: {message}")


def _quoted(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:79] + "…"


def _read_profile(ref: str, path: FsPath, via: Located | None) -> Located:
    """Read one file of an extends chain. A parent is not trusted to be a profile until it looks
    like one, so nothing it contains is quoted before that (`extends: /etc/shadow`)."""
    if not path.name.endswith(PROFILE_SUFFIXES):
        raise _refuse(via, ref, path, "is not a profile file (its name must end in .yaml or .yml)")
    try:
        located = read_source(path, display_path(path), quote=via is None)
    except FileProblem as exc:
        bundled = "/" not in ref and not ref.endswith(PROFILE_SUFFIXES)
        if exc.missing and bundled:
            known = f"bundled profiles: {', '.join(bundled_names()) or 'none'}"
            if via is None:
                raise ProfileError(f"{ref}: no such profile ({known})") from None
            raise ProfileError(
                via.problem(("extends",), f"unknown profile {_quoted(ref)} ({known})")
            ) from None
        if via is not None:
            raise _refuse(via, ref, path, exc.reason) from None
        raise ProfileError(str(exc)) from None
    except SourceError as exc:
        raise ProfileError(str(exc)) from None
    data = located.data
    if is_rig(data):
        raise _refuse(via, ref, path, "is a rig file, not a profile")
    if not isinstance(data, dict) and via is None:
        raise ProfileError(located.problem((), "a profile must be a mapping"))
    if not isinstance(data, dict) or ("spec" not in data and "device" not in data):
        raise _refuse(via, ref, path, NOT_A_PROFILE)
    return located


def _load_chain(
    ref: str, relative_to: FsPath | None, seen: tuple[str, ...], via: Located | None
) -> tuple[Located, tuple[str, ...]]:
    if via is not None and len(seen) >= MAX_CHAIN:
        raise ProfileError(via.problem(("extends",), f"extends chain longer than {MAX_CHAIN} profiles"))
    if "\0" in ref or len(ref) > MAX_REFERENCE:
        message = "is not a profile name or path"
        raise ProfileError(via.problem(("extends",), message) if via else f"{_quoted(ref)} {message}")
    path = resolve_reference(ref, relative_to)
    try:
        key = str(path.resolve())
    except (OSError, RuntimeError):  # a symlink loop: reading it will say so
        key = str(path.absolute())
    if key in seen:
        cycle = " -> ".join([*(FsPath(s).stem for s in seen), path.stem])
        err = (
            via.error(("extends",), f"extends cycle: {cycle}")
            if via
            else ProfileError(f"extends cycle: {cycle}")
        )
        raise ProfileError(str(err))
    located = _read_profile(ref, path, via)
    parent_ref = located.data.get("extends")
    chain: tuple[str, ...] = (key,)
    if parent_ref is not None:
        if not isinstance(parent_ref, str) or not parent_ref:
            raise ProfileError(located.problem(("extends",), "must be a profile name or path"))
        parent, parent_chain = _load_chain(parent_ref, path.parent, (*seen, key), located)
        _check_family(located, parent.data.get("device"), parent_ref)
        located = merge(parent, located)
        chain = parent_chain + chain
    return located, chain


def _check_family(child: Located, parent_device: Any, parent_ref: str) -> None:
    """A profile extends one of its own family; the mismatch is the child's (its `device:`)."""
    device = child.data.get("device")
    both = [
        value
        for value in (device, parent_device)
        if isinstance(value, str) and registry.family(value) is not None
    ]
    if len(both) == 2 and device != parent_device:
        message = f"{device!r} cannot extend {_quoted(parent_ref)}, a profile of the {parent_device} family"
        raise ProfileError(child.problem(("device",), f"{message}; extend one of the {device} family"))


def load_profile(
    ref: str, overrides: Located | dict[str, Any] | None = None, relative_to: FsPath | None = None
) -> Profile[Any]:
    """Load a bundled profile by name or a profile file by path, apply `overrides`, validate.

    `overrides` is merged last, like one more `extends` layer (a plain dict, e.g. from a test, or a
    located sub-tree of a rig file so that errors point into the rig). A file that cannot be read
    or resolved (its `extends` chain) raises at its first problem; once it is read, every problem of
    its keys and values is found and raised together, in file order."""
    located, chain = _load_chain(ref, relative_to, (), None)
    if isinstance(overrides, dict):
        overrides = Located(overrides, {(): Where("<overrides>", 1)})
    if overrides is not None:
        located = merge(located, overrides)
    data = located.data
    problems = _check_top(located)
    device = data.get("device")
    fam = registry.family(device) if isinstance(device, str) else None
    config = None
    if fam is not None:
        body = {k: v for k, v in data.items() if k not in TOP_LEVEL_KEYS}
        try:
            config = Section(fam.schema).check(body, ())
        except SchemaError as exc:
            problems += [located.problem(e.path, e.message) for e in every_error(exc)]
    if problems:
        raise ProfileError(*in_file_order(problems, display_path(resolve_reference(ref, relative_to))))
    assert fam is not None and config is not None  # an unknown family is a problem of `device`
    return Profile(
        FsPath(chain[-1]).stem,
        located.places[()].source,
        fam.name,
        data.get("description") or "",
        tuple(chain),
        config,
    )


def _known_families() -> str:
    """Every family's name, for a message (imports every family: only on a problem)."""
    return ", ".join(sorted(registry.families())) or "none"


def _check_top(located: Located) -> list[Problem]:
    """The problems of the keys every profile has (`spec`, `device`, `description`)."""
    data = located.data
    problems = []
    spec = data.get("spec")
    if spec is None:
        problems.append(located.problem(("spec",), f"is required (spec: {SPEC_VERSION})"))
    elif spec != SPEC_VERSION or isinstance(spec, bool):
        message = f"{_quoted(spec)} is not a supported version (only {SPEC_VERSION})"
        problems.append(located.problem(("spec",), message))
    device = data.get("device")
    if device is None:
        problems.append(located.problem(("device",), f"is required; one of {_known_families()}"))
    elif not isinstance(device, str) or registry.family(device) is None:
        problems.append(located.problem(("device",), f"{_quoted(device)} is not one of {_known_families()}"))
    description = data.get("description")
    if description is not None and not isinstance(description, str):
        problems.append(located.problem(("description",), "must be a string"))
    elif description is not None:
        try:
            DESCRIPTION.check(description, ("description",))
        except SchemaError as exc:
            problems.append(located.problem(exc.path, exc.message))
    return problems
