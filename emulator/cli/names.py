"""The control-channel names the bundled profiles accept, for `ctl input --help` and `ctl get --help`.

Computed from the models, never listed by hand: each bundled profile's model is built (no state
directory) and asked for its `control_names()`. Names are grouped per family: those every profile
of the family has, then those only some profiles have (an MS2000 module's), with those profiles.
The models are imported only when the help is shown: `stage-emu ctl list` loads this module too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import click


@dataclass(frozen=True)
class FamilyNames:
    """One family's names of one kind (`inputs` or `observables`) across its bundled profiles."""

    family: str
    profiles: tuple[str, ...]
    common: tuple[str, ...]  # every profile of the family has these
    some: tuple[tuple[str, tuple[str, ...]], ...]  # (name, the profiles that have it), by name


def names_by_family(kind: str) -> list[FamilyNames]:
    """Each family's names of `kind`, from a model of each bundled profile."""
    from emulator.device import DeviceServices
    from emulator.profiles import registry
    from emulator.profiles.profile import ProfileError, bundled_names, load_profile

    per_profile: dict[str, dict[str, set[str]]] = {}
    for name in bundled_names():
        try:
            profile = load_profile(name)
        except ProfileError:
            continue  # `stage-emu profiles` reports it
        family = registry.family(profile.family)
        if family is None:
            continue
        model = family.factory(name, profile, 0.0, DeviceServices())
        per_profile.setdefault(profile.family, {})[name] = set(model.control_names()[kind])
    groups = []
    for family_name, profiles in sorted(per_profile.items()):
        common = set.intersection(*profiles.values())
        others = sorted(set.union(*profiles.values()) - common)
        some = tuple((n, tuple(p for p, names in profiles.items() if n in names)) for n in others)
        groups.append(FamilyNames(family_name, tuple(profiles), tuple(sorted(common)), some))
    return groups


class NamesHelp(click.Command):
    """A command whose --help ends with the names the bundled profiles' devices accept."""

    def __init__(self, *args: Any, kind: str, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._kind = kind

    def format_epilog(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section(f"{self._kind.capitalize()} of the bundled profiles"):
            for group in names_by_family(self._kind):
                count = len(group.profiles)
                every = "the one profile" if count == 1 else f"all {count} profiles"
                formatter.write_text(f"{group.family} ({every}):")
                with formatter.indentation():
                    formatter.write_text(", ".join(group.common) or "(none)")
                if group.some:
                    formatter.write_text(f"{group.family}, only in the profiles named:")
                    with formatter.indentation():
                        formatter.write_dl([(name, ", ".join(profiles)) for name, profiles in group.some])
                formatter.write_paragraph()
        formatter.write_text(f"`stage-emu ctl get DEVICE` lists a running device's {self._kind}.")
        formatter.write("\n")
