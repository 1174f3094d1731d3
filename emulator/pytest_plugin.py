"""pytest plugin (entry point `pytest11: stage_emu`): emulated controllers for a user's own tests.

    def test_move(stage_emu):
        emu = stage_emu(profiles=["ms2000"])      # a daemon of its own, stopped after the test
        port = serial.Serial(emu.port("ms2000"), 9600, timeout=2)
        emu.control.input("ms2000", "joystick", x=0.5)

`stage_emu` starts a daemon per call and stops it when the test ends, passed or failed;
`stage_emu_session` returns the same daemon for the same arguments all session long. With
`time="virtual"` the devices run in the test's process instead, in virtual time
(emulator/pytest_virtual.py): `emu.port(...)` is then a `stageemu://` URL, opened with
`serial.serial_for_url`. Each daemon
lives in a private temporary directory: its links, control socket, state and owner records (its
runtime directory) never touch the user's. With `--stage-emu-port PATH --stage-emu-device NAME` the
fixtures start nothing and hand out the real port instead (`.control` is None), and tests marked
`stage_emu_control`, `stage_emu_timing` or `stage_emu_modem` are skipped.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from emulator.control_client import ControlRequests
    from emulator.hosting.launcher import RunningDaemon
    from emulator.urlhandler.hosted import HostedDevice

#: marker -> what a test marked with it needs that only the emulator has
EMULATOR_ONLY = {
    "stage_emu_control": "the emulator's control channel",
    "stage_emu_timing": "exact timing that only the emulator guarantees",
    "stage_emu_modem": "modem lines driven through the emulator",
}
#: `serve` options the plugin sets itself: they keep the daemon inside its private directory
PLUGIN_OWNED = ("control", "link_dir", "state_dir")


def pytest_addoption(parser: pytest.Parser) -> None:
    # namespaced: a project's own conftest may well define --port/--device (this one does)
    group = parser.getgroup("stage_emu", "stage-emu fixtures: emulated controllers, or a real one")
    group.addoption(
        "--stage-emu-port",
        metavar="PATH",
        help="serial port of a real controller: the stage_emu fixtures hand it out instead of "
        "starting the emulator, and tests needing the emulator skip",
    )
    group.addoption(
        "--stage-emu-device",
        metavar="NAME",
        help="the device name tests ask for on --stage-emu-port (e.g. ms2000)",
    )


def pytest_configure(config: pytest.Config) -> None:
    for marker, needs in EMULATOR_ONLY.items():
        config.addinivalue_line("markers", f"{marker}: needs {needs} (skipped with --stage-emu-port)")
    if config.getoption("stage_emu_port") and not config.getoption("stage_emu_device"):
        raise pytest.UsageError("--stage-emu-port needs --stage-emu-device (the name tests ask for)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    port = config.getoption("stage_emu_port")
    if not port:
        return
    for item in items:
        needs = [needs for marker, needs in EMULATOR_ONLY.items() if item.get_closest_marker(marker)]
        if needs:
            reason = f"needs {' and '.join(needs)}; --stage-emu-port {port} is a real controller"
            item.add_marker(pytest.mark.skip(reason=reason))


@dataclass
class StageEmu:
    """What the fixtures return: the ports by link name (`ms2000`, `ms2000-ttlrep.aux`), the
    control client and the daemon (both None on a real port; no daemon in virtual time, where
    `devices` holds the in-process devices)."""

    ports: dict[str, str]
    control: ControlRequests | None
    daemon: RunningDaemon | None
    devices: dict[str, HostedDevice] = field(default_factory=dict)

    @property
    def virtual(self) -> bool:
        return bool(self.devices)

    def advance(self, seconds: float) -> None:
        """Let `seconds` of device time pass at once on every device (virtual time only)."""
        if not self.virtual:
            raise RuntimeError("advance needs time='virtual' (a daemon's time runs by itself)")
        from emulator.pytest_virtual import advance

        advance(self.devices, seconds)

    def sleep(self, seconds: float) -> None:
        """A stand-in for `time.sleep` in a host program under test: in virtual time the devices'
        time passes instead of the wall clock's (monkeypatch the host's sleep with it); otherwise
        it is `time.sleep`."""
        if self.virtual:
            self.advance(seconds)
        else:
            time.sleep(seconds)

    def port(self, device: str, channel: str = "main") -> str:
        name = device if channel == "main" else f"{device}.{channel}"
        if name in self.ports:
            return self.ports[name]
        if self.daemon is None:
            pytest.skip(f"needs {name}; --stage-emu-port is {', '.join(self.ports)}")
        raise KeyError(f"{name!r} is not served; the ports are {', '.join(self.ports)}")


class StageEmuFactory:
    """`factory(profiles=("ms2000",), rig=None, timing="fast", time_scale=1.0, time="real",
    **options)`.

    Serves `profiles` (`NAME[:LINK]`, as `serve --profile`) or a `rig` file (relative to the
    rootdir); further `serve` options by keyword: `log_traffic=path`, `verbose=True`. With `reuse`,
    calls with the same arguments share one daemon. `time="virtual"` serves `profiles` in this
    process in virtual time instead (no daemon, no rig, no options). `close` stops every daemon
    started and switches every in-process device off."""

    def __init__(self, config: pytest.Config, *, reuse: bool) -> None:
        self._config = config
        self._reuse = reuse
        self._started: dict[str, StageEmu] = {}

    def __call__(
        self,
        profiles: Sequence[str] = ("ms2000",),
        rig: str | Path | None = None,
        timing: str | None = "fast",
        time_scale: float = 1.0,
        time: str = "real",
        **options: Any,
    ) -> StageEmu:
        real_port = self._config.getoption("stage_emu_port")
        if real_port:
            return StageEmu({self._config.getoption("stage_emu_device"): real_port}, None, None)
        if isinstance(profiles, str):  # `profiles="ms2000"` would otherwise serve m, s, 2...
            profiles = [profiles]
        if time not in ("real", "virtual"):
            raise TypeError(f"stage_emu: time must be 'real' or 'virtual', got {time!r}")
        if time == "virtual" and (rig is not None or options or time_scale != 1.0):
            raise TypeError("stage_emu: virtual time serves profiles only (no rig, options or time_scale)")
        rig_path = None if rig is None else self._config.rootpath / rig
        key = repr((list(profiles), rig_path, timing, time_scale, time, sorted(options.items())))
        if not self._reuse:
            key += f"#{len(self._started)}"
        if key not in self._started and time == "virtual":
            self._started[key] = _serve_virtual(profiles, timing or "realistic")
        if key not in self._started:
            args = [str(rig_path)] if rig_path else [word for p in profiles for word in ("--profile", p)]
            if timing is not None:
                args += ["--timing", timing]
            args += ["--time-scale", str(time_scale), *_serve_flags(options)]
            self._started[key] = _launch(args, _port_count(profiles, rig_path))
        return self._started[key]

    def close(self) -> None:
        started, self._started = list(self._started.values()), {}
        with contextlib.ExitStack() as stopping:  # every daemon is stopped even if one stop raises
            for emu in started:
                for device in emu.devices.values():
                    stopping.callback(device.close)
                if emu.daemon is not None:
                    stopping.callback(shutil.rmtree, emu.daemon.workdir, ignore_errors=True)
                    stopping.callback(_stop, emu.daemon)


def _serve_flags(options: dict[str, Any]) -> list[str]:
    """`log_traffic="t.jsonl"` -> `--log-traffic t.jsonl`, `verbose=True` -> `--verbose`."""
    flags: list[str] = []
    for key, value in options.items():
        if key in PLUGIN_OWNED:
            raise TypeError(f"stage_emu: {key} is set by the plugin (a private temporary directory)")
        flag = "--" + key.replace("_", "-")
        if value is True:
            flags.append(flag)
        elif value is not None and value is not False:
            flags += [flag, str(value)]
    return flags


def _port_count(profiles: Sequence[str], rig: Path | None) -> int:
    """How many readiness lines the daemon prints: one per port of the rig it will serve."""
    from emulator.hosting.rig import load_rig, rig_from_profiles

    spec = load_rig(rig) if rig is not None else rig_from_profiles(list(profiles))
    return sum(len(device.ports) for device in spec.devices)


def _serve_virtual(profiles: Sequence[str], timing: str) -> StageEmu:
    # imported here: most test runs of the environment never serve a device
    import emulator.urlhandler  # noqa: F401  (teaches pyserial the stageemu:// URLs it hands out)
    from emulator.pytest_virtual import InProcessControls, ports_of, serve_virtual

    devices = serve_virtual(profiles, timing)
    return StageEmu(ports_of(devices), InProcessControls(devices), None, devices)


def _launch(args: list[str], port_count: int) -> StageEmu:
    # imported here, not at the top: pytest loads this plugin in every run of the environment,
    # most of which never start a daemon
    from emulator.hosting.launcher import start_daemon

    # not under pytest's basetemp: that can be too deep for the control socket's path (107 bytes)
    workdir = Path(tempfile.mkdtemp(prefix="stage-emu-"))
    # the daemon keeps owner records (and reaps stale ones) in its runtime directory: a private one
    env = {**os.environ, "XDG_RUNTIME_DIR": str(workdir / "run")}
    daemon: RunningDaemon | None = None
    try:
        daemon = start_daemon(workdir, args, port_count, env=env)
        control = daemon.control()
    except BaseException:
        if daemon is not None:
            _stop(daemon)
        shutil.rmtree(workdir, ignore_errors=True)
        raise
    ports = {
        p["device"] if p["port"] == "main" else f"{p['device']}.{p['port']}": p["path"] for p in daemon.ports
    }
    return StageEmu(ports, control, daemon)


def _stop(daemon: RunningDaemon) -> None:
    try:
        daemon.stop()
    except subprocess.TimeoutExpired:  # stuck past the clean-shutdown wait: no process may outlive the test
        daemon.proc.kill()
        daemon.proc.wait()


@pytest.fixture
def stage_emu(request: pytest.FixtureRequest) -> Iterator[StageEmuFactory]:
    """Start emulator daemons for this test: `stage_emu(profiles=["ms2000"])` -> `StageEmu`."""
    factory = StageEmuFactory(request.config, reuse=False)
    yield factory
    factory.close()


@pytest.fixture(scope="session")
def stage_emu_session(request: pytest.FixtureRequest) -> Iterator[StageEmuFactory]:
    """Like `stage_emu`, but one daemon per distinct arguments for the whole session (the devices
    keep their state from test to test: `emu.control.reset(device)` for a fresh one)."""
    factory = StageEmuFactory(request.config, reuse=True)
    yield factory
    factory.close()
