"""The transports a port can use, by kind (a rig port's `transport`): each kind's factory builds
the transport for one port. The daemon creates every port through `create`."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from emulator.hosting.transports.base import Transport

if TYPE_CHECKING:
    from emulator.hosting.rig import PortSpec

#: (the port's spec, its link path (PTY ports), the daemon's loop) -> the transport, not yet open
Factory = Callable[["PortSpec", Path, asyncio.AbstractEventLoop], Transport]


# Each transport module is imported only when a port of its kind is made: they need termios and
# fcntl (POSIX only), and this package is imported with every runner, also where none of them is
# used (the in-process `stageemu://` URL handler, on Windows too).
def _pty(spec: PortSpec, link: Path, loop: asyncio.AbstractEventLoop) -> Transport:
    from emulator.hosting.transports.pty import PtyTransport

    return PtyTransport(link, spec.mode, loop)


def _tcp(spec: PortSpec, link: Path, loop: asyncio.AbstractEventLoop) -> Transport:
    from emulator.hosting.transports.tcp import TcpTransport

    return TcpTransport(spec.bind, spec.port or 0, loop)


def _rfc2217(spec: PortSpec, link: Path, loop: asyncio.AbstractEventLoop) -> Transport:
    from emulator.hosting.transports.rfc2217 import Rfc2217Transport

    return Rfc2217Transport(spec.bind, spec.port or 0, loop)


def _serial(spec: PortSpec, link: Path, loop: asyncio.AbstractEventLoop) -> Transport:
    from emulator.hosting.transports.serial import SerialTransport

    assert spec.device is not None  # the rig requires it
    return SerialTransport(spec.device, loop)


#: by kind (each transport class's `kind`)
FACTORIES: dict[str, Factory] = {"pty": _pty, "tcp": _tcp, "rfc2217": _rfc2217, "serial": _serial}
KINDS = tuple(FACTORIES)
#: the kinds that listen on a network address (`bind`, `port`) rather than create a link
NETWORK_KINDS = ("tcp", "rfc2217")
#: the kinds that open an existing serial device (`device`) rather than create a port
DEVICE_KINDS = ("serial",)


def create(spec: PortSpec, link: Path, loop: asyncio.AbstractEventLoop) -> Transport:
    return FACTORIES[spec.transport](spec, link, loop)
