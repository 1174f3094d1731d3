"""The pytest plugin's virtual time (`stage_emu(profiles=[...], time="virtual")`): the devices run in
the test's own process, no daemon, and device time passes only while the host program waits on a
port (a read with a timeout, a write the wire has no room for) or the test says so (`emu.advance`),
at once: a 10 s move costs no wall time, and every instant is exact whatever the machine's load.

Each device keeps its own clock, moved by waits on its own ports; `advance` and `sleep` move every
device's clock together. A host that sleeps on the wall clock between polls (`time.sleep`) lets no
device time pass by sleeping: patch its sleep with `emu.sleep` (monkeypatch), or leave it, and only
its polls' own wire time passes (more polls per device second, the same outcome).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from functools import partial
from typing import Any

from emulator.control_client import ControlFailure, ControlRequests
from emulator.hosting.clock import VirtualClock
from emulator.urlhandler.control import HostedControl
from emulator.urlhandler.hosted import HostedDevice, serve
from emulator.urlhandler.url import VIRTUAL, UrlOptions


def serve_virtual(profiles: Sequence[str], timing: str) -> dict[str, HostedDevice]:
    """One device per profile, named as `stage-emu serve --profile` names them (`ms2000`, then
    `ms2000-2` for the same profile again)."""
    from emulator.hosting.rig import rig_from_profiles

    names = [device.name for device in rig_from_profiles(list(profiles)).devices]
    devices: dict[str, HostedDevice] = {}
    try:
        for name, profile in zip(names, profiles, strict=True):
            devices[name] = serve(UrlOptions(profile=profile, timing=timing, time=VIRTUAL))
    except BaseException:
        for device in devices.values():
            device.close()
        raise
    return devices


def ports_of(devices: dict[str, HostedDevice]) -> dict[str, str]:
    """Every port's URL by the daemon's link name (`ms2000`, `ms2000-ttlrep.aux`)."""
    return {
        name if channel == "main" else f"{name}.{channel}": device.url(channel)
        for name, device in devices.items()
        for channel in device.channels
    }


def advance(devices: dict[str, HostedDevice], seconds: float) -> None:
    """`seconds` of device time pass on every device, at once."""
    for device in devices.values():
        clock = device.clock
        assert isinstance(clock, VirtualClock)  # served in virtual time
        device.call(partial(clock.step, seconds))


class InProcessControls(ControlRequests):
    """The control channel of several in-process devices, as a daemon serving them all answers it:
    device requests go to the device named, `list` lists them all, clock requests reach every
    device's clock. Events come from the one device subscribed to."""

    def __init__(self, devices: dict[str, HostedDevice]) -> None:
        self._controls = {name: HostedControl(device, name) for name, device in devices.items()}
        self._subscribed: HostedControl | None = None

    def request(self, request: dict[str, Any]) -> Any:
        if "device" in request:
            control = self._controls.get(request["device"])
            if control is None:
                raise ControlFailure(f"no device {request['device']!r}; devices: {', '.join(self._controls)}")
            if request.get("op") == "subscribe" and not request.get("traffic"):
                if self._subscribed not in (None, control):
                    raise ControlFailure("in virtual time, events come from one device at a time")
                self._subscribed = control
            return control.request(request)
        if request.get("op") == "list":
            return [entry for control in self._controls.values() for entry in control.request(request)]
        answers = [control.request(request) for control in self._controls.values()]
        return answers[0] if answers else None

    def events(self, timeout: float | None = None) -> Iterator[dict[str, Any]]:
        if self._subscribed is not None:
            yield from self._subscribed.events(timeout)
