"""The package's structure in numbers, read statically (every import, in-function ones included).

    python scripts/import_counts.py [PACKAGE_DIR]     # default: grasping_sym beside this folder

Prints, as JSON: import statements between the package's own modules (each (file, target,
line) once), the distinct file pairs, how many sit inside functions, how many run from a lower
floor to a higher one (the floors of the ``layers`` contract in ``pyproject.toml``, top first),
the import cycles (strongly connected groups of files), and the largest classes and functions
in lines. ``lint-imports`` enforces the floors; this counts them (issue 26's before/after).
"""
from __future__ import annotations

import ast
import json
import sys
import tomllib
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def modules(package: Path) -> dict[str, Path]:
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def targets(mods: dict[str, Path], current: str, node: ast.AST, top: str) -> list[str]:
    """The package's modules an import statement names (a name imported from a package counts
    as that submodule when it is one)."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names if a.name.split(".")[0] == top]
    else:
        base = node.module or ""
        if node.level:
            parts = current.split(".")
            keep = len(parts) - node.level + (1 if mods[current].name == "__init__.py" else 0)
            base = ".".join(parts[:keep] + ([base] if base else []))
        if base.split(".")[0] != top:
            return []
        names = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
    found = []
    for name in names:
        while name not in mods and "." in name:
            name = name.rsplit(".", 1)[0]
        if name in mods:
            found.append(name)
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Groups of two or more modules that reach each other (Tarjan, iterative)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]
    for root in list(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    group = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        group.append(w)
                        if w == v:
                            break
                    if len(group) > 1:
                        out.append(sorted(group))
    return out


def main(package: Path) -> dict:
    top = package.name
    mods = modules(package)
    layers = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"][0]["layers"]
    floor = {name: len(layers) - i for i, name in enumerate(layers)}  # higher number: higher floor

    def floor_of(module: str) -> int | None:
        while module:
            if module in floor:
                return floor[module]
            module = module.rpartition(".")[0]
        return None

    edges = set()
    classes, functions = [], []
    for name, path in mods.items():
        tree = ast.parse(path.read_text())
        pending = [(tree, False)]
        while pending:
            node, inside = pending.pop()
            for child in ast.iter_child_nodes(node):
                is_fn = isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    for target in targets(mods, name, child, top):
                        if target != name:
                            edges.add((name, target, inside, child.lineno))
                if is_fn:
                    functions.append((child.end_lineno - child.lineno + 1, f"{name}.{child.name}"))
                if isinstance(child, ast.ClassDef):
                    classes.append((child.end_lineno - child.lineno + 1, f"{name}.{child.name}"))
                pending.append((child, inside or is_fn))
    graph = defaultdict(set)
    for a, b, _, _ in edges:
        graph[a].add(b)
    for name in mods:
        graph.setdefault(name, set())
    upward = [(a, b, line) for a, b, _, line in edges
              if floor_of(a) is not None and floor_of(b) is not None and floor_of(b) > floor_of(a)]
    return {
        "import statements": len(edges),
        "distinct file pairs": len({(a, b) for a, b, _, _ in edges}),
        "inside functions": sorted(f"{a}:{line} -> {b}" for a, b, inside, line in edges if inside),
        "upward": sorted(f"{a}:{line} -> {b}" for a, b, line in upward),
        "cycles": cycles(graph),
        "largest classes": sorted(classes)[-3:],
        "largest functions": sorted(functions)[-3:],
    }


if __name__ == "__main__":
    print(json.dumps(main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "grasping_sym"), indent=1))
