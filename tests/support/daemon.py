"""The daemon launcher for tests: the product's own (emulator/hosting/launcher.py), run from the repository
with the test-only probe family registered when asked."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from emulator.hosting.launcher import RunningDaemon
from emulator.hosting.launcher import start_daemon as launch

ROOT = Path(__file__).resolve().parents[2]

__all__ = ["ROOT", "RunningDaemon", "start_daemon"]


def start_daemon(
    workdir: Path,
    args: list[str],
    expect_ports: int,
    test_devices: bool = False,
    env: dict[str, str] | None = None,
    preexec_fn: Callable[[], None] | None = None,
) -> RunningDaemon:
    """`stage-emu serve ARGS` under `workdir`; `test_devices` adds the probe family."""
    return launch(
        workdir,
        args,
        expect_ports,
        entry="tests.support.serve" if test_devices else "emulator.cli",
        cwd=ROOT,
        env=env or {**os.environ, "PYTHONPATH": str(ROOT)},
        preexec_fn=preexec_fn,
    )
