"""What the daemon may create and remove on disk (emulator/storage/runtime.py, control socket claim).

The rule under test: the daemon removes only what it created; everything else is refused with one line.
"""

from __future__ import annotations

import asyncio
import fcntl
import json
import os
import socket
from pathlib import Path

import pytest

from emulator.hosting.clock import ScaledClock
from emulator.hosting.control import ControlServer
from emulator.storage import runtime
from emulator.storage.runtime import (
    LINK,
    READY,
    SOCKET,
    Ownership,
    SetupError,
    check_output_path,
    check_ready_file,
    check_socket_path,
    pid_alive,
    private_dir,
    remove_ready_file,
    runtime_dir,
    write_private_atomic,
)


def control_server(path: Path) -> ControlServer:
    return ControlServer(path, {}, ScaledClock())


def stale_socket(path: Path) -> None:
    """A socket file nobody listens on, as a crashed daemon leaves it."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.bind(str(path))
    sock.close()


@pytest.mark.parametrize("kind", ["file", "symlink", "directory"])
def test_control_path_that_is_not_a_socket_is_refused_and_kept(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "control.sock"
    target = tmp_path / "precious.txt"
    target.write_text("user data")
    if kind == "file":
        path.write_text("user data")
    elif kind == "symlink":
        path.symlink_to(target)
    else:
        path.mkdir()
    with pytest.raises(SetupError, match="not a socket; refusing to replace it"):
        asyncio.run(control_server(path).start())
    assert os.path.lexists(path) and target.read_text() == "user data"


def test_stale_control_socket_is_replaced(tmp_path: Path) -> None:
    path = tmp_path / "control.sock"
    stale_socket(path)

    async def scenario() -> None:
        server = control_server(path)
        await server.start()
        await server.stop()

    asyncio.run(scenario())
    assert not os.path.lexists(path)


def test_failed_second_server_leaves_the_running_ones_socket(tmp_path: Path) -> None:
    path = tmp_path / "control.sock"

    async def scenario() -> None:
        first = control_server(path)
        await first.start()
        second = control_server(path)
        with pytest.raises(SetupError, match="in use by a running stage-emu"):
            await second.start()
        await second.stop()  # what a failing `serve` does on its way out
        assert path.exists()
        reader, writer = await asyncio.open_unix_connection(str(path))
        writer.write(b'{"op": "list"}\n')
        assert json.loads(await reader.readline())["ok"] is True
        writer.close()
        await first.stop()

    asyncio.run(scenario())
    assert not os.path.lexists(path)


def test_socket_path_too_long_for_af_unix_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(SetupError, match="at most 107"):
        check_socket_path(tmp_path / ("x" * 120), "--control")


def test_runtime_dir_that_is_a_regular_file_is_refused(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    (tmp_path / "stage-emu").write_text("not a folder")
    with pytest.raises(SetupError, match="exists and is not a directory"):
        runtime_dir()
    assert (tmp_path / "stage-emu").read_text() == "not a folder"


def test_link_dir_that_cannot_be_created_is_one_line() -> None:
    with pytest.raises(SetupError, match="cannot create it"):
        private_dir(Path("/proc/nope"), "--link-dir")


def test_link_dir_is_created_0700_and_made_absolute(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    made = private_dir(Path("links"), "--link-dir")
    assert made == tmp_path / "links" and made.is_absolute()
    assert made.stat().st_mode & 0o777 == 0o700


@pytest.mark.parametrize("option", ["--control", "--ready-file", "--log-traffic"])
def test_output_path_in_a_missing_folder_is_one_line(tmp_path: Path, option: str) -> None:
    with pytest.raises(SetupError, match=f"{option} .*folder .* does not exist"):
        check_output_path(tmp_path / "missing" / "file", option)


def test_ready_file_replaces_only_a_stale_ready_file(tmp_path: Path) -> None:
    path = tmp_path / "ready.json"
    path.write_text("my notes\n")
    with pytest.raises(SetupError, match="not a stage-emu ready file"):
        check_ready_file(path)
    path.write_text(json.dumps({"ports": [], "control": "x", "pid": 1}))  # pid 1 is alive (init)
    with pytest.raises(SetupError, match="belongs to a running stage-emu"):
        check_ready_file(path)
    path.write_text(json.dumps({"ports": [], "control": "x", "pid": 2**22 + 1}))  # beyond pid_max
    check_ready_file(path)


def test_only_the_ready_file_we_wrote_is_removed(tmp_path: Path) -> None:
    path = tmp_path / "ready.json"
    ours = json.dumps({"ports": [], "control": "c", "pid": os.getpid()}) + "\n"
    identity = write_private_atomic(path, ours)
    assert path.stat().st_mode & 0o777 == 0o600
    other = tmp_path / "other.json"
    other.write_text("someone else's file")
    os.replace(other, path)  # replaced behind our back
    assert remove_ready_file(path, identity) is False
    assert path.read_text() == "someone else's file"
    path.unlink()
    path.write_text("a file that reuses the inode number")
    assert remove_ready_file(path, identity) is False
    assert path.exists()
    identity = write_private_atomic(path, ours)
    assert remove_ready_file(path, identity) is True
    assert not path.exists() and not list(tmp_path.glob("*.tmp"))


def write_lock(owners: Path, pid: int, entries: list[dict[str, object]]) -> Path:
    lock = owners / f"{pid}.lock"
    lock.write_text("".join(json.dumps(e) + "\n" for e in entries))
    return lock


def test_dead_daemons_links_socket_and_ready_file_are_reaped(tmp_path: Path) -> None:
    owners = tmp_path / "run" / "owners"
    owners.mkdir(parents=True, mode=0o700)
    master, slave = os.openpty()  # an unrelated process now owns the pts the dead daemon used
    try:
        link = tmp_path / "mp285"
        link.symlink_to(os.ttyname(slave))
        sock = tmp_path / "control.sock"
        stale_socket(sock)
        ready = tmp_path / "ready.json"
        ready.write_text(json.dumps({"ports": [], "control": str(sock), "pid": 999999}))
        user_file = tmp_path / "notes"
        user_file.write_text("keep")
        lock = write_lock(
            owners,
            999999,
            [
                {"kind": LINK, "path": str(link)},
                {"kind": SOCKET, "path": str(sock)},
                {"kind": READY, "path": str(ready), "pid": 999999},
                {"kind": LINK, "path": str(user_file)},  # replaced by a user file since: kept
            ],
        )
        ownership = Ownership(tmp_path / "run")
        ownership.acquire()
        ownership.release()
    finally:
        os.close(master)
        os.close(slave)
    assert not os.path.lexists(link) and not os.path.lexists(sock) and not ready.exists()
    assert user_file.read_text() == "keep"
    assert not lock.exists()


def test_live_daemons_entries_are_never_reaped(tmp_path: Path) -> None:
    owners = tmp_path / "run" / "owners"
    owners.mkdir(parents=True, mode=0o700)
    master, slave = os.openpty()
    link = tmp_path / "mp285"
    link.symlink_to(os.ttyname(slave))
    lock = write_lock(owners, 4242, [{"kind": LINK, "path": str(link)}])
    held = os.open(lock, os.O_RDWR)
    fcntl.flock(held, fcntl.LOCK_EX)  # a live daemon holds its lock
    try:
        # a dead daemon that listed the same path (the live one took it over) does not remove it
        write_lock(owners, 4343, [{"kind": LINK, "path": str(link)}])
        ownership = Ownership(tmp_path / "run")
        ownership.acquire()
        ownership.release()
        assert link.is_symlink()
        assert lock.exists() and not (owners / "4343.lock").exists()
    finally:
        os.close(held)
        os.close(master)
        os.close(slave)


def test_owner_record_lists_created_paths_and_goes_at_release(tmp_path: Path) -> None:
    ownership = Ownership(tmp_path)
    ownership.acquire()
    ownership.record(LINK, tmp_path / "a")
    lock = tmp_path / "owners" / f"{os.getpid()}.lock"
    assert json.loads(lock.read_text()) == {"kind": LINK, "path": str(tmp_path / "a")}
    assert (tmp_path / "owners").stat().st_mode & 0o777 == 0o700
    ownership.release()
    assert not lock.exists()


def test_off_posix_no_process_is_signalled_and_no_directory_opened(tmp_path: Path, monkeypatch) -> None:
    """The in-process URL's `state=DIR` runs on Windows, where `os.kill(pid, 0)` terminates the
    process and a directory cannot be opened as a file: neither may happen there."""

    def forbidden(*args: object) -> None:
        raise AssertionError(f"called off POSIX with {args}")

    assert not pid_alive(2**22 + 12345)  # POSIX: a pid no process has is gone
    monkeypatch.setattr(runtime, "POSIX", False)
    monkeypatch.setattr(os, "kill", forbidden)
    assert pid_alive(2**22 + 12345)  # taken as alive: a stale temporary file is left, no process ended
    real_open = os.open

    def no_directories(path: str | Path, flags: int, *args: int) -> int:
        if Path(path).is_dir():
            forbidden(path)
        return real_open(path, flags, *args)

    monkeypatch.setattr(os, "open", no_directories)
    write_private_atomic(tmp_path / "positions.json", "{}", sync_dir=True)
    assert (tmp_path / "positions.json").read_text() == "{}"
