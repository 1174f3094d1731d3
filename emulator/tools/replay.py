"""Replaying a session's host side on a port and comparing the replies (`stage-emu replay`).

`play` writes the host's recorded bytes at their recorded times, a write per recorded read (so a
host that sent a byte per millisecond is replayed that way), sets the host's recorded line settings
when it changed them, and records what comes back, timed on the same scale. `compare` decodes both
sessions into exchanges (emulator/tools/session_decode.py: pairing by the order of bytes, never by timing)
and reports each exchange whose reply differs in bytes, or in timing beyond a tolerance: the
reply's first and last byte after the request's end, so the device's reaction time and the reply's
wire time are both checked. Device output outside any exchange (unsolicited) is compared by bytes.
"""

from __future__ import annotations

import itertools
import threading
import time
from bisect import bisect_left
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

import serial

import emulator.urlhandler  # noqa: F401  (registers stageemu:// with pyserial)
from emulator.device import HostLine, LineSettings
from emulator.profiles.profile import ProfileError, load_profile
from emulator.tools.session import RX, TX, Chunk, Event, LineChange, Session, iter_decode
from emulator.tools.session_decode import Exchange, reply_text
from emulator.tools.trace import readable

DEFAULT_TOLERANCE_S = 0.005
#: how long the replay listens after the session's last record, for late or extra output
GRACE_S = 0.5
#: how long a host write waits beyond its recorded time for device bytes it followed (`play`)
WAIT_S = 0.5
#: the reader's read timeout: how soon it notices the replay is over
READ_POLL_S = 0.02
PARITIES = {"none": serial.PARITY_NONE, "even": serial.PARITY_EVEN, "odd": serial.PARITY_ODD}


class ReplayError(Exception):
    """The replay cannot run (bad profile, port that cannot be opened or fails); one line."""


@dataclass(frozen=True)
class ReplayOptions:
    tolerance_s: float = DEFAULT_TOLERANCE_S
    #: lateness allowed on top of the tolerance (a test suite on a loaded machine: load can make a
    #: reply late, never early)
    late_allowance_s: float = 0.0
    #: compare reply timing (off for `timing=fast`, where replies come at once)
    timing: bool = True
    grace_s: float = GRACE_S
    wait_s: float = WAIT_S


# ---- the port -----------------------------------------------------------------------------------


def emulator_url(profile: str, timing: str) -> str:
    """The in-process emulator of `profile` (a bundled name or a file)."""
    if "/" in profile or profile.endswith((".yaml", ".yml")):
        return f"stageemu://?profile={quote(str(Path(profile).absolute()), safe='/')}&timing={timing}"
    return f"stageemu://{profile}?timing={timing}"


def check_profile(profile: str, family: str) -> None:
    try:
        loaded = load_profile(profile)
    except ProfileError as exc:
        raise ReplayError(str(exc)) from None
    if loaded.family != family:
        raise ReplayError(
            f"profile {profile} is for the {loaded.family}; the session was recorded on the {family}"
        )


def open_port(url: str, line: LineSettings) -> serial.Serial:
    """`url` (a device path, rfc2217://, stageemu://...) opened with the device's line settings."""
    try:
        return serial.serial_for_url(
            url,
            baudrate=line.baud or 9600,
            bytesize=line.data_bits or 8,
            parity=PARITIES[line.parity or "none"],
            stopbits=line.stop_bits or 1,
            rtscts=bool(line.rtscts),
            xonxoff=bool(line.xonxoff),
            timeout=READ_POLL_S,
        )
    except (serial.SerialException, ValueError) as exc:
        raise ReplayError(f"cannot open {url}: {exc}") from None


def apply_line(port: serial.Serial, host: HostLine) -> None:
    """Set what the host set (None: not seen, left as is); unchanged settings are not touched, since
    every assignment reconfigures the port."""
    wanted = {
        "baudrate": host.baud,
        "bytesize": host.data_bits,
        "parity": None if host.parity is None else PARITIES[host.parity],
        "stopbits": host.stop_bits,
        "rtscts": host.rtscts,
        "xonxoff": host.xonxoff,
    }
    for name, value in wanted.items():
        if value is not None and getattr(port, name) != value:
            setattr(port, name, value)


# ---- playing ------------------------------------------------------------------------------------


