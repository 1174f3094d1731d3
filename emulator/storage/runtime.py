"""The daemon's footprint on disk: the per-user runtime directory, the paths it may create, and a
record of what each running daemon created so that nothing else is ever removed.

Rule: the daemon removes only what it created. Each daemon holds an exclusive `flock` on
`<runtime dir>/owners/<pid>.lock` for its whole life and lists in it every link, socket and ready
file it creates. A lock file nobody holds belongs to a daemon that died (kill -9, power loss): the
next daemon removes the entries it listed that are still what that daemon made (a symlink to a pty,
a socket nobody listens on, a ready file naming its pid), then the lock file. A live daemon's lock
is held, so its entries are never touched.
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
import socket
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

log = logging.getLogger("stage_emu.runtime")

PTS_DIR = "/dev/pts/"
#: AF_UNIX `sun_path` holds 108 bytes including the terminating NUL
MAX_SOCKET_PATH = 107
LINK, SOCKET, READY = "link", "socket", "ready"
#: the in-process URL (`state=DIR`) also runs on Windows, where a few POSIX idioms here are harmful
POSIX = os.name == "posix"


class SetupError(Exception):
    """A path the daemon cannot use; the message is one line that says why and what to do."""


def runtime_dir() -> Path:
    """Per-user directory for port links, the control socket and owner records: created 0700 and
    checked to be a directory of ours ($XDG_RUNTIME_DIR/stage-emu, else /tmp/stage-emu-<uid>)."""
    base = os.environ.get("XDG_RUNTIME_DIR")
    path = Path(base) / "stage-emu" if base else Path(f"/tmp/stage-emu-{os.getuid()}")
    return private_dir(path, "runtime directory", ours=True)


def private_dir(path: Path, what: str, *, ours: bool = False) -> Path:
    """Create `path` (mode 0700) if missing and return it absolute. A directory of `ours` (in a
    shared place such as /tmp) must be a real directory owned by this user and is kept 0700; a
    folder the user named (`--link-dir`) may be any directory, symlinked or not, and keeps its mode."""
    path = path.expanduser().absolute()
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
    except FileExistsError:
        message = f"{what} {path} exists and is not a directory; remove it or choose another"
        raise SetupError(message) from None
    except OSError as exc:
        raise SetupError(f"{what} {path}: cannot create it: {exc.strerror or exc}") from None
    if not ours:
        return path
    info = path.lstat()
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
        raise SetupError(f"{what} {path} is not a directory owned by you; refusing to use it")
    if stat.S_IMODE(info.st_mode) & 0o077:
        os.chmod(path, 0o700)
    return path


def check_output_path(path: Path, option: str) -> Path:
    """A file the daemon will create: its folder must exist and be a folder. Returns it absolute."""
    path = path.expanduser().absolute()
    parent = path.parent
    if not parent.is_dir():
        reason = "does not exist" if not parent.exists() else "is not a directory"
        raise SetupError(f"{option} {path}: folder {parent} {reason}")
    if path.is_dir():
        raise SetupError(f"{option} {path} is a directory")
    return path


def check_socket_path(path: Path, option: str) -> None:
    size = len(os.fsencode(str(path)))
    if size > MAX_SOCKET_PATH:
        raise SetupError(
            f"{option} {path} is {size} bytes long; a Unix socket path holds at most "
            f"{MAX_SOCKET_PATH}: choose a shorter path"
        )


def pid_alive(pid: int) -> bool:
    """Whether `pid` may still be a process. Only "no such process" (or a number no process can
    have) counts as gone: another user's process, or any other refusal, is taken as alive, so what
    it owns is left alone. Off POSIX every pid counts as alive: on Windows `os.kill(pid, 0)` is no
    probe but TerminateProcess, which would end whatever process now has that number."""
    if not POSIX:
        return True
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):
        return False
    except OSError:
        return True
    return True


def socket_is_live(path: Path) -> bool:
    """True when something accepts connections on the Unix socket at `path`."""
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.connect(str(path))
    except OSError as exc:
        if exc.errno in (errno.ECONNREFUSED, errno.ENOENT):
            return False
        raise SetupError(f"{path}: cannot tell whether it is in use: {exc.strerror or exc}") from None
    finally:
        probe.close()
    return True


def write_private_atomic(path: Path, text: str, *, sync_dir: bool = False) -> tuple[int, int]:
    """Write `text` to `path` mode 0600 through a uniquely named temporary file in the same folder
    (flush, fsync, rename; with `sync_dir` the rename itself is made durable): readers see the old
    file or the new one, never a part, even after a kill -9. The temporary file's name carries the
    writer's pid (`.<name>.<pid>.<random>.tmp`), so a later run can tell a dead writer's leftover.
    Returns the new file's (st_dev, st_ino) so that only this very file is removed later."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
            info = os.fstat(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    if sync_dir and POSIX:  # Windows opens no directory as a file; NTFS journals renames
        dir_fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)
    return info.st_dev, info.st_ino


