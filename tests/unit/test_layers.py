"""The layers of emulator/: a module imports only from its own layer and the layers below it.

Every import is read with `ast`, module-level and inside functions, and also those under
`if TYPE_CHECKING:` (a type-only import still says what a module knows about). An upward import
that is inherent is listed in ALLOWED with its reason, so it is seen rather than hidden, and an
entry that no longer matches an import fails too.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: lowest first; a layer is the modules under any of its prefixes
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("storage", ("emulator.storage",)),
    ("profiles", ("emulator.profiles",)),
    (
        "contract",
        (
            "emulator.device",
            "emulator.motion",
            "emulator.wire_time",
            "emulator.uart",
            "emulator.control_client",
        ),
    ),
    ("devices", ("emulator.devices",)),
    ("hosting", ("emulator.hosting",)),
    ("in-process", ("emulator.urlhandler", "emulator.pytest_plugin", "emulator.pytest_virtual")),
    ("tools", ("emulator.tools",)),
    ("cli", ("emulator.cli",)),
)

#: (importing module, imported module): why the import goes up
ALLOWED: dict[tuple[str, str], str] = {
    (
        "emulator.profiles.registry",
        "emulator.devices",
    ): "the registry lists the bundled families by importing emulator.devices' packages by name",
    (
        "emulator.profiles.registry",
        "emulator.device",
    ): "a family's factory is typed as making a Device (TYPE_CHECKING: profile.py imports the registry)",
}


def module_of(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer_of(module: str) -> int | None:
    for rank, (_, prefixes) in enumerate(LAYERS):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return rank
    return None


def imported(tree: ast.Module) -> list[tuple[int, str]]:
    """(line, module) for every import of ours; `from a import b` counts as a.b when b is a module."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                name = f"{node.module}.{alias.name}"
                found.append((node.lineno, name if layer_of(name) is not None else node.module))
    return [(line, name) for line, name in found if name.split(".")[0] == "emulator"]


def modules() -> list[tuple[str, Path]]:
    paths = sorted((ROOT / "emulator").rglob("*.py"))
    return [(module_of(p), p) for p in paths if module_of(p) != "emulator"]


def upward_imports() -> list[tuple[str, str, str]]:
    """(importer, imported, where) for every import of a higher layer."""
    edges = []
    for module, path in modules():
        own = layer_of(module)
        assert own is not None
        for line, name in imported(ast.parse(path.read_text(), str(path))):
            target = layer_of(name)
            if target is not None and target > own:
                edges.append((module, name, f"{path.relative_to(ROOT)}:{line}"))
    return edges


def allowed(importer: str, name: str) -> bool:
    return any(importer == i and (name == t or name.startswith(t + ".")) for i, t in ALLOWED)


def test_every_module_has_a_layer() -> None:
    assert [str(p.relative_to(ROOT)) for m, p in modules() if layer_of(m) is None] == []


def test_no_module_imports_a_layer_above_its_own() -> None:
    names = [name for name, _ in LAYERS]
    bad = [
        f"{where}: {importer} ({names[layer_of(importer) or 0]}) imports {name}"
        f" ({names[layer_of(name) or 0]})"
        for importer, name, where in upward_imports()
        if not allowed(importer, name)
    ]
    assert bad == []


def test_every_allowed_exception_is_still_used() -> None:
    edges = [(importer, name) for importer, name, _ in upward_imports()]
    unused = [
        (i, t) for i, t in ALLOWED if not any(e == i and (n == t or n.startswith(t + ".")) for e, n in edges)
    ]
    assert unused == []
