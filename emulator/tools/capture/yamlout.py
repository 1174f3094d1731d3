"""Writing a captured profile: a comment header (where it came from, what it extends, the notes),
then `spec`, `device`, `description`, `extends` and the keys that differ, in the order `describe`
lists them. Lists are written inline (`modules: [LL COMMANDS, CRISP]`), numbers as short as they
stay exact, as in the bundled profiles.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import yaml

from emulator.profiles.profile import MAX_DESCRIPTION, SPEC_VERSION, Profile, ProfileError, load_profile
from emulator.profiles.yamlsource import SourceError, load_located
from emulator.tools.capture.closest import Settled
from emulator.tools.capture.readings import FieldPath, Reading

#: decimals a float is tried at before falling back to its full repr
SHORT_DECIMALS = 9
#: no value is folded onto a second line (a status template is 95 characters)
WIDTH = 4096


class _Dumper(yaml.SafeDumper):
    """Block mappings, inline lists, short exact floats."""


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True)


def _represent_float(dumper: yaml.SafeDumper, data: float) -> yaml.Node:
    for decimals in range(1, SHORT_DECIMALS + 1):
        short = f"{data:.{decimals}f}"
        if float(short) == data:
            return dumper.represent_scalar("tag:yaml.org,2002:float", short)
    return dumper.represent_float(data)


_Dumper.add_representer(list, _represent_list)
_Dumper.add_representer(float, _represent_float)


def _order(profile: Profile[Any]) -> list[FieldPath]:
    return [tuple(row.path.split(".")) for row in profile.describe()]


def _rank(path: FieldPath, order: list[FieldPath]) -> int:
    """Where `path` comes in `describe`'s order (a key under a mapping-valued field: with it)."""
    for index, row in enumerate(order):
        if path[: len(row)] == row or row[: len(path)] == path:
            return index
    return len(order)


def body(settled: Settled, device: str, description: str) -> dict[str, Any]:
    """The profile as plain data: the top keys, then the chosen readings nested."""
    data: dict[str, Any] = {
        "spec": SPEC_VERSION,
        "device": device,
        "description": description,
        "extends": settled.parent.name,
    }
    order = _order(settled.profile)
    for reading in sorted(settled.chosen, key=lambda r: _rank(r.path, order)):
        node = data
        for part in reading.path[:-1]:
            node = node.setdefault(part, {})
        node[reading.path[-1]] = reading.value
    return data


def description_of(text: str) -> str:
    """One printable line the profile's `description` accepts."""
    line = "".join(ch if ch.isprintable() else "?" for ch in text)
    return line if len(line) <= MAX_DESCRIPTION else line[: MAX_DESCRIPTION - 1] + "…"


def render(data: dict[str, Any], header: Sequence[str], notes: Sequence[str]) -> str:
    comments = [f"# {line}".rstrip() for line in header]
    if notes:
        comments += ["#", "# Notes:"] + [f"# - {note}" for note in notes]
    text = yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=WIDTH)
    return "\n".join(comments) + "\n" + text


def load_text(text: str, parent: Profile[Any], readings: Sequence[Reading]) -> Profile[Any]:
    """The written text loaded as the project's loader reads it (on top of `parent`, the profile
    it extends); ProfileError when it does not validate or does not reproduce every reading."""
    try:
        located = load_located(text, "<captured profile>")
    except SourceError as exc:
        raise ProfileError(str(exc)) from None
    profile = load_profile(parent.name, overrides=located)
    unmatched = [r.dotted for r in readings if not r.matches(profile)]
    if unmatched:
        raise ProfileError(f"the written profile does not reproduce {', '.join(unmatched)}")
    return profile
