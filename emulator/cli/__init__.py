"""`stage-emu`: serve a rig, list/validate/describe profiles, talk to a running daemon.

The group loads a subcommand's module (emulator/cli/*.py) only when that subcommand runs or shows its
help, so a command imports only what it needs: `ctl list` the control client, not the daemon, asyncio
or the device models. `stage-emu --help` lists every subcommand from `COMMANDS` without importing
any (tests/unit/test_cli_lazy.py checks the table against the commands' own help)."""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import click


@dataclass(frozen=True)
class Entry:
    """Where a subcommand lives, and the one line `stage-emu --help` shows for it: the command's
    own short help, as click would print it in an 80-column listing."""

    module: str
    attribute: str
    summary: str


COMMANDS: dict[str, Entry] = {
    "capture": Entry(
        "emulator.cli.capture", "capture", "Read a controller's identity and settings with read-only..."
    ),
    "ctl": Entry("emulator.cli.ctl", "ctl", "Talk to a running daemon over its control channel."),
    "describe": Entry(
        "emulator.cli.profiles",
        "describe",
        "Print every knob of PROFILE: value, default, allowed values...",
    ),
    "gcode": Entry(
        "emulator.cli.gcode", "gcode", "Run the G-code program FILE on an MS-2000 stage controller..."
    ),
    "plot": Entry(
        "emulator.cli.plot", "plot", "Draw the path a device's stage took in TRAFFIC_LOG (written..."
    ),
    "profiles": Entry("emulator.cli.profiles", "profiles", "List the bundled profiles."),
    "proxy": Entry(
        "emulator.cli.session", "proxy", "Put a pseudo-terminal in front of the controller on PORT and..."
    ),
    "replay": Entry(
        "emulator.cli.session", "replay_command", "Play the host side of SESSION (from `stage-emu proxy..."
    ),
    "serve": Entry(
        "emulator.cli.serve", "serve", "Serve RIG (default: the bundled rig, one MP-285 and one..."
    ),
    "trace": Entry(
        "emulator.cli.trace", "trace", "Show TRAFFIC_LOG (written by `stage-emu serve --log-traffic`)..."
    ),
    "validate": Entry(
        "emulator.cli.profiles", "validate", "Check profile or rig FILES; exit 1 with every problem, one..."
    ),
    "view": Entry(
        "emulator.cli.view", "view", "Live view of a running daemon: each device's positions, busy..."
    ),
}


class LazyGroup(click.Group):
    """A group whose subcommands are imported by name from `COMMANDS` when first resolved."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        entry = COMMANDS.get(cmd_name)
        if entry is None:
            return None
        command = getattr(importlib.import_module(entry.module), entry.attribute)
        assert isinstance(command, click.Command), entry
        return command

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        if args and args[0] not in COMMANDS:
            # click (8.4+) suggests the closest of the group's own `commands` for an unknown name:
            # name them all there (placeholders, never run: get_command resolves from the table)
            self.commands = {name: click.Command(name) for name in COMMANDS}
        return super().resolve_command(ctx, args)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The listing of click's own Group, from the table instead of every subcommand's module."""
        rows = [(name, COMMANDS[name].summary) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup)
@click.version_option(package_name="stage-emu")
def main() -> None:
    """Emulate Sutter MP-285 and ASI MS2000 controllers on pseudo-terminals."""
