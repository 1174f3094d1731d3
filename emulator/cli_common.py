"""What every `stage-emu` command shares: the one-line failure and the control-channel connection."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import NoReturn

import click

from emulator.control_client import ControlClient
from emulator.runtime import SetupError, runtime_dir


def fail(message: str, code: int = 1) -> NoReturn:
    """`stage-emu: message` on stderr, then exit `code`: bad input is one line, never a traceback."""
    click.echo(f"stage-emu: {message}", err=True)
    sys.exit(code)


def connect(control: Path | None) -> ControlClient:
    """The running daemon's control channel (`control`, else the default socket), or a one-line exit."""
    try:
        path = control or runtime_dir() / "control.sock"
    except SetupError as exc:
        fail(str(exc))
    try:
        return ControlClient(path)
    except OSError as exc:
        fail(f"cannot reach the daemon at {path}: {exc.strerror or exc} (is `stage-emu serve` running?)")