class _Listener(threading.Thread):
    """Reads the port and stamps each read; a writer can wait until so many bytes have come."""

    def __init__(self, port: serial.Serial, clock: Callable[[], float]) -> None:
        super().__init__(name="stage-emu-replay-reader", daemon=True)
        self._port = port
        self._clock = clock
        self.chunks: list[Chunk] = []
        #: bytes received by the end of each chunk
        self._totals: list[int] = []
        self.count = 0
        self.failure: BaseException | None = None
        self.done = threading.Event()
        self._arrived = threading.Condition()

    def run(self) -> None:
        port = self._port
        try:
            while not self.done.is_set():
                data = port.read(1)
                if data:
                    waiting = port.in_waiting
                    data += port.read(waiting) if waiting else b""
                    with self._arrived:
                        self.chunks.append(Chunk(self._clock(), TX, data))
                        self.count += len(data)
                        self._totals.append(self.count)
                        self._arrived.notify_all()
        except (serial.SerialException, OSError) as exc:
            self.failure = exc
            self.done.set()
            with self._arrived:
                self._arrived.notify_all()

    def wait_for(self, count: int, limit: float) -> float | None:
        """When the `count`th byte came (session time), waiting at most `limit` seconds for it."""
        deadline = time.monotonic() + limit
        with self._arrived:
            while self.count < count and not self.done.is_set():
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._arrived.wait(left)
            index = bisect_left(self._totals, count)
            return self.chunks[index].t if index < len(self.chunks) else None


@dataclass
class _HostPlan:
    """The host's events of a session as they are read, each with how many device bytes had come
    before it and when the last of them came; `last_t` is the time of the last event read."""

    events: Iterable[Event]
    last_t: float = 0.0

    def __iter__(self) -> Iterator[tuple[Event, int, float]]:
        received, last = 0, 0.0
        for event in self.events:
            self.last_t = event.t
            if isinstance(event, Chunk) and event.direction == TX:
                received, last = received + len(event.data), event.t
            else:
                yield event, received, last


def play(
    session: Session, port: serial.Serial, options: ReplayOptions, on_write: Callable[[], None] | None = None
) -> list[Event]:
    """Play the host side of `session` on the open `port`; the replayed session's events, timed on
    the recording's scale (the host's first action happens at its recorded `t`).

    A host write that followed device bytes in the recording waits for as many (at most
    `wait_s`; a shortfall is then forgiven for the rest of the replay) and keeps the host's reaction
    time after them: a reply a little later than recorded must not meet a next request the host
    only sent because it had that reply. The rest of the schedule moves by the same delay.

    The session's events are read as they are played (`on_write` hears of each host event), so a
    long session costs no more memory than what the device sends back."""
    plan = _HostPlan(session.events)
    first = next(iter(plan), None)
    origin = first[0].t if first is not None else 0.0
    start = time.monotonic()

    def clock() -> float:
        return time.monotonic() - start + origin

    port.timeout = READ_POLL_S
    port.reset_input_buffer()
    listener = _Listener(port, clock)
    events: list[Event] = []
    lag = shortfall = 0.0
    listener.start()
    try:
        for event, needed, after in plan:
            if on_write is not None:
                on_write()
            due = event.t + lag
            wanted = int(needed - shortfall)
            if listener.count < wanted:
                came = listener.wait_for(wanted, max(due - clock(), 0.0) + options.wait_s)
                if came is None:
                    shortfall = needed - listener.count
                    due = max(due, clock())
                else:
                    due = max(due, came + event.t - after)
                lag = due - event.t
            if listener.done.wait(max(due - clock(), 0.0)):
                break
            if isinstance(event, LineChange):
                apply_line(port, event.host)
                events.append(LineChange(clock(), event.host))
            elif isinstance(event, Chunk):
                events.append(Chunk(clock(), RX, event.data))
                port.write(event.data)
        end = plan.last_t + lag + options.grace_s
        listener.done.wait(max(end - clock(), 0.0))
    except (serial.SerialException, OSError) as exc:
        listener.failure = listener.failure or exc
    finally:
        listener.done.set()
        listener.join()
    if listener.failure is not None:
        raise ReplayError(f"the port failed during the replay: {listener.failure}")
    return sorted([*events, *listener.chunks], key=lambda e: e.t)


# ---- comparing ----------------------------------------------------------------------------------


@dataclass
class Slot:
    """A request's exchange (None before the first request) and the unsolicited output after it."""

    number: int
    exchange: Exchange | None
    after: list[Exchange] = field(default_factory=list)

    @property
    def after_bytes(self) -> bytes:
        return b"".join(e.reply for e in self.after)


def slots(exchanges: Iterable[Exchange]) -> Iterator[Slot]:
    """Each request's slot once the next request (or the end) shows it complete."""
    slot = Slot(0, None)
    for exchange in exchanges:
        if exchange.request is None:
            slot.after.append(exchange)
        else:
            yield slot
            slot = Slot(slot.number + 1, exchange)
    yield slot


