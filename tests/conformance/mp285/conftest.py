"""The MP-285 suite's fixtures: the emulator's log of the device a test talks to."""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from tests.conformance.conftest import DaemonPool
from tests.conformance.mp285.wire import DaemonLog, DeviceLog, Host, HostedLog

LogOf = Callable[..., DeviceLog]


@pytest.fixture
def log_of(daemon_pool: DaemonPool) -> Iterator[LogOf]:
    """`log_of(host, overrides=None, profile="mp285")`: the emulator's warnings about `host`'s
    device from now on (the daemon serving the profile and overrides `host` was opened with, or the
    device served in this process)."""
    handlers: list[HostedLog] = []
    logger = logging.getLogger("stage_emu")

    def factory(host: Host, overrides: dict[str, Any] | None = None, profile: str = "mp285") -> DeviceLog:
        if host.target.virtual:
            handlers.append(HostedLog(host.target))
            logger.addHandler(handlers[-1])
            return handlers[-1]
        log = DaemonLog(daemon_pool.get(profile, overrides, "realistic"))
        log.drain()
        return log

    yield factory
    for handler in handlers:
        logger.removeHandler(handler)
