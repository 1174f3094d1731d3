"""Print the import circles of a package: the strongly connected components (more than one file) of
the graph of its files' imports, read with `ast`. Imports under `if TYPE_CHECKING:` count only with
`--typing`, since they do not run; `--explicit` leaves out the edge every import has to the
`__init__` of the packages above the imported file (a package `__init__` that imports its
submodules otherwise joins every circle).

    python scripts/import_cycles.py emulator/devices/ms2000 [--typing] [--explicit]
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path


def module_name(path: Path, root: Path) -> str:
    """The dotted name of `path`, relative to the directory that holds the package (`root`)."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST, here: str, is_package: bool, typing: bool) -> list[tuple[str, tuple[str, ...]]]:
    """What this file imports: (module, names) for each `from module import names`, (module, ())
    for each `import module`."""
    found: list[tuple[str, tuple[str, ...]]] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node.test) and not typing:
            for branch in node.orelse:
                visit(branch)
            return
        if isinstance(node, ast.Import):
            found.extend((alias.name, ()) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = here.split(".") if is_package else here.split(".")[:-1]
                package = package[: len(package) - node.level + 1]
                base = ".".join([*package, base] if base else package)
            found.append((base, tuple(alias.name for alias in node.names)))
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def import_graph(package: Path, typing: bool = False, parents: bool = True) -> dict[str, set[str]]:
    """File (dotted name) -> the files of the same package it imports, with `parents` the
    `__init__` of each parent package too (importing `a.b.c` runs `a/b/__init__.py` first)."""
    root = package.resolve().parent
    while (root / "__init__.py").is_file():  # names are dotted from the top-level package
        root = root.parent
    files = {module_name(p, root): p for p in sorted(package.resolve().rglob("*.py"))}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        targets: set[str] = set()
        for module, names in _imports(tree, name, path.name == "__init__.py", typing):
            submodules = [f"{module}.{n}" for n in names if f"{module}.{n}" in files]
            # `from pkg import submodule` imports the submodule; pkg itself only as its parent
            direct = submodules if names and len(submodules) == len(names) else [module, *submodules]
            for imported in direct:
                parts = imported.split(".")
                first = 1 if parents else len(parts)
                targets.update(".".join(parts[:n]) for n in range(first, len(parts) + 1))
        graph[name] = {t for t in targets if t in files and t != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one node (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, edges = work[-1]
            child = next(edges, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return sorted(found, key=len, reverse=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("package", type=Path, help="a package directory, e.g. emulator/devices/ms2000")
    parser.add_argument("--typing", action="store_true", help="count imports under `if TYPE_CHECKING:` too")
    parser.add_argument(
        "--explicit", action="store_true", help="only the imported files, not their parent packages"
    )
    args = parser.parse_args(argv)
    if not (args.package / "__init__.py").is_file():
        print(f"import_cycles: {args.package} is not a package directory", file=sys.stderr)
        return 2
    graph = import_graph(args.package, args.typing, not args.explicit)
    circles = cycles(graph)
    print(f"{len(graph)} files, {sum(map(len, graph.values()))} imports, {len(circles)} circle(s)")
    for component in circles:
        print(f"circle of {len(component)} files:")
        for name in component:
            print(f"  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