@dataclass(frozen=True)
class Difference:
    number: int
    expected: Slot | None
    got: Slot | None
    reasons: tuple[str, ...]

    def line(self, family: str) -> str:
        """One line: the exchange, the expected and the replayed reply, and what differs."""
        slot = self.expected or self.got
        assert slot is not None
        exchange = slot.exchange
        if exchange is None:
            head = "#0  before the first request"
        else:
            request = exchange.request
            assert request is not None
            head = f"#{self.number}  {exchange.t:.6f}  {request.summary}  {readable(request.data)}"
        why = "; ".join(self.reasons)
        want, have = self.expected, self.got
        if want and have and want.exchange and have.exchange and _same_bytes(want, have):
            reply = reply_text(family, want.exchange.reply, want.exchange.request)
            return f"{head}: {reply} [expected {_ms(want.exchange)}, got {_ms(have.exchange)}] ({why})"
        return f"{head}: expected {_shown(family, want)}, got {_shown(family, have)} ({why})"


def _same_bytes(a: Slot, b: Slot) -> bool:
    assert a.exchange is not None and b.exchange is not None
    return a.exchange.reply == b.exchange.reply and a.after_bytes == b.after_bytes


def _ms(exchange: Exchange) -> str:
    latency = exchange.latency
    return "no reply" if latency is None else f"{latency * 1000:.1f} ms"


def _shown(family: str, slot: Slot | None) -> str:
    if slot is None:
        return "no such exchange"
    exchange = slot.exchange
    if exchange is None:
        text = readable(slot.after_bytes) if slot.after_bytes else "nothing"
    else:
        text = reply_text(family, exchange.reply, exchange.request)
        if exchange.latency is not None:
            text += f" [{_ms(exchange)}]"
    if exchange is not None and slot.after_bytes:
        text += f" then unsolicited {readable(slot.after_bytes)}"
    return text


def compare(
    family: str, expected: Iterable[Exchange], got: Iterable[Exchange], options: ReplayOptions
) -> tuple[int, list[Difference]]:
    """(exchanges compared, the differing ones), the two sides read side by side as they close."""
    differences = []
    number = 0
    for number, (a, b) in enumerate(itertools.zip_longest(slots(expected), slots(got))):
        reasons = _reasons(a, b, options)
        if reasons:
            differences.append(Difference(number, a, b, tuple(reasons)))
    return number, differences


def _reasons(a: Slot | None, b: Slot | None, options: ReplayOptions) -> list[str]:
    if a is None or b is None:
        return ["the replay has an exchange the recording has not" if a is None else "missing in the replay"]
    reasons = []
    if a.exchange is not None and b.exchange is not None:
        assert a.exchange.request is not None and b.exchange.request is not None
        if a.exchange.request.data != b.exchange.request.data:
            reasons.append("another request")  # the same bytes were written: only a decoding change
        if a.exchange.reply != b.exchange.reply:
            reasons.append("reply bytes differ")
        elif options.timing:
            reasons += _timing(a.exchange, b.exchange, options.tolerance_s, options.late_allowance_s)
    if a.after_bytes != b.after_bytes:
        reasons.append("unsolicited output differs")
    return reasons


def _timing(want: Exchange, have: Exchange, tolerance: float, late_allowance: float = 0.0) -> list[str]:
    found = []
    pairs: list[tuple[str, Callable[[Exchange], float | None]]] = [
        ("first byte", lambda e: e.first_latency),
        ("last byte", lambda e: e.latency),
    ]
    for what, latency in pairs:
        a, b = latency(want), latency(have)
        if a is None or b is None:
            continue
        delta = b - a
        if delta < -tolerance:
            found.append(f"{what} {-delta * 1000:.1f} ms early (tolerance {tolerance * 1000:g} ms)")
        elif delta > tolerance + late_allowance:
            bound = (tolerance + late_allowance) * 1000
            found.append(f"{what} {delta * 1000:.1f} ms late (tolerance {bound:g} ms)")
    return found


@dataclass(frozen=True)
class ReplayResult:
    family: str
    compared: int
    differences: tuple[Difference, ...]
    #: the replayed session's events, as a session of its own would hold them
    events: tuple[Event, ...]

    @property
    def ok(self) -> bool:
        return not self.differences

    def report(self) -> list[str]:
        return [d.line(self.family) for d in self.differences]

    def summary(self, where: str) -> str:
        if self.ok:
            return f"{self.compared} exchanges replayed on {where}: no difference"
        return f"{len(self.differences)} of {self.compared} exchanges differ on {where}"


def replay(
    session: Session,
    port: serial.Serial,
    options: ReplayOptions | None = None,
    on_write: Callable[[], None] | None = None,
) -> ReplayResult:
    """Play `session` on `port` (opened with its line settings) and compare the replies."""
    options = options or ReplayOptions()
    events = play(session, port, options, on_write)
    family = session.header.device
    compared, differences = compare(
        family, iter_decode(family, session.events), iter_decode(family, events), options
    )
    return ReplayResult(family, compared, tuple(differences), tuple(events))
