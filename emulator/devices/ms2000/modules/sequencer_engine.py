"""The SEQUENCER's block engine (MS-SEQ-2…MS-SEQ-4): conditions, delays, repetitions, transitions.

Everything that happens is an `Occurrence`: an outside event (IN0 edge, `ARM`, `@`, the stage going
idle, an array arrival) or a block transition (START, DELAY_COMPLETE, REPEAT, REPETITION m,
COMPLETE). One time step takes an outside event, or a delay running out, and works through the
occurrences it causes in order: each is offered to every block (an idle block whose START condition
it meets starts, a block waiting whose REPEAT condition it meets repeats) and every output (TTL
START/STOP, AVO/STG STEP/RESET). A delay of 0 ms completes within the step. Block STARTs are
counted per step, the first included; the seventh is a recursion error (MS-SEQ-4).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from emulator.devices.ms2000.modules.sequencer_program import (
    ALWAYS,
    ARM_COMMAND,
    ARRAY_MOVE_DONE,
    AT_BUTTON,
    BLOCK_COMPLETE,
    BLOCK_DELAY_COMPLETE,
    BLOCK_DELAY_COMPLETE_OR_START,
    BLOCK_REPEAT,
    BLOCK_REPEAT_OR_COMPLETE,
    BLOCK_REPEAT_OR_START,
    BLOCK_REPETITION,
    STAGE_NOT_BUSY,
    TTL_TRIGGER,
    Block,
    Condition,
    Output,
    Program,
)

if TYPE_CHECKING:
    from emulator.devices.ms2000.scheduler import Timer

#: block STARTs one time step may process (MS-SEQ-4)
MAX_STARTS = 6
# block transitions
START, DELAY_COMPLETE, COMPLETE = "START", "DELAY_COMPLETE", "COMPLETE"
REPEAT, REPETITION = "REPEAT", "REPETITION"
#: the transitions each block condition code waits for (MS-SEQ-2)
BLOCK_TRANSITIONS = {
    BLOCK_DELAY_COMPLETE: {DELAY_COMPLETE},
    BLOCK_COMPLETE: {COMPLETE},
    BLOCK_REPEAT: {REPEAT},
    BLOCK_REPEAT_OR_START: {REPEAT, START},
    BLOCK_DELAY_COMPLETE_OR_START: {DELAY_COMPLETE, START},
    BLOCK_REPEAT_OR_COMPLETE: {REPEAT, COMPLETE},
    BLOCK_REPETITION: {REPETITION},
}
#: outside events, by their condition code
OUTSIDE = frozenset({TTL_TRIGGER, ARM_COMMAND, AT_BUTTON, STAGE_NOT_BUSY, ARRAY_MOVE_DONE})
# block state characters (MS-SEQ-3 [choice])
IDLE, DELAYING, WAITING = "I", "D", "W"


@dataclass(frozen=True)
class Occurrence:
    """An outside event (`code` its condition code) or a transition of block `block`."""

    code: int | None = None
    block: int | None = None
    transition: str | None = None
    repetition: int | None = None


def meets(condition: Condition, occurrence: Occurrence) -> bool:
    if condition.code in OUTSIDE:
        return occurrence.code == condition.code
    transitions = BLOCK_TRANSITIONS.get(condition.code)
    if transitions is None or occurrence.block != condition.block:
        return False  # NEVER, and ALWAYS, which is a state rather than an event
    if occurrence.transition not in transitions:
        return False
    return condition.code != BLOCK_REPETITION or occurrence.repetition == condition.repetition


class EngineSide(Protocol):
    """What the engine needs of its module: time, and the effects of transitions and outputs."""

    def at(self, due: float, action: Callable[[float], None]) -> Timer: ...

    def transition(self, block: int, transition: str, repetition: int | None, now: float) -> None: ...

    def act(self, action: int, now: float) -> None: ...

    def output(self, output: Output, start: bool, now: float) -> None:
        """`start`: TTL high / AVO, STG step; otherwise TTL low / AVO, STG reset."""

    def recursion_error(self, now: float) -> None: ...


class RecursionTripped(Exception):
    """A seventh block START in one time step (MS-SEQ-4)."""


@dataclass(eq=False)
class BlockRun:
    spec: Block
    state: str = IDLE
    repetition: int = 0
    #: a block with START = ALWAYS runs again whenever idle, once `ARM X` made it ready (MS-SEQ-6)
    ready: bool = False
    timer: Timer | None = None

    @property
    def always(self) -> bool:
        return self.spec.start.code == ALWAYS


class Engine:
    def __init__(self, side: EngineSide, program: Program) -> None:
        self.side = side
        self.program = program
        self.blocks = [BlockRun(spec) for spec in program.blocks]
        self._queue: deque[Occurrence] = deque()
        self._in_step = False
        self._starts = 0

    @property
    def running(self) -> bool:
        return any(b.state != IDLE or b.ready for b in self.blocks)

    def state_chars(self) -> list[str]:
        return [b.state for b in self.blocks]

    # ---- outside events and control -------------------------------------------------------------

    def outside(self, code: int, now: float) -> None:
        self._step(now, lambda: self._queue.append(Occurrence(code=code)))

    def initialise(self, ready_always: bool, now: float) -> None:
        """Every block idle (`ARM X`, `ARM Z`, `@` stop, reset); with `ready_always` the ALWAYS
        blocks are made ready and start at once (MS-SEQ-6)."""
        self._queue.clear()
        for b in self.blocks:
            if b.timer is not None:
                b.timer.cancel()
            b.state, b.repetition, b.timer = IDLE, 0, None
            b.ready = ready_always and b.always
        if ready_always:
            self._step(now, lambda: self._start_ready(now))

    def _start_ready(self, now: float) -> None:
        for b in self.blocks:
            if b.ready and b.state == IDLE:
                self._start(b, now)

    # ---- one time step ----------------------------------------------------------------------------

    def _step(self, now: float, cause: Callable[[], object]) -> None:
        """Run `cause`, then every occurrence it leads to; nested causes (an action whose move ends
        at once) join the step under way."""
        if self._in_step:
            cause()
            return
        self._in_step, self._starts = True, 0
        try:
            cause()
            while self._queue:
                self._offer(self._queue.popleft(), now)
        except RecursionTripped:
            self._queue.clear()
            self.side.recursion_error(now)
        finally:
            self._in_step = False

    def _offer(self, occurrence: Occurrence, now: float) -> None:
        for b in self.blocks:
            if b.state == IDLE and meets(b.spec.start, occurrence):
                self._start(b, now)
            elif b.state == WAITING and meets(b.spec.repeat, occurrence):
                self._repeat(b, now)
        for output in self.program.outputs:
            if meets(output.start, occurrence):
                self.side.output(output, True, now)
            if meets(output.stop, occurrence):
                self.side.output(output, False, now)

    def _emit(self, b: BlockRun, transition: str, now: float, repetition: int | None = None) -> None:
        number = b.spec.number
        self._queue.append(Occurrence(block=number, transition=transition, repetition=repetition))
        self.side.transition(number, transition, repetition, now)

    # ---- a block's life (MS-SEQ-3) --------------------------------------------------------------

    def _start(self, b: BlockRun, now: float) -> None:
        self._starts += 1
        if self._starts > MAX_STARTS:
            raise RecursionTripped
        b.repetition = 0
        self._emit(b, START, now)
        self._delay(b, now)

    def _repeat(self, b: BlockRun, now: float) -> None:
        self._count_repetition(b, now)
        self._delay(b, now)

    def _count_repetition(self, b: BlockRun, now: float) -> None:
        b.repetition += 1
        self._emit(b, REPEAT, now)
        self._emit(b, REPETITION, now, b.repetition)

    def _delay(self, b: BlockRun, now: float) -> None:
        b.state = DELAYING
        if b.spec.delay_ms:
            self._time(b, now)
        else:
            self._delay_over(b, now)

    def _time(self, b: BlockRun, now: float) -> None:
        b.timer = self.side.at(now + b.spec.delay_ms / 1000, lambda due: self._timed_out(b, due))

    def _timed_out(self, b: BlockRun, now: float) -> None:
        b.timer = None
        self._step(now, lambda: self._delay_over(b, now))

    def _delay_over(self, b: BlockRun, now: float) -> None:
        """DELAY_COMPLETE, then wait for REPEAT, or COMPLETE with its action. A REPEAT of ALWAYS
        repeats at once: looped here, as 0 ms delays would otherwise nest one call per repetition."""
        while True:
            self._emit(b, DELAY_COMPLETE, now)
            if b.repetition >= b.spec.repetitions:
                break
            b.state = WAITING
            if b.spec.repeat.code != ALWAYS:
                return
            self._count_repetition(b, now)
            b.state = DELAYING
            if b.spec.delay_ms:
                self._time(b, now)
                return
        b.state = IDLE
        self._emit(b, COMPLETE, now)
        self.side.act(b.spec.action, now)
        if b.ready and b.state == IDLE:
            self._start(b, now)  # ALWAYS: straight back into the sequence (MS-SEQ-3)
