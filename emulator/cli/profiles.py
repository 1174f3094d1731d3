"""`stage-emu profiles`, `validate` and `describe`: the bundled profiles, checking files, every knob."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import NoReturn

import click

from emulator.cli.common import fail
from emulator.hosting.rig import load_rig
from emulator.profiles.describe import DerivedDefault, plain
from emulator.profiles.profile import (
    ProfileError,
    bundled_names,
    display_path,
    is_rig,
    load_profile,
    resolve_reference,
)
from emulator.profiles.yamlsource import SourceError, read_source

#: `describe`'s allowed-values column is cut here (`--json` has every type in full)
ALLOWED_WIDTH = 48


def problem_lines(exc: SourceError) -> list[str]:
    """Every problem a file was refused for, one line each, in file order."""
    return exc.report() if isinstance(exc, ProfileError) else [str(exc)]


def fail_with(exc: SourceError) -> NoReturn:
    """`fail` with every problem of a refused file, each on its own `stage-emu:` line."""
    *first, last = problem_lines(exc)
    for line in first:
        click.echo(f"stage-emu: {line}", err=True)
    fail(last)


@click.command()
def profiles() -> None:
    """List the bundled profiles."""
    names = bundled_names()
    width = max((len(name) for name in names), default=0) + 2
    for name in names:
        try:
            profile = load_profile(name)
        except ProfileError as exc:
            click.echo(f"{name:<{width}}(invalid: {exc})")
            continue
        click.echo(f"{name:<{width}}{profile.family:<8} {profile.description}")


@click.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
def validate(files: tuple[Path, ...]) -> None:
    """Check profile or rig FILES; exit 1 with every problem, one `file:line: key: problem` line each,
    in file order (a file that cannot be read or parsed at all is one problem)."""
    failed = False
    for path in files:
        try:
            if is_rig(read_source(path).data):
                load_rig(path)
            else:
                load_profile(str(path.absolute()))
            click.echo(f"{path}: ok")
        except SourceError as exc:
            for line in problem_lines(exc):
                click.echo(line, err=True)
            failed = True
    sys.exit(1 if failed else 0)


@click.command()
@click.argument("profile")
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
def describe(profile: str, as_json: bool) -> None:
    """Print every knob of PROFILE: value, default, allowed values (type and range), rule and meaning."""
    try:
        loaded = load_profile(profile)
    except ProfileError as exc:
        hint = _rig_hint(profile)
        if hint:
            fail(hint)
        fail_with(exc)
    rows = loaded.describe()
    if as_json:
        click.echo(json.dumps([row.__dict__ for row in rows], indent=2, default=str, ensure_ascii=False))
        return
    click.echo(f"{loaded.name} ({loaded.family}): {loaded.description}")
    table = []
    for row in rows:
        value = json.dumps(row.value, ensure_ascii=False)
        if isinstance(row.default, DerivedDefault):
            default, mark = str(row.default), ""
        else:
            default = json.dumps(plain(row.default), ensure_ascii=False)
            mark = "" if row.value == plain(row.default) else "  *"
        table.append((row.path, value, default, _clipped(row.type), row.rule, row.doc + mark))
    # every column as wide as its widest cell, so long values keep the columns aligned
    widths = [max(len(cells[i]) for cells in table) for i in range(5)]
    for path, value, default, allowed, rule, doc in table:
        w_path, w_value, w_default, w_allowed, w_rule = widths
        click.echo(
            f"{path:<{w_path}}  {value:<{w_value}}  default {default:<{w_default}}  "
            f"allowed {allowed:<{w_allowed}}  {rule:<{w_rule}}  {doc}"
        )


def _clipped(text: str) -> str:
    return text if len(text) <= ALLOWED_WIDTH else text[: ALLOWED_WIDTH - 1] + "…"


def _rig_hint(ref: str) -> str:
    """If REF names a rig rather than a profile, say so and name the rig's profiles."""
    path = resolve_reference(ref, None)
    try:
        data = read_source(path).data
    except SourceError:
        return ""
    if not is_rig(data):
        return ""
    devices = data["devices"] if isinstance(data["devices"], list) else []
    names = [d["profile"] for d in devices if isinstance(d, dict) and isinstance(d.get("profile"), str)]
    return f"{display_path(path)} is a rig, not a profile; describe one of its profiles: {', '.join(names)}"
