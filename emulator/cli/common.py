"""What every `stage-emu` command shares: the one-line failure, the control-channel connection and the
clock's number options. Imported by every subcommand, so it imports nothing beyond click at load time
(emulator/cli/__init__.py loads a subcommand's dependencies only when it runs)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NoReturn

import click

if TYPE_CHECKING:
    from emulator.control_client import ControlClient


def fail(message: str, code: int = 1) -> NoReturn:
    """`stage-emu: message` on stderr, then exit `code`: bad input is one line, never a traceback."""
    click.echo(f"stage-emu: {message}", err=True)
    sys.exit(code)


def connect(control: Path | None) -> ControlClient:
    """The running daemon's control channel (`control`, else the default socket), or a one-line exit."""
    from emulator.control_client import ControlClient
    from emulator.storage.runtime import SetupError, runtime_dir

    try:
        path = control or runtime_dir() / "control.sock"
    except SetupError as exc:
        fail(str(exc))
    try:
        return ControlClient(path)
    except OSError as exc:
        fail(f"cannot reach the daemon at {path}: {exc.strerror or exc} (is `stage-emu serve` running?)")


class ClockNumber(click.ParamType):
    """A time scale or a clock step, checked by emulator.hosting.clock (finite, in range) with its message as
    the usage error. emulator.hosting.clock is imported only when the option is given or its help shown:
    `ctl list` must not pay for the clock's imports."""

    name = "number"

    def __init__(self, kind: Literal["scale", "step"]) -> None:
        self._kind = kind

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        from emulator.hosting import clock

        check = clock.check_scale if self._kind == "scale" else clock.check_step
        try:
            return float(check(float(value)))
        except ValueError as exc:
            self.fail(str(exc), param, ctx)

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        from emulator.hosting import clock

        if self._kind == "scale":
            return f"[{clock.MIN_SCALE:g}..{clock.MAX_SCALE:g}]"
        return f"[0..{clock.MAX_STEP:g}]"


TIME_SCALE = ClockNumber("scale")
STEP_SECONDS = ClockNumber("step")
