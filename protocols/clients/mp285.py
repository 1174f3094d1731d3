"""Thin host library for the Sutter MP-285 / MP-285A (pyserial only): the same on a real port and on
stage-emu.

    from protocols.clients.mp285 import Mp285
    with Mp285.open("/dev/ttyUSB0") as stage:       # MP-285A on USB: rtscts=True, model="mp285a"
        stage.set_velocity(1000)                     # µm/s, low resolution
        stage.move_to_um(100.0, -50.0, 0.0)          # returns once the move's CR has arrived
        print(stage.position_um())                   # (100.0, -50.0, 0.0)

Replies have fixed lengths and may contain CR bytes, so everything is read by count (MP-10). An
error reply `<digit> CR` in place of a reply raises an `Mp285Error` subclass carrying the digit
(MP-19). The device cannot report its move mode (MP-34), so the client tracks it, and the velocity,
from what it sent. Moves and programs wait for their final CR with a timeout derived from the
distance, the tracked speed and the settle time (MP-43, MP-44) plus a margin. Only ^C may be sent
while a move is outstanding (MP-12): start one with `wait=False`, then `wait()` or `interrupt()`.
The client never touches the modem lines.

Assumed device behaviour (the documented defaults): program move vectors are displacements
(MP-69) and `k`/`e` answer at a pause vector (MP-68).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import serial

from protocols import mp285 as proto
from protocols.clients.errors import NoReply
from protocols.mp285 import CR, ErrorCode, SpeedLimits, StatusBlock, Vector, Velocity

Xyz = tuple[int, int, int]


class Mp285Error(Exception):
    """The controller answered `<digit> CR` instead of the command's reply (MP-19)."""

    code: int = 0

    def __init__(self, command: str, code: int | None = None) -> None:
        self.command = command
        if code is not None:
            self.code = code
        super().__init__(f"{command}: error '{chr(self.code)}' ({proto.error_text(self.code)})")


class SpOverrun(Mp285Error):
    code = ErrorCode.SP_OVERRUN


class FrameError(Mp285Error):
    code = ErrorCode.FRAME


class BufferOverrun(Mp285Error):
    code = ErrorCode.BUFFER_OVERRUN


class BadCommand(Mp285Error):
    code = ErrorCode.BAD_COMMAND


class MoveInterrupted(Mp285Error):
    """'8', or '8' ORed with another code ('<' = '8' | '4'): `code` keeps the digit received."""

    code = ErrorCode.MOVE_INTERRUPTED


ERRORS: dict[int, type[Mp285Error]] = {
    cls.code: cls for cls in (SpOverrun, FrameError, BufferOverrun, BadCommand, MoveInterrupted)
}


def error_for(code: int, command: str) -> Mp285Error:
    """The exception for error digit `code`."""
    if code in ERRORS:
        return ERRORS[code](command)
    if proto.is_error_code(code):
        return MoveInterrupted(command, code)
    return Mp285Error(command, code)


class UnexpectedReply(Exception):
    """Bytes that are neither the command's reply nor an error reply."""


class MoveOutstanding(Exception):
    """A command other than ^C was attempted while a move or program had not answered (MP-12)."""


@dataclass(frozen=True)
class _Outstanding:
    """A sent `m`, `k` or `e` whose final CR has not been read yet."""

    command: str
    timeout: float
    program: int | None = None
    resume_at: int | None = None  # for k/e: the vector after the pause it stops at, None = the end


