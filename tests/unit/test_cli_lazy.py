"""The command line loads a subcommand's module only when it runs (emulator/cli/__init__.py): `--version` and
`ctl list` start without the daemon, asyncio, the models, the profiles or rich (issue "Fast,
deterministic feedback", item 4: 0.5-0.6 s each before, every subcommand's imports paid by all).
The help listing, made from a table instead of the modules, stays what click prints."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from functools import partial
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from emulator.cli import COMMANDS, main

#: modules only a daemon, a model, a profile, a session or a screen needs
HEAVY = (
    "asyncio",
    "yaml",
    "serial",
    "rich",
    "matplotlib",
    "emulator.hosting.daemon",
    "emulator.profiles.profile",
)

#: run `main(ARGS)` in a fresh interpreter; print every module it imported
PROBE = """
import json, sys
from emulator.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(json.dumps(sorted(sys.modules)))
"""


def imported_by(*args: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, check=True)
    return set(json.loads(out.stdout.splitlines()[-1]))


def ours(modules: set[str]) -> set[str]:
    return {name for name in modules if name.split(".")[0] in ("emulator", "protocols", "configs")}


def heavy(modules: set[str]) -> set[str]:
    return {name for name in modules if name.split(".")[0] in HEAVY or name in HEAVY}


def test_version_imports_only_the_group() -> None:
    modules = imported_by("--version")
    assert ours(modules) == {"emulator", "emulator.cli"}
    assert heavy(modules) == set()


def test_ctl_list_imports_only_the_control_client(tmp_path: Path) -> None:
    modules = imported_by("ctl", "--control", str(tmp_path / "none.sock"), "list")
    assert ours(modules) == {
        "emulator",
        "emulator.cli",
        "emulator.cli.common",
        "emulator.cli.ctl",
        "emulator.cli.names",
        "emulator.control_client",
        "emulator.storage",
        "emulator.storage.runtime",
    }
    assert heavy(modules) == set()


def test_serve_imports_one_family_only(tmp_path: Path) -> None:
    """`serve --profile ms2000` never imports the MP-285 model (here stopped at a bad link dir,
    after the profile is loaded)."""
    blocker = tmp_path / "file"
    blocker.write_text("")
    args = ["--link-dir", str(blocker / "links"), "--control", str(tmp_path / "c.sock"), "--no-state"]
    modules = imported_by("serve", "--profile", "ms2000", *args)
    assert "emulator.devices.ms2000" in modules
    assert not {name for name in modules if name.startswith("emulator.devices.mp285")}


def test_every_entry_is_its_command() -> None:
    ctx = click.Context(main, info_name="stage-emu")
    assert main.list_commands(ctx) == sorted(COMMANDS)
    for name in COMMANDS:
        command = main.get_command(ctx, name)
        assert isinstance(command, click.Command) and command.name == name


def listing(format_commands: Callable[[click.Context, click.HelpFormatter], None]) -> str:
    ctx = click.Context(main, info_name="stage-emu")
    # click's own width on any terminal 80 columns or wider (max_content_width 80, less 2)
    formatter = click.HelpFormatter(width=78)
    format_commands(ctx, formatter)
    return formatter.getvalue()


def test_the_listing_is_what_click_prints_from_the_commands() -> None:
    """The table's one-line help is each command's own, cut as click cuts it for the listing: the
    lazy listing cannot drift from the commands' docstrings."""
    eager = listing(partial(click.Group.format_commands, main))
    assert listing(main.format_commands) == eager
    assert all(name in eager for name in COMMANDS)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_subcommand_has_its_help(name: str) -> None:
    result = CliRunner().invoke(main, [name, "--help"])
    assert result.exit_code == 0, result.output
    assert result.output.startswith(f"Usage: main {name} ")


@pytest.mark.skipif(not hasattr(click.exceptions, "NoSuchCommand"), reason="click < 8.4 suggests nothing")
def test_a_mistyped_command_is_still_suggested() -> None:
    result = CliRunner().invoke(main, ["serv"])
    assert result.exit_code == 2
    assert "No such command 'serv'. Did you mean 'serve'?" in result.output
