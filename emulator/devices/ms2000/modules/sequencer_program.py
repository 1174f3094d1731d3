"""The SEQUENCER's program: blocks and outputs, as loaded through the control channel (MS-SEQ-1,
MS-SEQ-2, MS-SEQ-5, MS-SEQ-8).

ASI's serial programming commands are not public, so a program arrives whole as the `sequencer`
input and is checked here before anything changes: a condition in a position the condition table
forbids, a code or number out of range, an action or condition whose module the build lacks, or an
unknown key rejects the whole program with a message naming the block or output and the field.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from emulator.device import ControlError
from emulator.profiles.schema import finite_number

#: MS-SEQ-1 [choice counts]: BLK1…BLK8, TTL0…TTL3, AVO0…AVO1
BLOCK_COUNT = 8
TTL_COUNT = 4
AVO_COUNT = 2
#: [choice] bounds of a block's delay and repetition count
MAX_DELAY_MS = 3_600_000
MAX_REPETITIONS = 65_535
#: analog outputs span the DAC's range (MS-DAC-1) [choice]
AVO_MAX_V = 10.0
#: stage steps and start values are positions in units (MS-44), within the profile's ±10 m [choice]
MAX_STAGE_UNITS = 1e8

# condition codes (MS-SEQ-2)
NEVER, TTL_TRIGGER, ARM_COMMAND, AT_BUTTON, STAGE_NOT_BUSY = 0, 1, 2, 3, 4
BLOCK_DELAY_COMPLETE, BLOCK_COMPLETE, BLOCK_REPEAT = 5, 6, 7
BLOCK_REPEAT_OR_START, BLOCK_DELAY_COMPLETE_OR_START, BLOCK_REPEAT_OR_COMPLETE = 8, 9, 10
BLOCK_REPETITION, ALWAYS, ARRAY_MOVE_DONE = 11, 12, 13
CONDITION_NAMES = (
    "NEVER",
    "TTL_TRIGGER_RECEIVED",
    "ARM_COMMAND_RCVD",
    "AT_BUTTON_PRESSED",
    "XYZ_STAGE_NOT_BUSY",
    "BLOCK n DELAY_COMPLETE",
    "BLOCK n COMPLETE",
    "BLOCK n REPEAT",
    "BLOCK n REPEAT or START",
    "BLOCK n DELAY_COMPLETE or START",
    "BLOCK n REPEAT or COMPLETE",
    "BLOCK n REPETITION m",
    "ALWAYS",
    "ARRAY_MOVE_DONE",
)
#: codes that name a block n (5–11, even the block's own number) and a repetition m (11) (MS-SEQ-1)
NAMES_BLOCK = frozenset(range(BLOCK_DELAY_COMPLETE, BLOCK_REPETITION + 1))

# action codes on block completion (MS-SEQ-5)
ACTION_NAMES = (
    "IDLE",
    "RING_BUFFER_NEXT_POSITION",
    "INITIATE_AUTOFOCUS",
    "ARRAY_NEXT_POSITION",
    "ARRAY_START",
    "SEND_WHERE",
    "SEND_TIMESTAMP",
    "SEND_STATESTAMP",
)
#: the module an action or condition drives; absent from the build, it is refused (MS-SEQ-5)
ACTION_MODULES = {1: "RING BUFFER", 2: "AUTOFOCUS", 3: "ARRAY MODULE", 4: "ARRAY MODULE"}
CONDITION_MODULES = {ARRAY_MOVE_DONE: "ARRAY MODULE"}


class Position(Enum):
    """Where a condition is used: the columns of the condition table (MS-SEQ-2)."""

    BLOCK_START = "BLK START"
    BLOCK_REPEAT = "BLK REPEAT"
    TTL_START = "TTL START"
    TTL_STOP = "TTL STOP"
    STEP = "AVO/STG STEP"
    RESET = "AVO/STG RESET"


#: MS-SEQ-2: codes 0–9 and 13 are allowed everywhere; 10, 11 and 12 only in these positions
RESTRICTED = {
    BLOCK_REPEAT_OR_COMPLETE: {Position.BLOCK_START, Position.BLOCK_REPEAT, Position.TTL_START},
    BLOCK_REPETITION: {Position.BLOCK_START, Position.TTL_START},
    ALWAYS: {Position.BLOCK_START, Position.BLOCK_REPEAT},
}


def allowed(code: int, position: Position) -> bool:
    return position in RESTRICTED.get(code, set(Position))


@dataclass(frozen=True)
class Condition:
    code: int = NEVER
    block: int | None = None
    repetition: int | None = None

    def as_list(self) -> list[int]:
        return [v for v in (self.code, self.block, self.repetition) if v is not None]


@dataclass(frozen=True)
class Block:
    number: int
    start: Condition = Condition()
    repeat: Condition = Condition()
    delay_ms: int = 0
    repetitions: int = 0
    action: int = 0


@dataclass(frozen=True)
class Output:
    """A TTL output (`start` raises it, `stop` lowers it), an analog output or a stage stepper
    (`start` steps by `step_size`, `stop` resets to `initial`)."""

    kind: str  # "ttl" | "avo" | "stg"
    index: int | str  # TTL/AVO number, or the stepper's axis letter
    start: Condition = Condition()
    stop: Condition = Condition()
    step_size: float = 0.0
    initial: float = 0.0

    @property
    def label(self) -> str:
        return f"{self.kind} {self.index}"


@dataclass(frozen=True)
class Program:
    blocks: tuple[Block, ...] = field(default_factory=lambda: tuple(Block(n) for n in range(1, 9)))
    outputs: tuple[Output, ...] = ()

    def conditions(self) -> list[Condition]:
        pairs = [(b.start, b.repeat) for b in self.blocks] + [(o.start, o.stop) for o in self.outputs]
        return [c for pair in pairs for c in pair]

    def describe(self) -> dict[str, Any]:
        """The program in the input's own form (MS-SEQ-8), every block listed."""
        blocks = [
            {
                "start": b.start.as_list(),
                "repeat": b.repeat.as_list(),
                "delay_ms": b.delay_ms,
                "repetitions": b.repetitions,
                "action": b.action,
            }
            for b in self.blocks
        ]
        outputs: list[dict[str, Any]] = []
        for o in self.outputs:
            if o.kind == "ttl":
                ttl = {"kind": "ttl", "index": o.index, "start": o.start.as_list(), "stop": o.stop.as_list()}
                outputs.append(ttl)
                continue
            outputs.append(
                {
                    "kind": o.kind,
                    "index" if o.kind == "avo" else "axis": o.index,
                    "step": o.start.as_list(),
                    "reset": o.stop.as_list(),
                    "step_size": o.step_size,
                    "initial": o.initial,
                }
            )
        return {"blocks": blocks, "outputs": outputs}


