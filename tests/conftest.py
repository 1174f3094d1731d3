"""Shared pytest options: `--port PATH --device FAMILY` runs the conformance suite on real hardware."""

from __future__ import annotations

import os

import pytest

FAMILIES = ("mp285", "ms2000")
EMULATOR_ONLY = ("control", "timing")


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("stage-emu")
    group.addoption("--port", help="serial port of a real controller: run tests/conformance against it")
    group.addoption("--device", choices=FAMILIES, help="which controller is on --port")
    group.addoption("--baud", type=int, help="baud rate of the real controller (default: the profile's)")
    group.addoption(
        "--aux-port",
        help="the real controller's auxiliary port (TTL REPORT frames); tests needing it skip without",
    )
    group.addoption(
        "--target",
        choices=("virtual", "daemon", "serial"),
        default="virtual",
        help="where tests/conformance runs without --port: the emulator in process, in virtual time "
        "(default), a daemon's pseudo-terminals in real time, or a daemon's serial port on a "
        "null-modem cable of two pseudo-terminals",
    )


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """`-n auto` (make test): two workers per CPU. Much of the suite waits on real time rather than
    computing (daemons starting and stopping, the smoke runs' paced wires, subprocesses), so one
    worker per CPU leaves CPUs idle: on this 2-core machine the run takes 111 s with two workers and
    79 s with four."""
    del config
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return 2 * cpus


def pytest_configure(config: pytest.Config) -> None:
    if config.getoption("--port") and not config.getoption("--device"):
        raise pytest.UsageError("--port needs --device (mp285 or ms2000)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if not config.getoption("--port"):
        return
    family = config.getoption("--device")
    for item in items:
        marks = [m for m in EMULATOR_ONLY if item.get_closest_marker(m)]
        if marks:
            item.add_marker(
                pytest.mark.skip(reason=f"needs the emulator ({', '.join(marks)}); running on a real port")
            )
        elif "conformance" not in item.nodeid.split("/"):
            item.add_marker(pytest.mark.skip(reason="only the conformance suite runs against a real port"))
        elif f"/{family}/" not in f"/{item.nodeid}" and any(f"/{f}/" in f"/{item.nodeid}" for f in FAMILIES):
            item.add_marker(pytest.mark.skip(reason=f"suite for another controller than --device {family}"))
