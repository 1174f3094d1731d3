"""The command indexes at the top of docs/ms2000.md and docs/mp285.md: complete against the command
tables the models dispatch on, and naming only rules the rest of the document states, headings it
has, and profile keys its schema defines."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from emulator.device import DeviceServices
from emulator.devices.mp285.commands import TABLE as MP285_TABLE
from emulator.devices.mp285.schema import Mp285Config
from emulator.devices.ms2000.model import Ms2000Device
from emulator.devices.ms2000.schema import SCHEMA as MS2000_SCHEMA
from emulator.profiles.profile import bundled_names, load_profile
from emulator.profiles.schema import Section, schema_fields, spec_of
from protocols.ms2000.commands import BY_KEY

DOCS = Path(__file__).resolve().parents[2] / "docs"
INDEX_HEADING = "## Command index"
CTRL_C = "^C"
#: a rule ID, or a range of them as the documents cite one: `MS-RB-1…7`, `MS-99…MS-105`,
#: `MP-27 ... MP-36`, `MS-PEDAL-1, 2`
RULE = re.compile(
    r"\b(M[SP]-(?:[A-Z]+-)?)(\d+)"
    r"(?:(?:…| \.\.\. )(?:M[SP]-(?:[A-Z]+-)?)?(\d+)|((?:, \d+\b)+))?"
)


@dataclass(frozen=True)
class Row:
    commands: tuple[str, ...]  # the backticked words of the first cell
    rules: tuple[str, ...]
    anchors: tuple[str, ...]
    knobs: tuple[str, ...]


def split_index(text: str) -> tuple[list[Row], str]:
    """The index's rows, and the document without the index."""
    start = text.index(INDEX_HEADING)
    end = text.index("\n## ", start + len(INDEX_HEADING))
    rows = []
    for line in text[start:end].splitlines():
        if not line.startswith("| ") or line.startswith("| Command |"):
            continue
        cells = [cell.strip() for cell in line.strip("|").split(" | ")]
        assert len(cells) == 4, line
        command, rules, section, knobs = cells
        rows.append(
            Row(
                tuple(re.findall(r"`([^`]+)`", command)),
                tuple(rule.strip() for rule in rules.split(",")),
                tuple(re.findall(r"\]\(#([^)]+)\)", section)),
                tuple(re.findall(r"`([^`]+)`", knobs)),
            )
        )
    return rows, text[:start] + text[end:]


def slug(heading: str) -> str:
    """A heading's anchor as GitHub makes it: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(text: str) -> set[str]:
    return {slug(line.lstrip("#")) for line in text.splitlines() if re.match(r"#{1,6} ", line)}


def stated_rules(text: str) -> set[str]:
    """Every rule ID the text names, ranges expanded."""
    rules = set()
    for match in RULE.finditer(text):
        prefix, first, last, more = match.groups()
        numbers = {int(first)}
        if last is not None:
            numbers |= set(range(int(first), int(last) + 1))
        if more:
            numbers |= {int(n) for n in re.findall(r"\d+", more)}
        rules |= {f"{prefix}{n}" for n in numbers}
    return rules


def keys_of(cls: type[Any], prefix: str = "") -> set[str]:
    """Profile keys of a schema: knobs by their bare name, other keys by their dotted path."""
    keys = set()
    for f in schema_fields(cls):
        kind = spec_of(f).type
        if f.name == "knobs" and isinstance(kind, Section):
            keys |= {g.name for g in schema_fields(kind.cls)}
        elif isinstance(kind, Section):
            keys |= keys_of(kind.cls, f"{prefix}{f.name}.")
        else:
            keys.add(f"{prefix}{f.name}")
    return keys


def ms2000_commands() -> set[str]:
    """Every command key some bundled build dispatches: base table and module handlers."""
    keys: set[str] = set()
    for name in bundled_names():
        profile = load_profile(name)
        if profile.family != "ms2000":
            continue
        device = Ms2000Device("index", profile, 0.0, DeviceServices())
        keys |= set(device.base_table) | set(device.modules.handlers())
    return keys


def mp285_commands() -> set[str]:
    return {chr(byte) for byte in MP285_TABLE} | {CTRL_C}


FAMILIES = {
    "ms2000": (DOCS / "ms2000.md", lambda: keys_of(MS2000_SCHEMA)),
    "mp285": (DOCS / "mp285.md", lambda: keys_of(Mp285Config)),
}


def test_ms2000_index_lists_every_command_once() -> None:
    rows, _ = split_index((DOCS / "ms2000.md").read_text(encoding="utf-8"))
    listed = [command for row in rows for command in row.commands]
    assert len(listed) == len(set(listed))
    assert set(listed) == ms2000_commands()
    assert set(listed) == set(BY_KEY)  # the firmware's whole command table


def test_mp285_index_lists_every_command_once() -> None:
    rows, _ = split_index((DOCS / "mp285.md").read_text(encoding="utf-8"))
    listed = [row.commands[0] for row in rows]
    assert len(listed) == len(set(listed))
    assert set(listed) == mp285_commands()


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_index_names_only_stated_rules(family: str) -> None:
    """Each rule of a row is stated somewhere in the document outside the index."""
    rows, rest = split_index(FAMILIES[family][0].read_text(encoding="utf-8"))
    stated = stated_rules(rest)
    for row in rows:
        assert row.rules and set(row.rules) <= stated, (row.commands, set(row.rules) - stated)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_index_links_to_headings(family: str) -> None:
    text = FAMILIES[family][0].read_text(encoding="utf-8")
    rows, _ = split_index(text)
    headings = anchors(text)
    for row in rows:
        assert row.anchors and set(row.anchors) <= headings, (row.commands, set(row.anchors) - headings)


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_index_names_only_profile_keys(family: str) -> None:
    path, keys = FAMILIES[family]
    rows, _ = split_index(path.read_text(encoding="utf-8"))
    known = keys()
    for row in rows:
        assert set(row.knobs) <= known, (row.commands, set(row.knobs) - known)


def test_rule_ranges_expand() -> None:
    assert stated_rules("(MS-RB-1…3) and MS-99…MS-101, MS-PEDAL-1, 2; MP-27 ... MP-29") == {
        "MS-RB-1",
        "MS-RB-2",
        "MS-RB-3",
        "MS-99",
        "MS-100",
        "MS-101",
        "MS-PEDAL-1",
        "MS-PEDAL-2",
        "MP-27",
        "MP-28",
        "MP-29",
    }
