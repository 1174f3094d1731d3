"""Safe YAML loading that remembers where every key came from (file and line) for error messages.

Every profile and rig file is read by `read_source`, which opens it once and refuses hostile input
early, each time with a one-line `file[:line]: message` error instead of a traceback:

- only a regular file is read (a missing file, a directory, a FIFO and a device each have their
  own message; a FIFO is never opened blocking);
- `MAX_FILE_BYTES` (1 MiB): bundled profiles are a few KB; at most this many bytes plus one are
  read, so a huge file costs nothing;
- the text must be UTF-8 (`not UTF-8 text, byte N`, N counted from 0);
- `MAX_NODES` (100 000): YAML nodes of one document, counted while composing and again while
  building with aliases expanded, so an alias bomb ("billion laughs") stops early;
- `MAX_DEPTH` (64): nesting of mappings and sequences (a profile needs 4), which also stops
  self-referencing anchors.

Files that are only referenced (the parent of an `extends`) are read with `quote=False`: their
errors then never quote what the file contains, in case it is not a profile at all.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass, field
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.resolver import Resolver

from emulator.profiles.schema import Path, path_text

MAX_FILE_BYTES = 1 << 20
MAX_NODES = 100_000
MAX_DEPTH = 64
#: how libyaml's parser words the refusal of nesting deeper than its own limit
LIBYAML_TOO_DEEP = "exceeded maximum nesting depth"

try:  # libyaml scans and parses several times faster; the composer stays in Python (limits)
    from yaml._yaml import CParser

    _PARSER_BASES: tuple[type, ...] = (CParser,)

    def _init_parser(loader: Any, text: str) -> None:
        CParser.__init__(loader, text)

except ImportError:  # pragma: no cover - PyYAML built without libyaml
    from yaml.parser import Parser
    from yaml.reader import Reader
    from yaml.scanner import Scanner

    _PARSER_BASES = (Reader, Scanner, Parser)

    def _init_parser(loader: Any, text: str) -> None:
        Reader.__init__(loader, text)
        Scanner.__init__(loader)
        Parser.__init__(loader)


@dataclass(frozen=True)
class Where:
    source: str
    line: int


class SourceError(Exception):
    """An error in a YAML file, already formatted as `file:line: key: message`."""


@dataclass(frozen=True)
class Problem:
    """One error of a file, formatted (`file:line: key: message`), and where it is (None: nowhere
    in particular, e.g. the file as a whole), to report several in file order."""

    text: str
    where: Where | None = None


def in_file_order(problems: list[Problem], primary: str) -> list[Problem]:
    """`problems` without repeats, those of the file `primary` first, each file's by line; those
    without a place last, in the order found."""
    unique = list(dict.fromkeys(problems))
    sources = list(dict.fromkeys(p.where.source for p in unique if p.where is not None))

    def key(problem: Problem) -> tuple[int, int, int]:
        if problem.where is None:
            return (2, 0, 0)
        rank = 0 if problem.where.source == primary else 1
        return (rank, sources.index(problem.where.source), problem.where.line)

    return sorted(unique, key=key)


class FileProblem(SourceError):
    """The file itself cannot be read as text (missing, not a regular file, too big...).

    `reason` completes a sentence about the file: `does not exist`, `is a directory, ...`."""

    def __init__(self, name: str, reason: str, missing: bool = False) -> None:
        super().__init__(f"{name}: {reason}")
        self.reason = reason
        self.missing = missing


@dataclass
class Located:
    """Plain data loaded from YAML plus the file/line of each key path."""

    data: Any
    places: dict[Path, Where] = field(default_factory=dict)

    def where(self, path: Path) -> Where | None:
        for end in range(len(path), -1, -1):
            place = self.places.get(path[:end])
            if place is not None:
                return place
        return None

    def subtree(self, path: Path) -> Located:
        """The value at `path` as its own document, keeping the original file positions."""
        data = self.data
        for part in path:
            data = data[part]
        places = {k[len(path) :]: v for k, v in self.places.items() if k[: len(path)] == path}
        return Located(data, places)

    def error(self, path: Path, message: str) -> SourceError:
        return SourceError(self.problem(path, message).text)

    def problem(self, path: Path, message: str) -> Problem:
        place = self.where(path)
        prefix = f"{place.source}:{place.line}: " if place else ""
        key = f"{path_text(path)}: " if path else ""
        return Problem(f"{prefix}{key}{message}", place)


def read_source(path: os.PathLike[str] | str, source: str | None = None, quote: bool = True) -> Located:
    """Read and parse one YAML file within the limits above; `source` names it in messages."""
    name = source if source is not None else str(path)
    return load_located(read_text(path, name), name, quote)


def read_text(path: os.PathLike[str] | str, name: str) -> str:
    """The file's text: a regular file of at most MAX_FILE_BYTES, strictly UTF-8."""
    try:
        _check_kind(os.stat(path).st_mode, name)
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    except FileNotFoundError:
        raise FileProblem(name, "does not exist", missing=True) from None
    except (OSError, ValueError) as exc:
        raise FileProblem(name, f"cannot be read: {_strerror(exc)}") from None
    try:
        _check_kind(os.fstat(fd).st_mode, name)  # it may have been replaced since the stat
        chunks: list[bytes] = []
        size = 0
        while size <= MAX_FILE_BYTES:
            chunk = os.read(fd, MAX_FILE_BYTES + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise FileProblem(name, f"cannot be read: {_strerror(exc)}") from None
    finally:
        os.close(fd)
    if size > MAX_FILE_BYTES:
        raise FileProblem(name, f"is larger than {MAX_FILE_BYTES} bytes (1 MiB); a profile is a few KB")
    data = b"".join(chunks)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise SourceError(f"{name}:{line}: not UTF-8 text, byte {exc.start}") from None


def _check_kind(mode: int, name: str) -> None:
    if stat.S_ISREG(mode):
        return
    if stat.S_ISDIR(mode):
        raise FileProblem(name, "is a directory, not a file")
    if stat.S_ISFIFO(mode):
        raise FileProblem(name, "is a FIFO (named pipe), not a regular file")
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        raise FileProblem(name, "is a device, not a regular file")
    raise FileProblem(name, "is not a regular file")


def _strerror(exc: Exception) -> str:
    if isinstance(exc, OSError):
        return exc.strerror or type(exc).__name__
    return "not a valid file name"


class _Loader(Composer, *_PARSER_BASES, SafeConstructor, Resolver):  # type: ignore[misc]
    """The safe loader with counted, depth-limited composition (the Python composer over the
    fastest parser available)."""

    def __init__(self, text: str, source: str, quote: bool) -> None:
        _init_parser(self, text)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        Resolver.__init__(self)
        self.source = source
        self.quote = quote
        self.depth = 0
        self.nodes = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        line = self.peek_event().start_mark.line + 1
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise _too_many(self.source, line)
        if self.depth >= MAX_DEPTH:
            raise _too_deep(self.source, line)
        self.depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


# YAML 1.2 floats without a dot (`1e300`, `5E-3`), which PyYAML's 1.1 rules read as strings.
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def _too_many(source: str, line: int) -> SourceError:
    return SourceError(f"{source}:{line}: more than {MAX_NODES} YAML nodes (aliases expanded)")


def _too_deep(source: str, line: int) -> SourceError:
    return SourceError(f"{source}:{line}: nested deeper than {MAX_DEPTH} levels")


def load_located(text: str, source: str, quote: bool = True) -> Located:
    """Parse YAML with the safe loader (no tags, no Python objects) keeping key positions.

    With `quote=False` no message repeats anything the text contains (tags, keys, characters)."""
    try:
        return _load(text, source, quote)
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        code = exc.character if isinstance(exc.character, int) else ord(exc.character)
        detail = f": character U+{code:04X} is not allowed" if quote else ""
        raise SourceError(f"{source}:{line}: not valid YAML{detail}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = mark.line + 1 if mark is not None else 1
        problem = " ".join((getattr(exc, "problem", None) or str(exc)).split())
        if problem == LIBYAML_TOO_DEEP:
            # libyaml (PyYAML >= 6.0.4) stops at its own depth limit, far beyond ours, before our
            # composer sees the nesting: the same refusal, in the same words
            raise _too_deep(source, where) from None
        raise SourceError(f"{source}:{where}: not valid YAML" + (f": {problem}" if quote else "")) from None


def _load(text: str, source: str, quote: bool) -> Located:
    loader = _Loader(text, source, quote)
    try:
        node = loader.get_single_node()
        located = Located(None, {(): Where(source, 1)})
        if node is not None:
            loader.nodes = 0  # count again, aliases expanded
            located.data = _build(loader, node, (), located.places)
        return located
    finally:
        loader.dispose()


_PLAIN_TAGS: dict[type[yaml.Node], str] = {
    yaml.MappingNode: "tag:yaml.org,2002:map",
    yaml.SequenceNode: "tag:yaml.org,2002:seq",
}


def _build(loader: _Loader, node: yaml.Node, path: Path, places: dict[Path, Where]) -> Any:
    source = loader.source
    line = node.start_mark.line + 1
    loader.nodes += 1
    if loader.nodes > MAX_NODES:
        raise _too_many(source, line)
    if len(path) >= MAX_DEPTH:
        raise _too_deep(source, line)
    expected = _PLAIN_TAGS.get(type(node))
    if expected is not None and node.tag != expected:
        tag = f" {node.tag}" if loader.quote else ""
        raise SourceError(f"{source}:{line}: not valid YAML: tag{tag} is not allowed")
    if isinstance(node, yaml.MappingNode):
        result: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            key_line = key_node.start_mark.line + 1
            key = _scalar(loader, key_node) if isinstance(key_node, yaml.ScalarNode) else None
            if not isinstance(key, str | int | float | bool):
                raise SourceError(f"{source}:{key_line}: keys must be plain scalars")
            if key in result:
                name = f"{path_text((*path, str(key)))}: " if loader.quote else ""
                raise SourceError(f"{source}:{key_line}: {name}duplicate key")
            child = (*path, str(key))
            places[child] = Where(source, key_line)
            result[key] = _build(loader, value_node, child, places)
        return result
    if isinstance(node, yaml.SequenceNode):
        items = []
        for index, item in enumerate(node.value):
            child = (*path, index)
            places[child] = Where(source, item.start_mark.line + 1)
            items.append(_build(loader, item, child, places))
        return items
    return _scalar(loader, node)


def _scalar(loader: _Loader, node: yaml.Node) -> Any:
    try:
        return loader.construct_object(node, deep=True)
    except (ValueError, OverflowError) as exc:  # e.g. an integer of 5000 digits, a 13th month
        detail = f": {' '.join(str(exc).split(';')[0].split())}" if loader.quote else ""
        raise SourceError(f"{loader.source}:{node.start_mark.line + 1}: not a valid value{detail}") from None


def merge(base: Located, over: Located) -> Located:
    """Deep-merge `over` onto `base`: mappings merge key by key, anything else is replaced.

    Positions follow the values: a replaced value keeps `over`'s positions for itself and
    everything under it (linear in the number of positions, whatever the shapes)."""
    replaced: set[Path] = set()

    def walk(a: Any, b: Any, path: Path) -> Any:
        if isinstance(a, dict) and isinstance(b, dict):
            merged = dict(a)
            for key, value in b.items():
                child = (*path, str(key))
                if key in a:
                    merged[key] = walk(a[key], value, child)
                else:
                    replaced.add(child)
                    merged[key] = value
            return merged
        replaced.add(path)
        return b

    data = walk(base.data if base.data is not None else {}, over.data if over.data is not None else {}, ())
    places = {k: v for k, v in base.places.items() if not any(k[:end] in replaced for end in range(len(k)))}
    places.update(
        {
            k: v
            for k, v in over.places.items()
            if k != () and any(k[:end] in replaced for end in range(len(k) + 1))
        }
    )
    return Located(data, places)