class Mp285:
    """One controller on an open serial port.

    `stage` selects the µm conversion (MP-28: `mp285` 25 µsteps/µm, `mt800` 20 on X and Y),
    `model` the speed limits the device clamps to (MP-38). `timeout` bounds replies that come at
    once; `gap_s` is how long a reply may pause between bytes (scheduling slack on both sides),
    `settle_s` and `reset_deaf_s` are the device's settle and post-reset deaf times (MP-44, MP-56),
    `margin_s` is added to every computed completion timeout.
    """

    def __init__(
        self,
        port: serial.Serial,
        *,
        stage: str = "mp285",
        model: str = "mp285",
        z_usteps_per_um: float = proto.DEFAULT_Z_USTEPS_PER_UM,
        timeout: float = 1.0,
        gap_s: float = 0.1,
        settle_s: float = 0.15,
        reset_deaf_s: float = 0.2,
        margin_s: float = 0.5,
    ) -> None:
        if model not in proto.MAX_SPEED_LOW_UM_S:
            raise ValueError(f"model must be one of {', '.join(proto.MAX_SPEED_LOW_UM_S)}, got {model!r}")
        if stage not in proto.XY_USTEPS_PER_UM:
            raise ValueError(f"stage must be one of {', '.join(proto.XY_USTEPS_PER_UM)}, got {stage!r}")
        self.port = port
        self.factors = proto.axis_factors(stage, z_usteps_per_um)
        self.model = model
        self.limits = SpeedLimits.of_model(model)
        self.timeout = timeout
        self.gap_s = gap_s
        self.settle_s = settle_s
        self.reset_deaf_s = reset_deaf_s
        self.margin_s = margin_s
        #: "absolute", "relative", or None until the client has set it (the device cannot say)
        self.mode: str | None = None
        #: the `V` word in force as far as the client knows (None until set or read from the status)
        self.velocity: Velocity | None = None
        #: the program stopped at a pause vector, if any (MP-68)
        self.paused: int | None = None
        self._resume_at: int | None = None
        self._programs: dict[int, tuple[Vector, ...]] = {}
        self._outstanding: _Outstanding | None = None

    @classmethod
    def open(
        cls,
        path: str,
        baudrate: int = 9600,
        *,
        rtscts: bool = False,
        parity: str = serial.PARITY_NONE,
        stopbits: float = serial.STOPBITS_ONE,
        **options: Any,
    ) -> Mp285:
        """Open `path` with the device's line settings: 9600 8N1 by default; the MP-285A's USB
        virtual COM port needs `rtscts=True` (MP-2). `options` go to the constructor."""
        port = serial.Serial(
            path,
            baudrate,
            bytesize=serial.EIGHTBITS,
            parity=parity,
            stopbits=stopbits,
            rtscts=rtscts,
            timeout=options.get("timeout", 1.0),
        )
        return cls(port, **options)

    def close(self) -> None:
        self.port.close()

    def __enter__(self) -> Mp285:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- units (MP-28) -------------------------------------------------------------------------

    def to_um(self, usteps: Sequence[int]) -> tuple[float, float, float]:
        x, y, z = (proto.usteps_to_um(p, f) for p, f in zip(usteps, self.factors, strict=True))
        return (x, y, z)

    def to_usteps(self, um: Sequence[float]) -> Xyz:
        x, y, z = (proto.um_to_usteps(v, f) for v, f in zip(um, self.factors, strict=True))
        return (x, y, z)

    # ---- queries -------------------------------------------------------------------------------

    def position(self) -> Xyz:
        """Reported position in µsteps, relative to the origin (MP-35)."""
        self._idle("c")
        self._send(proto.GetPosition().encode())
        return proto.decode_position(self._reply("c", proto.POSITION_REPLY_LENGTH))

    def position_um(self) -> tuple[float, float, float]:
        return self.to_um(self.position())

    def status(self) -> StatusBlock:
        """The 32-byte status block (MP-60); its XSPEED also updates the tracked velocity."""
        self._idle("s")
        self._send(proto.GetStatus().encode())
        block = StatusBlock.unpack(self._reply("s", proto.STATUS_REPLY_LENGTH))
        self.velocity = block.velocity
        return block

    # ---- settings ------------------------------------------------------------------------------

    def set_velocity(self, speed_um_s: int, high: bool = False) -> None:
        """`V`: speed for following moves and resolution (high = fine). The device reduces a speed
        over its limit to the limit (MP-39), and so does the tracked value."""
        requested = Velocity(speed_um_s, high)
        self._command("V", proto.SetVelocity(requested.word))
        self.velocity = self.limits.clamp(requested)

    def set_origin(self) -> None:
        """`o`: the current position becomes (0, 0, 0) (MP-32)."""
        self._command("o", proto.SetOrigin())

    def absolute(self) -> None:
        """`a`: `m` values are targets (MP-33)."""
        self._command("a", proto.Absolute())
        self.mode = "absolute"

    def relative(self) -> None:
        """`b`: `m` values are displacements (MP-33)."""
        self._command("b", proto.Relative())
        self.mode = "relative"

    def refresh(self) -> None:
        """`n`: redraw the controller's display (MP-74)."""
        self._command("n", proto.Refresh())

    def reset(self) -> None:
        """`r`: no reply (MP-55); waits out the deaf time that follows (MP-56), accepting the one NUL
        some units send (MP-58). Afterwards the device is in absolute mode with its power-on
        velocity (MP-57), which the client reads from the status when it next needs it."""
        self._idle("r")
        self._send(proto.Reset().encode())
        quiet = self._read(2, self._chars(2) + self.reset_deaf_s + self.gap_s)
        if quiet not in (b"", b"\x00"):
            raise UnexpectedReply(f"r: expected silence, got {quiet.hex(' ')}")
        self.mode = "absolute"
        self.velocity = None
        self.paused = self._resume_at = None
        self._programs.clear()  # they may not have survived (program_retention, MP-73)

    # ---- motion --------------------------------------------------------------------------------

    def move_to(self, x: int, y: int, z: int, wait: bool = True) -> None:
        """Move to (x, y, z) µsteps, whatever the tracked mode."""
        target = (x, y, z)
        self._idle("m")
        self._know_mode()
        current = self.position()
        deltas = _sub(target, current)
        self._move(target if self.mode == "absolute" else deltas, deltas, wait)

    def move_by(self, dx: int, dy: int, dz: int, wait: bool = True) -> None:
        """Move by (dx, dy, dz) µsteps, whatever the tracked mode."""
        deltas = (dx, dy, dz)
        self._idle("m")
        self._know_mode()
        if self.mode == "relative":
            self._move(deltas, deltas, wait)
        else:
            self._move(_add(self.position(), deltas), deltas, wait)

    def move_to_um(self, x: float, y: float, z: float, wait: bool = True) -> None:
        self.move_to(*self.to_usteps((x, y, z)), wait=wait)

    def move_by_um(self, dx: float, dy: float, dz: float, wait: bool = True) -> None:
        self.move_by(*self.to_usteps((dx, dy, dz)), wait=wait)

    @property
    def moving(self) -> bool:
        """True while an `m`, `k` or `e` has not answered."""
        return self._outstanding is not None

    def wait(self) -> None:
        """Read the outstanding move's or program's final CR (a device error reply raises)."""
        op = self._outstanding
        if op is None:
            return
        if math.isinf(op.timeout):
            raise ValueError(f"{op.command}: at speed 0 a move never ends (MP-40); interrupt() it")
        try:
            self._reply(op.command, 1, op.timeout)
        except Mp285Error:
            self._outstanding = None
            raise
        self._outstanding = None  # after NoReply it stays outstanding: the host may interrupt() it
        self._stopped(op)

    def interrupt(self) -> bool:
        """^C (MP-48, MP-49). True if it halted an outstanding move; False if nothing was
        outstanding or the move's final CR crossed the ^C, which then got an idle CR (TV-36). A
        program, running or paused, is abandoned (MP-54, MP-71)."""
        self._send(proto.Interrupt().encode())
        op, self._outstanding = self._outstanding, None
        self.paused = self._resume_at = None
        if op is None:
            self._reply("^C", 1)
            return False
        first = self._exact(1, self.timeout, "^C")
        if first == bytes((proto.ACK_INTERRUPT,)):
            self._reply(op.command, 1, self._chars(1) + self.settle_s + self.margin_s)
            return True
        final = first
        if proto.is_error_code(first[0]):
            final += self._exact(1, self._chars(1) + self.gap_s, "^C")
        elif first != b"\r":
            raise UnexpectedReply(f"^C: unexpected {first.hex(' ')}")
        self._reply("^C", 1)  # the ^C came after the final reply: an idle one (MP-49)
        if final != b"\r":
            raise error_for(final[0], op.command)
        return False

    # ---- programs (MP-66 ... MP-73) --------------------------------------------------------------

    def download(self, program: int, vectors: Sequence[Vector]) -> None:
        """`d`: store program 1-10 of 1-99 vectors (`Vector.move(x, y, z)`, `Vector.pause()`)."""
        vectors = tuple(vectors)
        if not 1 <= program <= proto.MAX_PROGRAM or not 1 <= len(vectors) <= proto.MAX_VECTORS:
            raise ValueError(f"program 1-10 of 1-99 vectors, got program {program} of {len(vectors)}")
        self._command("d", proto.Download(program, vectors))
        self._programs[program] = vectors

    def upload(self, program: int) -> tuple[Vector, ...]:
        """`u`: the stored vectors, as downloaded; () for a never-downloaded program (MP-72)."""
        self._idle("u")
        self._send(proto.Upload(program).encode())
        vectors = proto.decode_program(self._reply("u", lambda count: 2 + proto.VECTOR_LENGTH * count))
        self._programs[program] = vectors
        return vectors

    def execute(self, program: int, wait: bool = True) -> None:
        """`k`: run the program; it answers at a pause vector (then `paused` is set) or at the end."""
        self._idle("k")
        vectors = self._programs[program] if program in self._programs else self.upload(program)
        self.paused = self._resume_at = None
        self._run_program("k", proto.Execute(program), program, vectors, 0, wait)

    def continue_program(self, wait: bool = True) -> None:
        """`e`: resume the paused program up to its next pause or end; with nothing paused the
        device answers at once (MP-70)."""
        self._idle("e")
        program, start = self.paused, self._resume_at
        self.paused = self._resume_at = None
        if program is None or start is None:
            self._command("e", proto.Continue())
            return
        self._run_program("e", proto.Continue(), program, self._programs[program], start, wait)

    def _run_program(
        self,
        name: str,
        command: proto.Command,
        program: int,
        vectors: Sequence[Vector],
        start: int,
        wait: bool,
    ) -> None:
        moves: list[Vector] = []
        resume_at = None
        for index in range(start, len(vectors)):
            if vectors[index].is_pause:
                resume_at = index + 1
                break
            moves.append(vectors[index])
        motion = sum(self._motion_time(vector.xyz) for vector in moves)
        self._send(command.encode())
        self._outstanding = _Outstanding(name, self._completion(motion, len(moves)), program, resume_at)
        if wait:
            self.wait()

    # ---- internals -----------------------------------------------------------------------------

    def _know_mode(self) -> None:
        """The device starts in absolute mode, but the client cannot read it (MP-34): set it once."""
        if self.mode is None:
            self.absolute()

    def _move(self, values: Xyz, deltas: Xyz, wait: bool) -> None:
        if not all(proto.INT32_MIN <= v <= proto.INT32_MAX for v in values):
            raise ValueError(f"move values {values} do not fit signed 32 bits (MP-27)")
        motion = self._motion_time(deltas)
        if wait and math.isinf(motion):
            raise ValueError("at speed 0 a move never ends (MP-40); use wait=False and interrupt()")
        self._send(proto.Move(*values).encode())
        self._outstanding = _Outstanding("m", self._completion(motion, 1))
        if wait:
            self.wait()

    def _motion_time(self, deltas: Sequence[int]) -> float:
        """Upper bound of the motion time: the axes' times added, which also covers axes moving one
        after another (MP-43); clamping at travel limits only shortens it (MP-36)."""
        distance_um = sum(proto.usteps_to_um(abs(d), f) for d, f in zip(deltas, self.factors, strict=True))
        if not distance_um:
            return 0.0
        if self.velocity is None:
            self.status()
        assert self.velocity is not None
        return distance_um / self.velocity.speed if self.velocity.speed else math.inf

    def _completion(self, motion_s: float, moves: int) -> float:
        """Timeout of a final CR: motion + 5 % (clock rates, acceleration) + settle per move + the
        reply's wire time + margin."""
        return motion_s * 1.05 + moves * self.settle_s + self._chars(1) + self.margin_s

    def _stopped(self, op: _Outstanding) -> None:
        if op.program is not None and op.resume_at is not None:
            self.paused, self._resume_at = op.program, op.resume_at

    def _idle(self, command: str) -> None:
        if self._outstanding is not None:
            raise MoveOutstanding(
                f"{command}: '{self._outstanding.command}' has not answered; wait() or interrupt() first"
            )

    def _command(self, name: str, command: proto.Command) -> None:
        """A command whose reply is a lone CR, sent at once."""
        self._idle(name)
        self._send(command.encode())
        self._reply(name, 1)

    def _send(self, frame: bytes) -> None:
        self.port.write(frame)

    def _chars(self, count: int) -> float:
        """Wire time of `count` characters at the port's settings."""
        port = self.port
        bits = 1 + port.bytesize + (0 if port.parity == serial.PARITY_NONE else 1) + port.stopbits
        return count * bits / port.baudrate

    def _read(self, count: int, timeout: float) -> bytes:
        previous = self.port.timeout
        self.port.timeout = timeout
        try:
            return bytes(self.port.read(count))
        finally:
            self.port.timeout = previous

    def _exact(self, count: int, timeout: float, what: str) -> bytes:
        data = self._read(count, timeout)
        if len(data) < count:
            got = data.hex(" ") or "nothing"
            raise NoReply(f"{what}: {len(data)} of {count} bytes within {timeout:.3f} s ({got})")
        return data

    def _reply(self, what: str, length: int | Callable[[int], int], timeout: float | None = None) -> bytes:
        """A reply of `length` bytes (or `length(first byte)`) ending in CR. An error reply `<digit>
        CR` can look like the start of a data reply; it is one if nothing follows within the wire
        time of the rest plus `gap_s`, since the device sends a reply's bytes back to back."""
        first = self._exact(1, (self.timeout if timeout is None else timeout) + self._chars(1), what)
        total = length(first[0]) if callable(length) else length
        if total == 1:
            if first == b"\r":
                return first
            if proto.is_error_code(first[0]) and self._exact(1, self._chars(1) + self.gap_s, what) == b"\r":
                raise error_for(first[0], what)
            raise UnexpectedReply(f"{what}: expected CR, got {first.hex(' ')}")
        head = first + self._exact(1, self._chars(1) + self.gap_s, what)
        if head[1] == CR and proto.is_error_code(head[0]) and total > 2:
            follow = self._read(1, self._chars(1) + self.gap_s)
            if not follow:
                raise error_for(head[0], what)
            head += follow
        data = head + self._read(total - len(head), self._chars(total - len(head)) + self.gap_s)
        if len(data) < total:
            raise NoReply(f"{what}: {len(data)} of {total} bytes ({data.hex(' ')})")
        if data[-1] != CR:
            raise UnexpectedReply(f"{what}: reply does not end in CR: {data.hex(' ')}")
        return data


def _add(a: Sequence[int], b: Sequence[int]) -> Xyz:
    x, y, z = (p + q for p, q in zip(a, b, strict=True))
    return (x, y, z)


def _sub(a: Sequence[int], b: Sequence[int]) -> Xyz:
    x, y, z = (p - q for p, q in zip(a, b, strict=True))
    return (x, y, z)