# ---- parsing ----------------------------------------------------------------------------------


class Place:
    """Where in the program a value sits, for the rejection message."""

    def __init__(self, where: str) -> None:
        self.where = where

    def reject(self, what: str, problem: str) -> ControlError:
        return ControlError(f"sequencer: {self.where} {what}: {problem}; program not loaded")


def _integer(value: Any, low: int, high: int, place: Place, what: str) -> int:
    number = isinstance(value, int | float) and not isinstance(value, bool) and finite_number(value)
    if not number or value != int(value) or not low <= value <= high:
        raise place.reject(what, f"{value!r} is not an integer {low}…{high}")
    return int(value)


def _number(value: Any, low: float, high: float, place: Place, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not finite_number(value):
        raise place.reject(what, f"{value!r} is not a number")
    if not low <= value <= high:
        raise place.reject(what, f"{value} is outside {low:g}…{high:g}")
    return float(value)


def _keys(entry: Any, known: Collection[str], place: Place) -> Mapping[str, Any]:
    if not isinstance(entry, dict):
        raise place.reject("", f"{entry!r} is not a mapping")
    unknown = sorted(set(entry) - set(known))
    if unknown:
        raise place.reject(unknown[0], f"unknown field (known: {', '.join(known)})")
    return entry


def condition(value: Any, position: Position, modules: Collection[str], place: Place, what: str) -> Condition:
    """`[code]`, `[code, n]` (5–10) or `[11, n, m]`, allowed in `position` (MS-SEQ-2)."""
    if not isinstance(value, list) or not value:
        raise place.reject(what, f"{value!r} is not a list [code, n?, m?]")
    code = _integer(value[0], 0, len(CONDITION_NAMES) - 1, place, what + " code")
    name = f"condition {code} ({CONDITION_NAMES[code]})"
    wanted = 3 if code == BLOCK_REPETITION else 2 if code in NAMES_BLOCK else 1
    if len(value) != wanted:
        raise place.reject(what, f"{name} takes {wanted} number(s), got {value!r}")
    if not allowed(code, position):
        raise place.reject(what, f"{name} is not allowed in {position.value}")
    module = CONDITION_MODULES.get(code)
    if module is not None and module not in modules:
        raise place.reject(what, f"{name} needs module {module}")
    block = _integer(value[1], 1, BLOCK_COUNT, place, what + " block") if wanted > 1 else None
    repetition = _integer(value[2], 1, MAX_REPETITIONS, place, what + " repetition") if wanted > 2 else None
    return Condition(code, block, repetition)


def _block(number: int, entry: Any, modules: Collection[str]) -> Block:
    place = Place(f"block {number}")
    fields = _keys(entry, ("start", "repeat", "delay_ms", "repetitions", "action"), place)
    action = _integer(fields.get("action", 0), 0, len(ACTION_NAMES) - 1, place, "action")
    module = ACTION_MODULES.get(action)
    if module is not None and module not in modules:
        raise place.reject("action", f"action {action} ({ACTION_NAMES[action]}) needs module {module}")
    return Block(
        number,
        condition(fields.get("start", [NEVER]), Position.BLOCK_START, modules, place, "start"),
        condition(fields.get("repeat", [NEVER]), Position.BLOCK_REPEAT, modules, place, "repeat"),
        _integer(fields.get("delay_ms", 0), 0, MAX_DELAY_MS, place, "delay_ms"),
        _integer(fields.get("repetitions", 0), 0, MAX_REPETITIONS, place, "repetitions"),
        action,
    )


def _output(number: int, entry: Any, modules: Collection[str], axes: Collection[str]) -> Output:
    place = Place(f"output {number}")
    kind = entry.get("kind") if isinstance(entry, dict) else None
    if kind == "ttl":
        fields = _keys(entry, ("kind", "index", "start", "stop"), place)
        index: int | str = _integer(fields.get("index"), 0, TTL_COUNT - 1, place, "index")
        place = Place(f"output {number} (ttl {index})")
        return Output(
            "ttl",
            index,
            condition(fields.get("start", [NEVER]), Position.TTL_START, modules, place, "start"),
            condition(fields.get("stop", [NEVER]), Position.TTL_STOP, modules, place, "stop"),
        )
    if kind not in ("avo", "stg"):
        raise place.reject("kind", f"{kind!r} is not ttl, avo or stg")
    key = "index" if kind == "avo" else "axis"
    fields = _keys(entry, ("kind", key, "step", "reset", "step_size", "initial"), place)
    if kind == "avo":
        index = _integer(fields.get("index"), 0, AVO_COUNT - 1, place, "index")
        size_limit, low, high = AVO_MAX_V, 0.0, AVO_MAX_V
    else:
        letter = fields.get("axis")
        if not isinstance(letter, str) or letter not in axes:
            raise place.reject("axis", f"{letter!r} is not a motor axis ({', '.join(axes)})")
        index = letter
        size_limit, low, high = MAX_STAGE_UNITS, -MAX_STAGE_UNITS, MAX_STAGE_UNITS
    place = Place(f"output {number} ({kind} {index})")
    return Output(
        kind,
        index,
        condition(fields.get("step", [NEVER]), Position.STEP, modules, place, "step"),
        condition(fields.get("reset", [NEVER]), Position.RESET, modules, place, "reset"),
        _number(fields.get("step_size", 0.0), -size_limit, size_limit, place, "step_size"),
        _number(fields.get("initial", 0.0), low, high, place, "initial"),
    )


def parse(params: Mapping[str, Any], modules: Collection[str], axes: Collection[str]) -> Program:
    """The program of a `sequencer` input; ControlError naming the block or output and field."""
    top = _keys(dict(params), ("blocks", "outputs"), Place("program"))
    blocks, outputs = top.get("blocks", []), top.get("outputs", [])
    if not isinstance(blocks, list) or len(blocks) > BLOCK_COUNT:
        raise Place("program").reject("blocks", f"a list of at most {BLOCK_COUNT} blocks is needed")
    if not isinstance(outputs, list):
        raise Place("program").reject("outputs", "a list of outputs is needed")
    given = [_block(n, entry, modules) for n, entry in enumerate(blocks, start=1)]
    unused = [Block(n) for n in range(len(given) + 1, BLOCK_COUNT + 1)]
    parsed = [_output(n, entry, modules, axes) for n, entry in enumerate(outputs, start=1)]
    seen: set[str] = set()
    for n, out in enumerate(parsed, start=1):
        if out.label in seen:
            raise Place(f"output {n} ({out.label})").reject("index", "programmed twice")
        seen.add(out.label)
    return Program(tuple(given + unused), tuple(parsed))
