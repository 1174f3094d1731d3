"""Safe YAML loading that remembers where every key came from (file and line) for error messages."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import yaml

from emulator.schema import Path, path_text


@dataclass(frozen=True)
class Where:
    source: str
    line: int


class SourceError(Exception):
    """An error in a YAML file, already formatted as `file:line: key: message`."""


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
        place = self.where(path)
        prefix = f"{place.source}:{place.line}: " if place else ""
        key = f"{path_text(path)}: " if path else ""
        return SourceError(f"{prefix}{key}{message}")


def load_located(text: str, source: str) -> Located:
    """Parse YAML with the safe loader (no tags, no Python objects) keeping key positions."""
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        located = Located(None, {(): Where(source, 1)})
        if node is not None:
            located.data = _build(loader, node, (), located.places, source)
        return located
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f"{mark.line + 1}" if mark is not None else "1"
        problem = getattr(exc, "problem", None) or str(exc)
        raise SourceError(f"{source}:{line}: not valid YAML: {problem}") from None
    finally:
        loader.dispose()


_PLAIN_TAGS = {yaml.MappingNode: "tag:yaml.org,2002:map", yaml.SequenceNode: "tag:yaml.org,2002:seq"}


def _build(
    loader: yaml.SafeLoader, node: yaml.Node, path: Path, places: dict[Path, Where], source: str
) -> Any:
    expected = _PLAIN_TAGS.get(type(node))
    if expected is not None and node.tag != expected:
        raise SourceError(
            f"{source}:{node.start_mark.line + 1}: not valid YAML: tag {node.tag} is not allowed"
        )
    if isinstance(node, yaml.MappingNode):
        result: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            if not isinstance(key, str | int | float | bool):
                raise SourceError(f"{source}:{key_node.start_mark.line + 1}: keys must be plain scalars")
            if key in result:
                raise SourceError(
                    f"{source}:{key_node.start_mark.line + 1}: {path_text((*path, str(key)))}: duplicate key"
                )
            child = (*path, str(key))
            places[child] = Where(source, key_node.start_mark.line + 1)
            result[key] = _build(loader, value_node, child, places, source)
        return result
    if isinstance(node, yaml.SequenceNode):
        items = []
        for index, item in enumerate(node.value):
            places[(*path, index)] = Where(source, item.start_mark.line + 1)
            items.append(_build(loader, item, (*path, index), places, source))
        return items
    return loader.construct_object(node, deep=True)


def merge(base: Located, over: Located) -> Located:
    """Deep-merge `over` onto `base`: mappings merge key by key, anything else is replaced."""
    places = dict(base.places)

    def walk(a: Any, b: Any, path: Path) -> Any:
        if isinstance(a, dict) and isinstance(b, dict):
            merged = dict(a)
            for key, value in b.items():
                child = (*path, str(key))
                merged[key] = walk(a.get(key), value, child) if key in a else _take(value, child)
            return merged
        return _take(b, path)

    def _take(value: Any, path: Path) -> Any:
        for key in [k for k in places if k[: len(path)] == path and len(k) > len(path)]:
            del places[key]
        places.update({k: v for k, v in over.places.items() if k[: len(path)] == path and k != ()})
        return value

    data = walk(base.data if base.data is not None else {}, over.data if over.data is not None else {}, ())
    return Located(data, places)
