"""From readings to the few keys a profile file needs: the closest bundled profile, and the smallest
set of readings that, on top of it, gives a profile matching every reading.

- `checked`: a reading whose value its field cannot hold (a range, a length) becomes a note.
- `closest`: the bundled profile of the family with the least weighted distance to the readings
  (build, modules and axes weigh most), ties by name.
- `settle`: the readings the parent does not match, plus any a derived default then needs (a new
  encoder resolution changes the derived finish error), less any the others make redundant. The
  profile is loaded at every step with the project's loader; a problem it finds at a key set from
  a reading drops that reading (with a note); any other problem is a `CaptureBug`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from emulator.profiles import registry
from emulator.profiles.profile import Profile, ProfileError, bundled_names, load_profile
from emulator.profiles.schema import MapOf, SchemaError, Section, Type, schema_fields, spec_of
from emulator.profiles.schema import Path as SchemaPath
from emulator.profiles.yamlsource import Located, Where
from emulator.tools.capture.readings import CaptureBug, FieldPath, Reading, Transcript

#: the source name of the keys a capture sets, so that a loader problem can be traced to its reading
SOURCE = "<capture>"
#: rounds of adding what derived defaults need (a chain is never longer than a field or two)
MAX_ROUNDS = 8


def field_type(schema: type[Any], path: FieldPath) -> Type | None:
    """The type the family's schema gives the value at `path` (None: no such field)."""
    kind: Type = Section(schema)
    for part in path:
        if isinstance(kind, Section):
            found = next((f for f in schema_fields(kind.cls) if f.name == part), None)
            if found is None:
                return None
            kind = spec_of(found).type
        elif isinstance(kind, MapOf):
            kind = kind.value
        else:
            return None
    return kind


def checked(family: str, readings: Sequence[Reading], transcript: Transcript) -> list[Reading]:
    """The readings whose values their fields hold; each other one becomes a note."""
    found = registry.family(family)
    assert found is not None
    kept = []
    for reading in readings:
        kind = field_type(found.schema, reading.path)
        if kind is None:
            raise CaptureBug(f"{reading.dotted} is not a field of the {family} profile")
        try:
            kind.check(reading.value, reading.path)
        except SchemaError as exc:
            transcript.note(f"{reading.source} gave {reading.dotted} {reading.value!r}: {exc.message}")
            continue
        kept.append(reading)
    return kept


def candidates(family: str) -> list[Profile[Any]]:
    """The bundled profiles of `family`, by name."""
    found = []
    for name in bundled_names():
        try:
            profile = load_profile(name)
        except ProfileError:
            continue
        if profile.family == family:
            found.append(profile)
    return found


def closest(family: str, readings: Sequence[Reading]) -> Profile[Any]:
    """The bundled profile of `family` the readings are least far from."""
    profiles = candidates(family)
    if not profiles:
        raise CaptureBug(f"no bundled {family} profile to extend")
    return min(profiles, key=lambda p: (sum(r.cost(p) for r in readings), p.name))


def nested(readings: Sequence[Reading]) -> Located:
    """The readings' values as a profile's nested keys, each located at its reading's index."""
    data: dict[str, Any] = {}
    places: dict[SchemaPath, Where] = {}
    for index, reading in enumerate(readings):
        node = data
        for part in reading.path[:-1]:
            node = node.setdefault(part, {})
        node[reading.path[-1]] = reading.value
        places[reading.path] = Where(SOURCE, index)
    return Located(data, places)


@dataclass(frozen=True)
class Settled:
    """The outcome: `parent` to extend, `chosen` the readings the file sets (in reading order),
    `profile` the captured profile as loaded, `readings` every reading kept."""

    parent: Profile[Any]
    chosen: list[Reading]
    profile: Profile[Any]
    readings: list[Reading]


class _Dropped(Exception):
    def __init__(self, readings: list[Reading]) -> None:
        self.readings = readings


def _load(parent: Profile[Any], chosen: list[Reading]) -> Profile[Any]:
    """`parent` with `chosen` on top; _Dropped with the readings the loader blames, CaptureBug when
    it blames anything else."""
    try:
        return load_profile(parent.name, overrides=nested(chosen))
    except ProfileError as exc:
        blamed = [p.where.line for p in exc.problems if p.where is not None and p.where.source == SOURCE]
        if len(blamed) != len(exc.problems):
            raise CaptureBug(f"the captured profile does not validate: {exc}") from None
        raise _Dropped([chosen[i] for i in dict.fromkeys(blamed)]) from None


def settle(parent: Profile[Any], readings: list[Reading], transcript: Transcript) -> Settled:
    readings = list(readings)
    chosen = [r for r in readings if not r.matches(parent)]
    for _ in range(MAX_ROUNDS):
        try:
            profile = _load(parent, chosen)
        except _Dropped as dropped:
            for reading in dropped.readings:
                _drop(reading, parent, chosen, transcript)
                readings.remove(reading)
            chosen = [r for r in chosen if r in readings]
            continue
        missing = [r for r in readings if r not in chosen and not r.matches(profile)]
        if not missing:
            break
        chosen = [r for r in readings if r in chosen or r in missing]
    else:
        raise CaptureBug("the captured profile does not settle: derived values keep changing")
    for reading in reversed(list(chosen)):
        trial = [r for r in chosen if r is not reading]
        try:
            smaller = _load(parent, trial)
        except _Dropped:
            continue
        if all(r.matches(smaller) for r in readings):
            chosen, profile = trial, smaller
    unmatched = [r.dotted for r in readings if not r.matches(profile)]
    if unmatched:
        raise CaptureBug(f"the captured profile does not reproduce {', '.join(unmatched)}")
    return Settled(parent, chosen, profile, readings)


def _drop(reading: Reading, parent: Profile[Any], chosen: list[Reading], transcript: Transcript) -> None:
    """Say why the loader refused `reading`: its own message, as loading it alone gives it."""
    try:
        load_profile(parent.name, overrides=nested([reading]))
        why = "refused with the other values read"
    except ProfileError as exc:
        why = str(exc).split(": ", 2)[-1]
    transcript.note(f"{reading.source} gave {reading.dotted} {reading.value!r}: {why}; left out")