def remove_ready_file(path: Path, identity: tuple[int, int] | None) -> bool:
    """Unlink our ready file only if it is still the file (device, inode) we wrote and still names
    this process (an inode number can be reused by a file someone put there since)."""
    if identity is None:
        return False
    try:
        info = path.lstat()
    except FileNotFoundError:
        return False
    if (info.st_dev, info.st_ino) != identity or read_ready_pid(path) != os.getpid():
        return False
    path.unlink()
    return True


def read_ready_pid(path: Path) -> int | None:
    """The `pid` of a stage-emu ready file, or None when `path` is not one (never echoes content)."""
    try:
        info = path.lstat()
        if not stat.S_ISREG(info.st_mode) or info.st_size > 1 << 20:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if isinstance(data, dict) and isinstance(data.get("pid"), int) and "ports" in data:
        return int(data["pid"])
    return None


def check_ready_file(path: Path) -> None:
    """A ready file may replace only a stale ready file (its daemon is gone)."""
    if not os.path.lexists(path):
        return
    pid = read_ready_pid(path)
    if pid is None:
        raise SetupError(
            f"--ready-file {path} exists and is not a stage-emu ready file; refusing to overwrite it"
        )
    if pid != os.getpid() and pid_alive(pid):
        raise SetupError(f"--ready-file {path} belongs to a running stage-emu (pid {pid}); choose another")


@dataclass
class Ownership:
    """This daemon's owner record: a held lock file listing what it created (see module doc)."""

    directory: Path
    _fd: int = -1
    _path: Path | None = None
    _entries: list[dict[str, Any]] = field(default_factory=list)

    def acquire(self) -> None:
        import fcntl  # POSIX only, and only the daemon locks: the models load on Windows too

        owners = private_dir(self.directory / "owners", "owner records folder", ours=True)
        self.reap(owners)
        path = owners / f"{os.getpid()}.lock"
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        fcntl.flock(fd, fcntl.LOCK_EX)
        self._fd, self._path = fd, path

    def record(self, kind: str, path: Path, **extra: Any) -> None:
        """Note a created path; written through at once so a kill -9 leaves it listed."""
        if self._fd < 0:
            return
        entry = {"kind": kind, "path": str(path), **extra}
        self._entries.append(entry)
        os.write(self._fd, (json.dumps(entry) + "\n").encode())

    def release(self) -> None:
        if self._fd < 0:
            return
        assert self._path is not None
        with contextlib.suppress(FileNotFoundError):
            self._path.unlink()
        os.close(self._fd)
        self._fd = -1

    def reap(self, owners: Path) -> None:
        """Remove what dead daemons left behind (only what they listed and is still theirs)."""
        import fcntl  # POSIX only (see Ownership.acquire)

        for lock in sorted(owners.glob("*.lock")):
            if not lock.stem.isdigit():
                continue
            try:
                fd = os.open(lock, os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC)
            except OSError:
                continue
            try:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    continue  # a live daemon holds it
                entries = _parse_entries(os.read(fd, 1 << 20))
                claimed = live_claims(owners, exclude=lock)
                removed = [e["path"] for e in entries if e.get("path") not in claimed and _remove_stale(e)]
                if removed:
                    what = ", ".join(removed)
                    log.warning("removed what a stopped stage-emu (pid %s) left behind: %s", lock.stem, what)
                with contextlib.suppress(FileNotFoundError):
                    lock.unlink()
            finally:
                os.close(fd)


def live_claims(owners: Path, exclude: Path) -> set[str]:
    """Paths listed by daemons that are still running (their lock is held), `exclude` aside."""
    claimed: set[str] = set()
    for lock in sorted(owners.glob("*.lock")):
        entries = None if lock == exclude else _held_entries(lock)
        if entries is not None:
            claimed.update(str(e.get("path")) for e in entries)
    return claimed


def _held_entries(lock: Path) -> list[dict[str, Any]] | None:
    """The entries of a lock file whose daemon is alive; None when nobody holds it."""
    import fcntl  # POSIX only (see Ownership.acquire)

    try:
        fd = os.open(lock, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _parse_entries(os.read(fd, 1 << 20))
        return None
    finally:
        os.close(fd)


def _parse_entries(raw: bytes) -> list[dict[str, Any]]:
    entries = []
    for line in raw.splitlines():
        try:
            entry = json.loads(line)
        except ValueError:
            continue  # a line cut short by kill -9
        if isinstance(entry, dict) and isinstance(entry.get("path"), str):
            entries.append(entry)
    return entries


def _remove_stale(entry: dict[str, Any]) -> bool:
    """Remove one path a dead daemon listed, only if it is still of the kind it made."""
    path = Path(entry["path"])
    try:
        info = path.lstat()
    except OSError:
        return False
    kind = entry.get("kind")
    if kind == LINK:
        if not stat.S_ISLNK(info.st_mode) or not os.readlink(path).startswith(PTS_DIR):
            return False
    elif kind == SOCKET:
        if not stat.S_ISSOCK(info.st_mode):
            return False
        try:
            if socket_is_live(path):
                return False
        except SetupError:
            return False
    elif kind == READY:
        if read_ready_pid(path) != entry.get("pid"):
            return False
    else:
        return False
    try:
        path.unlink()
    except OSError:
        return False
    return True
